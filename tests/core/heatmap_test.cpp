#include <gtest/gtest.h>

#include <cmath>

#include "core/heatmap.hpp"

namespace tirstrain {
namespace {

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
  // Map origin at (70, 40) in the canvas; sample cell centres.
  const auto at = [&](int r, int c) { return image.at<cv::Vec3b>(40 + 10 * r + 5, 70 + 10 * c + 5); };
  EXPECT_GT(at(0, 0)[0], 200);  // blue channel high
  EXPECT_LT(at(0, 0)[2], 60);
  EXPECT_GT(at(0, 2)[2], 200);  // red channel high
  EXPECT_LT(at(0, 2)[0], 60);
  EXPECT_EQ(at(0, 1), cv::Vec3b(255, 255, 255));  // zero is white
  EXPECT_EQ(at(1, 0), cv::Vec3b(200, 200, 200));  // NaN is grey
}

}  // namespace
}  // namespace tirstrain
