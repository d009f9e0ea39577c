#include "flow/phase_correlation.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>

#include "noise_texture.hpp"

namespace tirstrain::flow {
namespace {

cv::Mat textured(cv::Size size, unsigned seed) {
  return testing::smoothed_noise(size, seed, 1.2);
}

// A frame of a moving texture: its content moved by `shift` px (and a little noise of its own).
cv::Mat shifted(const cv::Mat& big, cv::Size size, cv::Point2d shift, unsigned seed) {
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, 40 - shift.x, 0, 1, 30 - shift.y);
  cv::Mat out;
  cv::warpAffine(big, out, m, size, cv::INTER_CUBIC | cv::WARP_INVERSE_MAP);
  cv::Mat noise(size, CV_32F);
  cv::RNG(seed).fill(noise, cv::RNG::NORMAL, 0.0, 0.01);
  return out + noise;
}

// Frame after frame against the previous one, each spectrum computed once: the same shifts and responses
// as OpenCV's phaseCorrelate on each pair, for transform-friendly and padded sizes, with and without a
// window. The arithmetic is OpenCV's step for step, so they agree to the last few bits.
TEST(PhaseCorrelation, FrameAfterFrameEqualsOpenCVsPairByPair) {
  const cv::Mat big = textured({400, 300}, 4);
  const cv::Point2d path[] = {{0, 0}, {1.3, -0.4}, {2.9, -0.2}, {7.4, 1.1}, {7.0, 1.6}, {-3.2, 0.5}};
  for (const cv::Size size : {cv::Size(128, 48), cv::Size(131, 45), cv::Size(97, 64)})
    for (bool windowed : {false, true}) {
      cv::Mat window;
      if (windowed) cv::createHanningWindow(window, size, CV_32F);
      PhaseCorrelator correlator;
      cv::Mat previous = shifted(big, size, path[0], 1);
      correlator.set_reference(previous, window);
      for (std::size_t k = 1; k < std::size(path); ++k) {
        const cv::Mat current = shifted(big, size, path[k], static_cast<unsigned>(k + 1));
        double response = 0.0, expected_response = 0.0;
        const cv::Point2d s = correlator.correlate(current, &response);
        const cv::Point2d expected =
            cv::phaseCorrelate(previous.clone(), current.clone(), window, &expected_response);
        EXPECT_NEAR(s.x, expected.x, 1e-9) << size << (windowed ? " windowed" : "") << ", frame " << k;
        EXPECT_NEAR(s.y, expected.y, 1e-9) << size << (windowed ? " windowed" : "") << ", frame " << k;
        EXPECT_NEAR(response, expected_response, 1e-9);
        // And the motion itself (how far the second image's content moved): OpenCV's 5×5 centroid of a
        // broad peak on these small images is off by up to ~1 px (the tracker uses it only to reveal jumps
        // of a quarter window and more), so here only within 1.5 px, which still fixes sign and size.
        EXPECT_NEAR(s.x, path[k].x - path[k - 1].x, 1.5);
        EXPECT_NEAR(s.y, path[k].y - path[k - 1].y, 1.5);
        correlator.adopt_last_as_reference();
        previous = current;
      }
    }
}

// Images that are views into larger ones (the plate's band of a frame), with sizes the transform pads in
// both directions: the padding is zeros, never the pixels around the view (here NaN), as for copies.
TEST(PhaseCorrelation, ViewsArePaddedWithZerosNotTheirSurroundings) {
  const cv::Mat big = textured({400, 300}, 5);
  const cv::Size size(131, 56);  // padded to 135 × 60
  cv::Mat frame_a(100, 200, CV_32F, cv::Scalar(std::nanf(""))), frame_b = frame_a.clone();
  const cv::Rect band(10, 20, size.width, size.height);
  shifted(big, size, {0.0, 0.0}, 1).copyTo(frame_a(band));
  shifted(big, size, {2.2, -0.7}, 2).copyTo(frame_b(band));
  cv::Mat window;
  cv::createHanningWindow(window, size, CV_32F);
  PhaseCorrelator correlator;
  correlator.set_reference(frame_a(band), window);
  double response = 0.0, expected_response = 0.0;
  const cv::Point2d s = correlator.correlate(frame_b(band), &response);
  const cv::Point2d expected =
      cv::phaseCorrelate(frame_a(band).clone(), frame_b(band).clone(), window, &expected_response);
  EXPECT_NEAR(s.x, expected.x, 1e-9);
  EXPECT_NEAR(s.y, expected.y, 1e-9);
  EXPECT_NEAR(response, expected_response, 1e-9);
  EXPECT_NEAR(s.x, 2.2, 1.0);
  EXPECT_NEAR(s.y, -0.7, 1.0);
}

// Unrelated images give no clear peak; an image against itself a response of one.
TEST(PhaseCorrelation, ResponseSeparatesAMatchFromNoise) {
  const cv::Mat a = textured({96, 80}, 7), b = textured({96, 80}, 8);
  PhaseCorrelator correlator;
  correlator.set_reference(a);
  double same = 0.0, unrelated = 0.0;
  const cv::Point2d zero = correlator.correlate(a, &same);
  EXPECT_NEAR(zero.x, 0.0, 1e-6);
  EXPECT_NEAR(zero.y, 0.0, 1e-6);
  EXPECT_GT(same, 0.9);
  correlator.correlate(b, &unrelated);
  EXPECT_LT(unrelated, 0.1);
}

}  // namespace
}  // namespace tirstrain::flow
