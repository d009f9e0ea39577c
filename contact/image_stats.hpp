#pragma once
// Two statistics of a float image the segmentation takes several times a frame: Otsu's split of the texture
// energy into contact and background, and the means inside and outside a mask.
#include <opencv2/core.hpp>

namespace tirstrain::contact {

// Otsu's threshold on a 256-bin histogram of a non-negative float image, with the means of the two classes
// (all 0 when the image's maximum is not positive).
struct OtsuSplit {
  float threshold = 0.0f;
  double mean_low = 0.0, mean_high = 0.0;
};
OtsuSplit otsu(const cv::Mat& values);

// Mean of a float image inside a mask (non-zero) and outside it, in one pass, with the pixel counts.
struct MaskedMeans {
  double inside = 0.0, outside = 0.0, inside_count = 0.0, outside_count = 0.0;
};
MaskedMeans masked_means(const cv::Mat& image, const cv::Mat& mask);

}  // namespace tirstrain::contact
