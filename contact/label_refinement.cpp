#include "contact/label_refinement.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "contact/geometry.hpp"
#include "contact/ridge_labels.hpp"

namespace tirstrain::contact {
namespace {

// An ellipse's elongation and direction as the vector (a - b) / 2 (cos 2 angle, sin 2 angle): directions half
// a turn apart agree, and a near-circle's ill-defined direction carries little weight. Its border's radius is
// (a + b) / 2 + that vector . (cos 2 phi, sin 2 phi) to first order (phi about the centre).
cv::Vec2d shape_vector(const Ellipse& e) {
  const double half_difference = 0.5 * (e.semi_major_px - e.semi_minor_px);
  return {half_difference * std::cos(2.0 * e.angle_rad), half_difference * std::sin(2.0 * e.angle_rad)};
}

// `base` with its shape vector moved `weight` of the way to `other`'s, its mean semi-axis kept.
Ellipse with_blended_shape(const Ellipse& base, const Ellipse& other, double weight) {
  const cv::Vec2d blended = (1.0 - weight) * shape_vector(base) + weight * shape_vector(other);
  const double mean_px = 0.5 * (base.semi_major_px + base.semi_minor_px);
  const double half_difference = std::min(cv::norm(blended), 0.9 * mean_px);
  Ellipse e = base;
  e.semi_major_px = mean_px + half_difference;
  e.semi_minor_px = mean_px - half_difference;
  e.angle_rad = 0.5 * std::atan2(blended[1], blended[0]);
  return e;
}

double area_mm2(const std::vector<cv::Point2d>& outline_px, const SegmenterOptions& options) {
  return polygon_area_px2(outline_px) / (options.px_per_mm * options.px_per_mm);
}

// The brackets' size and shape terms: each outline point (already shifted) moved radially about the fit's
// centre, the hull and area taken again, and the fit's ellipse.
void apply_brackets(const RidgeLabelFit& fit, const SegmenterOptions& options, ContactResult& result) {
  const cv::Point2d centre(fit.ellipse.cx_px, fit.ellipse.cy_px);
  for (auto& p : result.outline_px) {
    const cv::Point2d d = p - centre;
    const double r = cv::norm(d);
    if (r < 1e-9) continue;
    // cos 2 phi and sin 2 phi from the direction itself: (dx^2 - dy^2) / r^2 and 2 dx dy / r^2.
    const double radial_px =
        fit.shape_size_px +
        (fit.shape_cos2_px * (d.x * d.x - d.y * d.y) + fit.shape_sin2_px * 2.0 * d.x * d.y) / (r * r);
    p += d * (radial_px / r);
  }
  result.outline_px = convex_hull(result.outline_px);
  result.hull_px = resample_closed_polygon(result.outline_px, options.hull_points);
  result.area_mm2 = area_mm2(result.outline_px, options);
  *result.ellipse = fit.ellipse;
  result.ridge_label_shape_px = cv::Vec3d(fit.shape_size_px, fit.shape_cos2_px, fit.shape_sin2_px);
}

// The logistic fit's elongation blended into the level edge's ellipse (moved by `shift`); the outline
// (already shifted) goes with its ellipse onto the blended one.
void apply_blended_shape(const RidgeLabelFit& fit, cv::Point2d shift, const SegmenterOptions& options,
                         ContactResult& result) {
  Ellipse level_edge = *result.ellipse;
  level_edge.cx_px += shift.x;
  level_edge.cy_px += shift.y;
  const Ellipse blended = with_blended_shape(level_edge, fit.ellipse, options.ridge_label_shape_weight);
  const cv::Matx23d map = ellipse_to_ellipse(level_edge, blended);
  for (auto& p : result.outline_px) {
    const cv::Vec2d moved = map * cv::Vec3d(p.x, p.y, 1.0);
    p = cv::Point2d(moved[0], moved[1]);
  }
  result.hull_px = resample_closed_polygon(result.outline_px, options.hull_points);
  result.area_mm2 = area_mm2(result.outline_px, options);
  const cv::Vec2d shape_change = shape_vector(blended) - shape_vector(level_edge);
  result.ridge_label_shape_px = cv::Vec3d(0.0, shape_change[0], shape_change[1]);
  *result.ellipse = blended;
}

}  // namespace

void refine_with_ridge_labels(const LabelRefinementFrame& frame, const SegmenterOptions& options,
                              ContactResult& result) {
  RidgeLabelOptions label_options;
  label_options.method = frame.small_contact ? RidgeLabelMethod::logistic : RidgeLabelMethod::brackets;
  if (options.border_band_centre && !frame.small_contact)
    label_options.border_band = result.border_averaged ? BorderBandUse::alone : BorderBandUse::with_labels;
  const std::optional<RidgeLabelFit> fit =
      fit_ellipse_to_ridge_labels(*frame.image, frame.full_scale, *result.ellipse, frame.period_px,
                                  frame.polarity, label_options, frame.illumination);
  if (!fit) return;
  const cv::Point2d shift(fit->ellipse.cx_px - result.ellipse->cx_px,
                          fit->ellipse.cy_px - result.ellipse->cy_px);
  if (!(cv::norm(shift) <= 0.5 * frame.period_px)) return;
  // The brackets' size and shape terms as well, where they are of the size the level edge's errors have (a
  // few px: at most half a period; see fit_brackets in contact/ridge_labels.cpp).
  const bool reshape = !frame.small_contact && std::hypot(fit->shape_size_px, fit->shape_cos2_px,
                                                          fit->shape_sin2_px) <= 0.5 * frame.period_px;
  for (auto& p : result.outline_px) p += shift;
  if (reshape) {
    apply_brackets(*fit, options, result);
  } else if (frame.small_contact && options.ridge_label_shape_weight > 0.0) {
    apply_blended_shape(*fit, shift, options, result);
  } else {
    for (auto& p : result.hull_px) p += shift;
    result.ellipse->cx_px += shift.x;
    result.ellipse->cy_px += shift.y;
  }
  const cv::Rect moved =
      cv::boundingRect(std::vector<cv::Point2f>(result.outline_px.begin(), result.outline_px.end()));
  result.bounding_box_px = moved & cv::Rect(0, 0, frame.image->cols, frame.image->rows);
  result.ridge_label_shift_px = shift;
  result.border_band_used = fit->border_band_used;
}

}  // namespace tirstrain::contact
