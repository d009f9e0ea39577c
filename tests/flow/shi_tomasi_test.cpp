#include "flow/shi_tomasi.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "noise_texture.hpp"

namespace tirstrain::flow {
namespace {

cv::Mat textured(cv::Size size, unsigned seed) {
  return testing::smoothed_noise(size, seed, 1.5);
}

// Band by band equals the whole region at once, for views anywhere in a frame (touching its edges or
// not), region heights that are and are not multiples of the band, and several block sizes. The tensor's
// box sums run in double and are rounded to float at the end, so the two agree to float rounding.
TEST(ShiTomasi, BandByBandEqualsOpenCVsWholeRegion) {
  const cv::Mat frame = textured({180, 150}, 3);
  cv::Mat banded, scratch, whole;
  for (const cv::Rect& box : {cv::Rect(0, 0, 180, 150), cv::Rect(17, 9, 120, 96), cv::Rect(40, 20, 77, 31),
                              cv::Rect(5, 100, 170, 50), cv::Rect(60, 0, 33, 5)})
    for (int block : {3, 5, 7, 9}) {
      const cv::Mat region = frame(box);
      cv::cornerMinEigenVal(region, whole, block, 3);
      min_eigenvalue_map(region, block, banded, scratch);
      ASSERT_EQ(banded.size(), region.size());
      ASSERT_EQ(banded.type(), CV_32F);
      double largest = 0.0;
      cv::minMaxLoc(cv::abs(whole), nullptr, &largest);
      ASSERT_GT(largest, 0.0);
      EXPECT_LE(cv::norm(banded, whole, cv::NORM_INF), 1e-6 * largest)
          << "box " << box << ", block " << block;
    }
}

// A uniform region scores zero everywhere, and a single row works.
TEST(ShiTomasi, UniformAndOneRowRegions) {
  const cv::Mat flat(64, 80, CV_32F, cv::Scalar(0.4));
  cv::Mat out, scratch;
  min_eigenvalue_map(flat, 7, out, scratch);
  EXPECT_LE(cv::norm(out, cv::NORM_INF), 1e-6);
  const cv::Mat frame = textured({50, 40}, 9);
  cv::Mat whole;
  cv::cornerMinEigenVal(frame.rowRange(20, 21), whole, 3, 3);
  min_eigenvalue_map(frame.rowRange(20, 21), 3, out, scratch);
  EXPECT_LE(cv::norm(out, whole, cv::NORM_INF), 1e-6);
}

}  // namespace
}  // namespace tirstrain::flow
