#pragma once
// Ellipses in image coordinates (x right, y down, pixels): the direct least-squares fit of Fitzgibbon,
// Pilu & Fisher (1999) in the numerically stable form of Halíř & Flusser (1998), and the similarity
// transform (translation, rotation, uniform scale) that carries an ellipse onto the standard normalised
// ellipse — centred at the origin, major axis along +x, semi-major axis 1 — and back.
#include <opencv2/core/matx.hpp>
#include <opencv2/core/types.hpp>

#include <cmath>
#include <optional>
#include <span>
#include <vector>

namespace tirstrain::contact {

struct Ellipse {
  double cx_px = 0.0;
  double cy_px = 0.0;
  double semi_major_px = 0.0;
  double semi_minor_px = 0.0;
  // Direction of the major axis, measured from +x towards +y (clockwise on screen), in (-pi/2, pi/2].
  double angle_rad = 0.0;
};

// Fits an ellipse to >= 6 points. Returns nothing when the points do not determine one (too few,
// collinear, or the best conic is not an ellipse); never returns NaN.
std::optional<Ellipse> fit_ellipse_direct(std::span<const cv::Point2d> points_px);

// `count` points at equal parameter steps of the ellipse's parametric form between t0 and t1 (radians).
std::vector<cv::Point2d> sample_ellipse(const Ellipse& ellipse, int count, double t0_rad, double t1_rad);

// Algebraic "distance" normalised so that 0 is on the ellipse, <0 inside, >0 outside:
// |q|^2 - 1 in the ellipse's own axes scaled to a unit circle.
double ellipse_level(const Ellipse& ellipse, const cv::Point2d& p_px);

// The affine map that carries `from` onto `to`: a point's position in `from`'s axes, each scaled to 1, put at
// the same place in `to`'s (centre to centre, border to border). Used to move an outline with its ellipse.
cv::Matx23d ellipse_to_ellipse(const Ellipse& from, const Ellipse& to);

// q = scale * R(-angle) * (p - centre): the ellipse goes to the standard normalised ellipse
// x^2 + (y / aspect)^2 = 1 with aspect = semi_minor / semi_major.
class EllipseNormalization {
 public:
  EllipseNormalization() = default;
  explicit EllipseNormalization(const Ellipse& ellipse);

  cv::Point2d normalize(const cv::Point2d& p_px) const;
  cv::Point2d denormalize(const cv::Point2d& q) const;
  // The same maps as 2x3 affine matrices [s R | t], for cv::transform / cv::warpAffine.
  cv::Matx23d forward_matrix() const;
  cv::Matx23d inverse_matrix() const;

  double scale_per_px() const { return scale_; }  // 1 / semi_major_px
  double aspect() const { return aspect_; }
  // The map's +x in the image, radians from +x towards +y: the major axis's direction, or 0.
  double angle_rad() const { return std::atan2(sin_, cos_); }

 private:
  double cx_ = 0.0, cy_ = 0.0, cos_ = 1.0, sin_ = 0.0, scale_ = 1.0, aspect_ = 1.0;
};

}  // namespace tirstrain::contact
