#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "core/heatmap.hpp"

namespace tirstrain {
namespace {

// The table the maps colour their cells with is OpenCV's viridis, level for level.
TEST(Heatmap, SequentialTableIsViridis) {
  const SequentialColours table;
  for (const double t : {-0.5, 0.0, 0.1, 0.37, 0.5, 0.999, 1.0, 2.0}) {
    cv::Mat1b in(1, 1, static_cast<uchar>(std::clamp(t, 0.0, 1.0) * 255.0));
    cv::Mat out;
    cv::applyColorMap(in, out, cv::COLORMAP_VIRIDIS);
    EXPECT_EQ(table(t), out.at<cv::Vec3b>(0, 0)) << t;
    EXPECT_EQ(sequential_colour(t), out.at<cv::Vec3b>(0, 0)) << t;
  }
}

TEST(Heatmap, DivergingMapIsBlueForNegativeRedForPositiveGreyForNaN) {
  cv::Mat values(2, 3, CV_64F);
  values.at<double>(0, 0) = -1.0;
  values.at<double>(0, 1) = 0.0;
  values.at<double>(0, 2) = 1.0;
  values.at<double>(1, 0) = std::nan("");
  values.at<double>(1, 1) = 0.5;
  values.at<double>(1, 2) = -0.5;
  HeatmapOptions options;
  options.pixels_per_cell = 10;
  const cv::Mat image = render_heatmap(values, options);
  // Map origin at (70, 58) in the canvas; sample cell centres.
  const auto at = [&](int r, int c) { return image.at<cv::Vec3b>(58 + 10 * r + 5, 70 + 10 * c + 5); };
  EXPECT_GT(at(0, 0)[0], 200);  // blue channel high
  EXPECT_LT(at(0, 0)[2], 60);
  EXPECT_GT(at(0, 2)[2], 200);  // red channel high
  EXPECT_LT(at(0, 2)[0], 60);
  EXPECT_EQ(at(0, 1), cv::Vec3b(255, 255, 255));  // zero is white
  EXPECT_EQ(at(1, 0), cv::Vec3b(200, 200, 200));  // NaN is grey
}

// One border cell a hundred times larger than the rest: on the full range the interior is white; on the
// 98th percentile it takes the end colour and the one outlier saturates.
TEST(Heatmap, PercentileRangeKeepsTheInteriorVisibleBesideAnOutlier) {
  cv::Mat values(10, 10, CV_64F, cv::Scalar(0.01));
  values.at<double>(0, 0) = 1.0;
  HeatmapOptions options;
  options.pixels_per_cell = 10;
  const auto centre = [](const cv::Mat& image) { return image.at<cv::Vec3b>(58 + 55, 70 + 55); };
  const cv::Vec3b full = centre(render_heatmap(values, options));
  EXPECT_GT(full[0], 245) << "0.01 against a range of ±1 is near white";
  options.range_percentile = 98.0;
  const cv::Vec3b robust = centre(render_heatmap(values, options));
  EXPECT_EQ(robust, diverging_colour(1.0)) << "0.01 is the top of a ±0.01 range";
}

}  // namespace
}  // namespace tirstrain
