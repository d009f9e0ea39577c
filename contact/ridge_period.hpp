#pragma once
// Ridge period from the image's own spectrum: fingerprint ridges have a nearly constant spacing whatever
// their orientation, so the ridge texture shows as a ring in the 2-D power spectrum.
#include <opencv2/core.hpp>

#include <optional>

namespace tirstrain::contact {

struct PeriodEstimate {
  double period_px = 0.0;   // in the pixels of the image passed in
  double confidence = 0.0;  // ring power over the median of the searched band (after whitening); ~1 = none
};

// `image`: grey CV_32FC1. Searches periods in [min_period_px, max_period_px] (pixels of `image`). Returns
// nothing when the band does not fit the image; otherwise the strongest ring, with its confidence for the
// caller to judge.
std::optional<PeriodEstimate> estimate_ridge_period(const cv::Mat& image, double min_period_px,
                                                    double max_period_px);

}  // namespace tirstrain::contact
