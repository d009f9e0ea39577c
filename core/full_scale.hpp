#pragma once
// The one rule for an image's full-scale value, shared by every module that turns pixel codes into
// fractions of full scale (contact/, flow/): cameras store 10-14 bit data in 16-bit files, so a 16-bit
// frame's full scale is read from its largest value rather than assumed to be 65535.
#include <opencv2/core.hpp>

namespace tirstrain {

// Full scale of an image's values: 255 for 8-bit; for 16-bit the smallest of 2^10-1, 2^12-1, 2^14-1,
// 2^16-1 not below the frame's maximum; 1 for float and every other depth (values already fractions).
double full_scale_of(const cv::Mat& image);

}  // namespace tirstrain
