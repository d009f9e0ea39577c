// Ellipse fit and normalisation: exact recovery of known ellipses, round trips, degenerate inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "contact/ellipse.hpp"
#include "contact/geometry.hpp"

namespace tirstrain::contact {
namespace {

double angle_difference_mod_pi(double a, double b) {
  double d = std::fmod(std::abs(a - b), std::numbers::pi);
  return std::min(d, std::numbers::pi - d);
}

void expect_recovers(const Ellipse& truth, const std::vector<cv::Point2d>& points, double tol_px,
                     bool check_angle) {
  const auto fit = fit_ellipse_direct(points);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->cx_px, truth.cx_px, tol_px);
  EXPECT_NEAR(fit->cy_px, truth.cy_px, tol_px);
  EXPECT_NEAR(fit->semi_major_px, truth.semi_major_px, tol_px);
  EXPECT_NEAR(fit->semi_minor_px, truth.semi_minor_px, tol_px);
  if (check_angle) {
    EXPECT_LT(angle_difference_mod_pi(fit->angle_rad, truth.angle_rad), 1e-9);
  }
  // Every input point lies on the fitted ellipse.
  for (const auto& p : points) EXPECT_NEAR(ellipse_level(*fit, p), 0.0, 1e-9);
}

TEST(EllipseFit, RecoversGeneralEllipseFrom50Points) {
  const Ellipse truth{612.25, 498.75, 261.5, 180.25, 0.6};
  expect_recovers(truth, sample_ellipse(truth, 50, 0.0, 2.0 * std::numbers::pi * 49.0 / 50.0), 1e-8, true);
}

TEST(EllipseFit, RecoversNearlyCircularEllipse) {
  // Axes 1e-4 apart: the angle is barely defined, so only centre, axes and the points are checked.
  const Ellipse truth{300.0, 200.0, 150.0001, 150.0, -1.1};
  expect_recovers(truth, sample_ellipse(truth, 50, 0.3, 0.3 + 2.0 * std::numbers::pi * 49.0 / 50.0), 1e-7,
                  false);
  const Ellipse circle{300.0, 200.0, 150.0, 150.0, 0.0};
  expect_recovers(circle, sample_ellipse(circle, 50, 0.0, 6.0), 1e-8, false);
}

TEST(EllipseFit, RecoversVeryElongatedEllipse) {
  const Ellipse truth{640.0, 512.0, 500.0, 12.5, 1.3};
  expect_recovers(truth, sample_ellipse(truth, 50, 0.0, 2.0 * std::numbers::pi * 49.0 / 50.0), 1e-7, true);
}

TEST(EllipseFit, RecoversEllipseFromQuarterArc) {
  const Ellipse truth{400.0, 350.0, 220.0, 140.0, -0.35};
  expect_recovers(truth, sample_ellipse(truth, 50, 0.2, 0.2 + std::numbers::pi / 2.0), 1e-6, true);
}

TEST(EllipseFit, NoisyPointsGiveCloseEllipse) {
  const Ellipse truth{500.0, 400.0, 250.0, 170.0, 0.25};
  auto points = sample_ellipse(truth, 50, 0.0, 2.0 * std::numbers::pi * 49.0 / 50.0);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.5);
  for (auto& p : points) p += cv::Point2d(noise(rng), noise(rng));
  const auto fit = fit_ellipse_direct(points);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->cx_px, truth.cx_px, 0.3);
  EXPECT_NEAR(fit->cy_px, truth.cy_px, 0.3);
  EXPECT_NEAR(fit->semi_major_px / truth.semi_major_px, 1.0, 0.005);
  EXPECT_NEAR(fit->semi_minor_px / truth.semi_minor_px, 1.0, 0.005);
  EXPECT_LT(angle_difference_mod_pi(fit->angle_rad, truth.angle_rad), 0.01);
}

TEST(EllipseFit, DegenerateInputsGiveNothing) {
  std::vector<cv::Point2d> five = {{0, 0}, {1, 0}, {0, 1}, {2, 3}, {4, 1}};
  EXPECT_FALSE(fit_ellipse_direct(five).has_value());
  std::vector<cv::Point2d> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(i, 2.0 * i + 1.0);
  EXPECT_FALSE(fit_ellipse_direct(line).has_value());
  std::vector<cv::Point2d> same(10, cv::Point2d(5, 5));
  EXPECT_FALSE(fit_ellipse_direct(same).has_value());
  // A hyperbola's points: no ellipse passes through them, and the fit must not invent a NaN one.
  std::vector<cv::Point2d> hyperbola;
  for (int i = 1; i <= 20; ++i) hyperbola.emplace_back(i, 10.0 / i);
  const auto fit = fit_ellipse_direct(hyperbola);
  if (fit) {
    EXPECT_TRUE(std::isfinite(fit->cx_px) && std::isfinite(fit->semi_major_px) &&
                std::isfinite(fit->angle_rad));
  }
}

TEST(EllipseNormalization, MapsEllipseOntoStandardEllipseAndBack) {
  const Ellipse e{612.25, 498.75, 261.5, 180.25, 0.6};
  const EllipseNormalization n(e);
  EXPECT_DOUBLE_EQ(n.aspect(), 180.25 / 261.5);
  for (const auto& p : sample_ellipse(e, 50, 0.0, 6.0)) {
    const cv::Point2d q = n.normalize(p);
    EXPECT_NEAR(q.x * q.x + (q.y / n.aspect()) * (q.y / n.aspect()), 1.0, 1e-12);
  }
  const cv::Point2d centre = n.normalize({e.cx_px, e.cy_px});
  EXPECT_NEAR(centre.x, 0.0, 1e-12);
  EXPECT_NEAR(centre.y, 0.0, 1e-12);
  const cv::Point2d major_end = n.normalize(sample_ellipse(e, 1, 0.0, 0.0)[0]);
  EXPECT_NEAR(major_end.x, 1.0, 1e-12);
  EXPECT_NEAR(major_end.y, 0.0, 1e-12);

  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-2000.0, 3000.0);
  double worst_px = 0.0;
  const cv::Matx23d forward = n.forward_matrix(), inverse = n.inverse_matrix();
  for (int i = 0; i < 1000; ++i) {
    const cv::Point2d p(coordinate(rng), coordinate(rng));
    worst_px = std::max(worst_px, cv::norm(n.denormalize(n.normalize(p)) - p));
    const cv::Point2d q = n.normalize(p);
    const cv::Point2d q_matrix(forward(0, 0) * p.x + forward(0, 1) * p.y + forward(0, 2),
                               forward(1, 0) * p.x + forward(1, 1) * p.y + forward(1, 2));
    EXPECT_LT(cv::norm(q - q_matrix), 1e-12);
    const cv::Point2d back(inverse(0, 0) * q.x + inverse(0, 1) * q.y + inverse(0, 2),
                           inverse(1, 0) * q.x + inverse(1, 1) * q.y + inverse(1, 2));
    EXPECT_LT(cv::norm(back - p), 1e-9);
  }
  EXPECT_LT(worst_px, 1e-9);
}

// The map between two ellipses carries the border onto the border, point for point at the same parameter,
// and the centre onto the centre; between an ellipse and itself it is the identity.
TEST(EllipseToEllipse, CarriesBorderOntoBorder) {
  const Ellipse from{101.5, 87.25, 45.0, 43.5, 1.2};
  const Ellipse to{103.0, 86.0, 44.6, 42.9, -0.4};
  const cv::Matx23d map = ellipse_to_ellipse(from, to);
  const auto apply = [&](const cv::Point2d& p) {
    const cv::Vec2d q = map * cv::Vec3d(p.x, p.y, 1.0);
    return cv::Point2d(q[0], q[1]);
  };
  const std::vector<cv::Point2d> border_from = sample_ellipse(from, 36, 0.0, 6.1);
  const std::vector<cv::Point2d> border_to = sample_ellipse(to, 36, 0.0, 6.1);
  for (std::size_t i = 0; i < border_from.size(); ++i) {
    EXPECT_LT(cv::norm(apply(border_from[i]) - border_to[i]), 1e-9) << i;
    EXPECT_NEAR(ellipse_level(to, apply(border_from[i])), 0.0, 1e-12);
  }
  EXPECT_LT(cv::norm(apply({from.cx_px, from.cy_px}) - cv::Point2d(to.cx_px, to.cy_px)), 1e-12);
  const cv::Matx23d identity = ellipse_to_ellipse(from, from);
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(identity(r, c), r == c ? 1.0 : 0.0, 1e-12);
}

TEST(Geometry, ResampledPolygonPointsAreEquallySpaced) {
  // Perimeter 400 and sides that are multiples of 8, so every step of 400 / 50 = 8 is a straight chord.
  const std::vector<cv::Point2d> rectangle = {{0, 0}, {120, 0}, {120, 80}, {0, 80}};
  const auto points = resample_closed_polygon(rectangle, 50);
  ASSERT_EQ(points.size(), 50u);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_NEAR(cv::norm(points[(i + 1) % points.size()] - points[i]), 8.0, 1e-9);
  EXPECT_NEAR(polygon_area_px2(rectangle), 9600.0, 1e-9);
}

TEST(Geometry, RasterizedPolygonCountsPixelCentres) {
  // A 10 x 10 square with corners at pixel edges covers exactly 100 pixel centres.
  const std::vector<cv::Point2d> square = {{1.5, 1.5}, {11.5, 1.5}, {11.5, 11.5}, {1.5, 11.5}};
  const cv::Mat mask = rasterize_polygon(square, {20, 20});
  EXPECT_EQ(cv::countNonZero(mask), 100);
  EXPECT_DOUBLE_EQ(mask_iou(mask, mask), 1.0);
}

}  // namespace
}  // namespace tirstrain::contact
