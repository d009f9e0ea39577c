#pragma once
// Fingerprint ridge orientation by gradient principal-component analysis (Bazen & Gerez 2002): per block,
// the squared-gradient tensor [Gxx Gxy; Gxy Gyy] is summed; its principal axis is the mean gradient
// direction, the ridges run perpendicular to it, and the eigenvalue spread gives the coherence.
#include <opencv2/core.hpp>

namespace tirstrain::contact {

struct OrientationField {
  // One value per block, rows = blocks down, cols = blocks across; CV_32FC1.
  // orientation_rad: ridge direction from +x towards +y in [0, pi); coherence in [0, 1].
  cv::Mat orientation_rad;
  cv::Mat coherence;
};

// Gradients of `image` (CV_32FC1, a (possibly downsampled) view of the full frame where one pixel is
// `scale` full-resolution pixels) summed over blocks of `block_px` full-resolution pixels covering a frame
// of `full_size`. Blocks where `weight_mask` (CV_8UC1 at `image` resolution; empty = everywhere) covers
// less than half the block get orientation 0 and coherence 0.
OrientationField block_orientation(const cv::Mat& image, int scale, cv::Size full_size, int block_px,
                                   const cv::Mat& weight_mask);

}  // namespace tirstrain::contact
