#pragma once
// The ridge labels' fit (contact/ridge_labels.hpp) applied to a segmented contact: its outline, hull, area,
// bounding box and ellipse moved to the labels' centre, and with the brackets (large contacts) resized and
// reshaped, with the logistic fit (small contacts) given part of its elongation
// (SegmenterOptions::ridge_label_shape_weight).
#include <opencv2/core.hpp>

#include <functional>

#include "contact/segmenter.hpp"

namespace tirstrain::contact {

// What the fit reads besides the contact: the frame, its full scale, the ridge period (frame px), the
// polarity (-1 or +1), whether the contact is small (the logistic fit) and the flat field's surface at a
// frame pixel (empty: none).
struct LabelRefinementFrame {
  const cv::Mat* image = nullptr;
  double full_scale = 1.0;
  double period_px = 0.0;
  int polarity = 0;
  bool small_contact = false;
  std::function<double(double x_px, double y_px)> illumination;
};

// Fits the labels around `result.ellipse` (which must be set) and applies the fit when its centre moves by
// at most half a ridge period; otherwise `result` is left as it was.
void refine_with_ridge_labels(const LabelRefinementFrame& frame, const SegmenterOptions& options,
                              ContactResult& result);

}  // namespace tirstrain::contact
