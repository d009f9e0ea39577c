#pragma once
// The working image: the frame (or a region of it) averaged over f x f blocks and scaled to fractions of
// full scale, with the pixels at full scale counted in the same pass (the frame is read once). The contact
// segmentation runs on it; see contact/segmenter.hpp for why f is about a fifth of the ridge period.
#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tirstrain::contact {

// Column sums and a comparison mask reused from frame to frame (no allocation per frame).
struct WorkingImageBuffers {
  std::vector<float> row_sum;
  std::vector<std::uint16_t> sum_u16;
  std::vector<std::uint32_t> sum_u32;
  cv::Mat at_full_scale;
};

// `image` (CV_8UC1, CV_16UC1 or CV_32FC1) averaged over `factor` x `factor` blocks, divided by `full_scale`,
// into `out` (CV_32FC1; partial blocks at the right and bottom are dropped). Returns the number of pixels
// of `image` at or above `full_scale` (0 for float images, which carry no full-scale code).
std::size_t to_working_image(const cv::Mat& image, int factor, double full_scale, cv::Mat& out,
                             WorkingImageBuffers& buffers);

// The number of pixels of an integer `image` at or above `full_scale`.
std::size_t count_at_full_scale(const cv::Mat& image, double full_scale, WorkingImageBuffers& buffers);

}  // namespace tirstrain::contact
