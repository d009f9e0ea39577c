#pragma once
// A random texture for tests that need every direction textured at every pixel (no analytic truth needed):
// uniform noise smoothed by a Gaussian of `sigma_px`, the same for the same seed.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace tirstrain::flow::testing {

inline cv::Mat smoothed_noise(cv::Size size, unsigned seed, double sigma_px) {
  cv::Mat image(size, CV_32F);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(image, image, cv::Size(), sigma_px);
  return image;
}

}  // namespace tirstrain::flow::testing
