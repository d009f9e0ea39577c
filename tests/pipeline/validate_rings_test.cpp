// Coverage and accuracy by ring of the true contact (pipeline/validate_rings.hpp) on a drawn disk, where
// every ring's area and every coverage is known in closed form.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>

#include "pipeline/validate_rings.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kRadius = 100.0;
constexpr Vec2 kCentre{160.0, 120.0};

RingValidation disk_rings() {
  cv::Mat mask(240, 320, CV_8U, cv::Scalar(0));
  cv::circle(mask, cv::Point(160, 120), static_cast<int>(kRadius), cv::Scalar(255), cv::FILLED);
  contact::Ellipse e;
  e.cx_px = kCentre.x;
  e.cy_px = kCentre.y;
  e.semi_major_px = e.semi_minor_px = kRadius + 0.5;
  return RingValidation(mask, e);
}

// A fan of triangles covering the disk out to `rho` of its radius.
std::vector<std::array<Vec2, 3>> fan(double rho) {
  std::vector<std::array<Vec2, 3>> triangles;
  const int n = 720;
  for (int i = 0; i < n; ++i) {
    const double a0 = 2.0 * std::numbers::pi * i / n, a1 = 2.0 * std::numbers::pi * (i + 1) / n;
    const double r = rho * kRadius;
    triangles.push_back({kCentre, Vec2{kCentre.x + r * std::cos(a0), kCentre.y + r * std::sin(a0)},
                         Vec2{kCentre.x + r * std::cos(a1), kCentre.y + r * std::sin(a1)}});
  }
  return triangles;
}

TEST(ValidateRings, RingsOfAPointFollowTheEllipse) {
  const RingValidation rings = disk_rings();
  EXPECT_EQ(rings.ring_of({kCentre.x + 10.0, kCentre.y}), 0);
  EXPECT_EQ(rings.ring_of({kCentre.x, kCentre.y + 70.0}), 1);
  EXPECT_EQ(rings.ring_of({kCentre.x - 90.0, kCentre.y}), 2);
  EXPECT_EQ(rings.ring_of({kCentre.x + 99.0, kCentre.y}), 3);
  EXPECT_EQ(rings.ring_of({kCentre.x + 120.0, kCentre.y}), -1);
}

TEST(ValidateRings, CoverageByRingIsTheCoveredAreasShare) {
  RingValidation rings = disk_rings();
  // Covered out to 0.9 a: the two inner rings fully, [0.85, 0.95) by (0.9² − 0.85²)/(0.95² − 0.85²) = 48.6 %,
  // the outermost not at all; the whole contact 0.81 of its area. Pixel rasterisation: within 1.5 points.
  rings.add_frame_coverage(fan(0.9));
  // And a second frame with nothing: the means halve, the minima are 0.
  rings.add_frame_coverage({});
  EXPECT_NEAR(rings.mean_coverage_pct(0), 50.0, 0.5);
  EXPECT_NEAR(rings.mean_coverage_pct(1), 50.0, 0.5);
  EXPECT_NEAR(rings.mean_coverage_pct(2), 0.5 * 100.0 * (0.81 - 0.7225) / (0.9025 - 0.7225), 1.5);
  EXPECT_NEAR(rings.mean_coverage_pct(3), 0.0, 0.5);
  EXPECT_NEAR(rings.mean_coverage_pct(-1), 0.5 * 81.0, 1.0);
  EXPECT_EQ(rings.min_coverage_pct(-1), 0.0);

  // validation.csv rows: the coverage deficit's mean is 100 − mean coverage, its max the worst frame's.
  bool found = false;
  for (const ErrorStats& row : rings.rows())
    if (row.quantity == "coverage_deficit_ring_0-0.5") {
      found = true;
      EXPECT_NEAR(row.mean, 50.0, 0.5);
      EXPECT_NEAR(row.max_abs, 100.0, 1e-9);
      EXPECT_EQ(row.samples, 2);
    }
  EXPECT_TRUE(found);
}

TEST(ValidateRings, ErrorsAndCalibrationGoToTheRingOfThePoint) {
  RingValidation rings = disk_rings();
  // Two tracks in the outer ring with 0.3 px errors, predicted σ 0.1 px per coordinate: z = 3.
  rings.add_track({kCentre.x + 97.0, kCentre.y}, {0.3, 0.0}, {0.01, 0.0, 0.01});
  rings.add_track({kCentre.x - 97.0, kCentre.y}, {0.0, -0.3}, {0.01, 0.0, 0.01});
  // One in the centre, no covariance: counted in the RMS, not in the calibration.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rings.add_track(kCentre, {0.03, 0.04}, {nan, nan, nan});
  rings.add_triangle({kCentre.x + 97.0, kCentre.y}, {0.02, -0.01, 0.0}, {0.01, 0.01, 0.01});
  double outer_disp = 0.0, outer_z = 0.0, inner_disp = 0.0, outer_exx = 0.0, outer_strain_z = 0.0;
  long inner_z_samples = -1;
  for (const ErrorStats& row : rings.rows()) {
    if (row.quantity == "displacement_ring_0.95-1") outer_disp = row.rms;
    if (row.quantity == "displacement_z_ring_0.95-1") outer_z = row.rms;
    if (row.quantity == "displacement_ring_0-0.5") inner_disp = row.rms;
    if (row.quantity == "displacement_z_ring_0-0.5") inner_z_samples = row.samples;
    if (row.quantity == "E_xx_ring_0.95-1") outer_exx = row.rms;
    if (row.quantity == "strain_z_ring_0.95-1") outer_strain_z = row.rms;
  }
  EXPECT_NEAR(outer_disp, 0.3, 1e-12);
  EXPECT_NEAR(outer_z, 3.0 / std::sqrt(2.0), 1e-9);  // Mahalanobis distance per coordinate
  EXPECT_NEAR(inner_disp, 0.05, 1e-12);
  EXPECT_EQ(inner_z_samples, 0);
  EXPECT_NEAR(outer_exx, 0.02, 1e-12);
  EXPECT_NEAR(outer_strain_z, std::sqrt((4.0 + 1.0 + 0.0) / 3.0), 1e-9);
}

}  // namespace
}  // namespace tirstrain::pipeline
