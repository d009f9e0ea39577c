#pragma once
// The pixel noise of an image, measured on the image itself: Immerkær's estimator (1996), the mean absolute
// response to a 3 × 3 kernel that cancels any locally linear signal. Shared by the contact decision
// (contact/) and the tracker's texture measure (flow/).
#include <opencv2/core.hpp>

namespace tirstrain {

// Standard deviation of white noise in `image` (CV_32F), from the pixels where `mask` (CV_8U, same size) is
// non-zero, or every pixel when it is empty: for white noise of σ, E|I * N| = 6 σ √(2/π) with
// N = [1 −2 1; −2 4 −2; 1 −2 1]. Texture finer than a few pixels counts as noise. 0 for an image smaller
// than 3 × 3 or an empty mask.
double immerkaer_noise_sigma(const cv::Mat& image, const cv::Mat& mask = cv::Mat());

}  // namespace tirstrain
