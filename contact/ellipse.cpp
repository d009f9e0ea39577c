#include "contact/ellipse.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <numbers>

namespace tirstrain::contact {
namespace {

// Conic A x^2 + B xy + C y^2 + D x + E y + F = 0 to centre, axes and angle; nothing if not a real ellipse.
std::optional<Ellipse> conic_to_ellipse(const Eigen::Matrix<double, 6, 1>& k) {
  const double a = k(0), b = k(1), c = k(2), d = k(3), e = k(4), f = k(5);
  const double det = 4.0 * a * c - b * b;
  if (!(det > 0.0)) return std::nullopt;
  const double x0 = (b * e - 2.0 * c * d) / det;
  const double y0 = (b * d - 2.0 * a * e) / det;
  const double f0 = a * x0 * x0 + b * x0 * y0 + c * y0 * y0 + d * x0 + e * y0 + f;
  Eigen::Matrix2d q;
  q << a, b / 2.0, b / 2.0, c;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(q);
  // Both eigenvalues share the sign of A; the point set is an ellipse only if -f0 has that sign too.
  const double l_small = eig.eigenvalues()(0), l_large = eig.eigenvalues()(1);
  double r_major2 = -f0 / l_small, r_minor2 = -f0 / l_large;
  Eigen::Vector2d major_dir = eig.eigenvectors().col(0);
  if (l_small < 0.0) {  // negative definite: the roles of the eigenvalues swap
    r_major2 = -f0 / l_large;
    r_minor2 = -f0 / l_small;
    major_dir = eig.eigenvectors().col(1);
  }
  if (!(r_major2 > 0.0) || !(r_minor2 > 0.0) || !std::isfinite(r_major2) || !std::isfinite(r_minor2))
    return std::nullopt;
  if (r_minor2 > r_major2) {
    std::swap(r_major2, r_minor2);
    major_dir = Eigen::Vector2d(-major_dir(1), major_dir(0));
  }
  double angle = std::atan2(major_dir(1), major_dir(0));
  if (angle <= -std::numbers::pi / 2.0) angle += std::numbers::pi;
  if (angle > std::numbers::pi / 2.0) angle -= std::numbers::pi;
  return Ellipse{x0, y0, std::sqrt(r_major2), std::sqrt(r_minor2), angle};
}

}  // namespace

std::optional<Ellipse> fit_ellipse_direct(std::span<const cv::Point2d> points_px) {
  const auto n = static_cast<Eigen::Index>(points_px.size());
  if (n < 6) return std::nullopt;
  // Centring and scaling to unit RMS radius keeps the scatter matrices well conditioned for contacts
  // hundreds of pixels from the origin; the fit is done in these coordinates and mapped back.
  double mx = 0.0, my = 0.0;
  for (const auto& p : points_px) {
    mx += p.x;
    my += p.y;
  }
  mx /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double spread = 0.0;
  for (const auto& p : points_px) spread += (p.x - mx) * (p.x - mx) + (p.y - my) * (p.y - my);
  spread = std::sqrt(spread / static_cast<double>(n));
  if (!(spread > 0.0) || !std::isfinite(spread)) return std::nullopt;

  Eigen::MatrixXd d1(n, 3), d2(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double x = (points_px[static_cast<std::size_t>(i)].x - mx) / spread;
    const double y = (points_px[static_cast<std::size_t>(i)].y - my) / spread;
    d1.row(i) << x * x, x * y, y * y;
    d2.row(i) << x, y, 1.0;
  }
  // Halíř & Flusser: eliminate the linear part (S3 is 3x3 and regular unless the points are collinear),
  // leaving a 3x3 eigenproblem with the constraint 4AC - B^2 = 1 instead of Fitzgibbon's singular 6x6 one.
  const Eigen::Matrix3d s1 = d1.transpose() * d1;
  const Eigen::Matrix3d s2 = d1.transpose() * d2;
  const Eigen::Matrix3d s3 = d2.transpose() * d2;
  const Eigen::FullPivLU<Eigen::Matrix3d> s3_lu(s3);
  if (!s3_lu.isInvertible()) return std::nullopt;
  const Eigen::Matrix3d t = -s3_lu.solve(s2.transpose());
  const Eigen::Matrix3d m = s1 + s2 * t;
  Eigen::Matrix3d reduced;  // C1^-1 * M with C1 = [[0,0,2],[0,-1,0],[2,0,0]]
  reduced.row(0) = m.row(2) / 2.0;
  reduced.row(1) = -m.row(1);
  reduced.row(2) = m.row(0) / 2.0;
  const Eigen::EigenSolver<Eigen::Matrix3d> eig(reduced);
  if (eig.info() != Eigen::Success) return std::nullopt;
  const Eigen::Matrix3cd vectors = eig.eigenvectors();
  int best = -1;
  double best_constraint = 0.0;
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d v = vectors.col(j).real();
    const double constraint = 4.0 * v(0) * v(2) - v(1) * v(1);
    if (constraint > best_constraint) {
      best_constraint = constraint;
      best = j;
    }
  }
  if (best < 0) return std::nullopt;
  const Eigen::Vector3d a1 = vectors.col(best).real();
  const Eigen::Vector3d a2 = t * a1;
  Eigen::Matrix<double, 6, 1> conic;
  conic << a1, a2;
  std::optional<Ellipse> e = conic_to_ellipse(conic);
  if (!e) return std::nullopt;
  e->cx_px = e->cx_px * spread + mx;
  e->cy_px = e->cy_px * spread + my;
  e->semi_major_px *= spread;
  e->semi_minor_px *= spread;
  if (!std::isfinite(e->cx_px) || !std::isfinite(e->cy_px) || !std::isfinite(e->semi_major_px))
    return std::nullopt;
  return e;
}

std::vector<cv::Point2d> sample_ellipse(const Ellipse& ellipse, int count, double t0_rad, double t1_rad) {
  std::vector<cv::Point2d> points;
  if (count <= 0) return points;
  points.reserve(static_cast<std::size_t>(count));
  const double c = std::cos(ellipse.angle_rad), s = std::sin(ellipse.angle_rad);
  for (int i = 0; i < count; ++i) {
    const double t = count == 1 ? t0_rad : t0_rad + (t1_rad - t0_rad) * i / (count - 1);
    const double u = ellipse.semi_major_px * std::cos(t), v = ellipse.semi_minor_px * std::sin(t);
    points.emplace_back(ellipse.cx_px + c * u - s * v, ellipse.cy_px + s * u + c * v);
  }
  return points;
}

double ellipse_level(const Ellipse& ellipse, const cv::Point2d& p_px) {
  const double c = std::cos(ellipse.angle_rad), s = std::sin(ellipse.angle_rad);
  const double dx = p_px.x - ellipse.cx_px, dy = p_px.y - ellipse.cy_px;
  const double u = (c * dx + s * dy) / ellipse.semi_major_px;
  const double v = (-s * dx + c * dy) / ellipse.semi_minor_px;
  return u * u + v * v - 1.0;
}

cv::Matx23d ellipse_to_ellipse(const Ellipse& from, const Ellipse& to) {
  const double cf = std::cos(from.angle_rad), sf = std::sin(from.angle_rad);
  const double ct = std::cos(to.angle_rad), st = std::sin(to.angle_rad);
  // R(to) diag(a_to / a_from, b_to / b_from) R(-from), then the centres.
  const cv::Matx22d unrotate(cf, sf, -sf, cf), rotate(ct, -st, st, ct);
  const cv::Matx22d scale(to.semi_major_px / from.semi_major_px, 0.0, 0.0,
                          to.semi_minor_px / from.semi_minor_px);
  const cv::Matx22d linear = rotate * scale * unrotate;
  const cv::Vec2d shift = cv::Vec2d(to.cx_px, to.cy_px) - linear * cv::Vec2d(from.cx_px, from.cy_px);
  return {linear(0, 0), linear(0, 1), shift[0], linear(1, 0), linear(1, 1), shift[1]};
}

EllipseNormalization::EllipseNormalization(const Ellipse& ellipse)
    : cx_(ellipse.cx_px),
      cy_(ellipse.cy_px),
      cos_(std::cos(ellipse.angle_rad)),
      sin_(std::sin(ellipse.angle_rad)),
      scale_(ellipse.semi_major_px > 0.0 ? 1.0 / ellipse.semi_major_px : 1.0),
      aspect_(ellipse.semi_major_px > 0.0 ? ellipse.semi_minor_px / ellipse.semi_major_px : 1.0) {}

cv::Point2d EllipseNormalization::normalize(const cv::Point2d& p_px) const {
  const double dx = p_px.x - cx_, dy = p_px.y - cy_;
  return {scale_ * (cos_ * dx + sin_ * dy), scale_ * (-sin_ * dx + cos_ * dy)};
}

cv::Point2d EllipseNormalization::denormalize(const cv::Point2d& q) const {
  const double u = q.x / scale_, v = q.y / scale_;
  return {cx_ + cos_ * u - sin_ * v, cy_ + sin_ * u + cos_ * v};
}

cv::Matx23d EllipseNormalization::forward_matrix() const {
  const double a = scale_ * cos_, b = scale_ * sin_;
  return {a, b, -(a * cx_ + b * cy_), -b, a, -(-b * cx_ + a * cy_)};
}

cv::Matx23d EllipseNormalization::inverse_matrix() const {
  const double a = cos_ / scale_, b = sin_ / scale_;
  return {a, -b, cx_, b, a, cy_};
}

}  // namespace tirstrain::contact
