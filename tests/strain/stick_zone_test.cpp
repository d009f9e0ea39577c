// The stick radius c from a fit of the Cattaneo–Mindlin slip profile (strain/stick_zone.hpp): the basis
// against model/'s closed forms, c recovered from noisy track displacements on circular and elliptical
// contacts against the model's c, and the degenerate cases (full slip, no tangential load, slip beyond the
// tracks or rigid motion, too few tracks) giving defined values.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "model/cattaneo_mindlin.hpp"
#include "strain/stick_zone.hpp"

namespace tirstrain::strain {
namespace {

constexpr double kPxPerM = 52e3;  // 52 px/mm
constexpr double kMu = 1.0;
constexpr double kP = 2.0;

model::CattaneoMindlinParams params(double q_over_mu_p, double direction_rad, double radius_m = 0.02) {
  model::CattaneoMindlinParams p;
  p.normal_N = kP;
  p.friction = kMu;
  p.tangential_N = q_over_mu_p * kMu * kP;
  p.radius_m = radius_m;
  p.direction_rad = direction_rad;
  return p;
}

// The basis is (u − δ)/K with K = μp0·a/(4G) for traction along x and along y; a direction θ is
// cosθ·b_x + sinθ·b_y.
TEST(StickZone, SlipBasisIsTheModelsFieldRelativeToTheStickZone) {
  for (double q : {0.3, 0.8, 1.0}) {
    for (double direction : {0.0, std::numbers::pi / 2, 0.5, 4.2}) {
      const model::CattaneoMindlin m(params(q, direction));
      const double a = m.hertz().contact_radius_m;
      const double k = m.stick_radius_m() / a;
      const double big_k = kMu * m.hertz().peak_pressure_Pa * a / (4.0 * m.shear_modulus_Pa());
      const Vec2 shift{m.rigid_shift_m() * std::cos(direction), m.rigid_shift_m() * std::sin(direction)};
      for (double rho : {0.0, 0.2, 0.5, 0.75, 0.9, 0.999, 1.0, 1.3}) {
        for (double angle : {0.0, 0.7, 2.0, 3.9}) {
          const Vec2 p{rho * std::cos(angle), rho * std::sin(angle)};
          const Vec2 u = m.displacement_m(p.x * a, p.y * a);
          Vec2 bx, by;
          slip_basis(p, k, 0.4, bx, by);
          const double ex = big_k * (std::cos(direction) * bx.x + std::sin(direction) * by.x);
          const double ey = big_k * (std::cos(direction) * bx.y + std::sin(direction) * by.y);
          EXPECT_NEAR(u.x - shift.x, ex, 1e-12 * big_k) << q << " " << direction << " " << rho;
          EXPECT_NEAR(u.y - shift.y, ey, 1e-12 * big_k) << q << " " << direction << " " << rho;
        }
      }
    }
  }
}

struct Tracks {
  std::vector<Vec2> reference, current;
};

// Tracks on an 8 px grid over the contact (ellipse semi-axes in px, major axis at `angle`), displaced by
// the model field evaluated as samples/ does for an elliptical contact (coordinates mapped onto the disk,
// displacement unchanged), plus a plate/stuck-core offset, plus Gaussian noise σ per component; only out to
// `reach` of the normalised radius.
Tracks make_tracks(const model::CattaneoMindlin* m, double major_px, double minor_px, double angle,
                   Vec2 extra_px, double sigma_px, unsigned seed, double reach = 1.0) {
  const ContactDisk disk = contact_disk({400.0, 300.0}, major_px, minor_px, angle);
  const double a_m = m ? m->hertz().contact_radius_m : 0.0;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_px);
  Tracks t;
  for (double y = 300.0 - major_px; y <= 300.0 + major_px; y += 8.0)
    for (double x = 400.0 - major_px; x <= 400.0 + major_px; x += 8.0) {
      const double dx = x - 400.0, dy = y - 300.0;
      const Vec2 p{disk.to_disk.xx * dx + disk.to_disk.xy * dy, disk.to_disk.yx * dx + disk.to_disk.yy * dy};
      if (std::hypot(p.x, p.y) > reach) continue;
      Vec2 u;
      if (m) u = m->displacement_m(p.x * a_m, p.y * a_m);
      t.reference.push_back({x, y});
      t.current.push_back(
          {x + u.x * kPxPerM + extra_px.x + noise(rng), y + u.y * kPxPerM + extra_px.y + noise(rng)});
    }
  return t;
}

// The default scene's contact (R = 20 mm: a = 2.93 mm, 152 px) at the tracking noise of the default scene
// (0.06 px RMS per track, i.e. 0.042 px per component), distal loading.
TEST(StickZone, RecoversTheModelsStickRadiusOnACircularContact) {
  for (double c_over_a : {0.25, 0.4, 0.55, 0.7, 0.85}) {
    const double q = 1.0 - c_over_a * c_over_a * c_over_a;
    const model::CattaneoMindlin m(params(q, 1.5 * std::numbers::pi));
    const double a_px = m.hertz().contact_radius_m * kPxPerM;
    const Tracks t = make_tracks(&m, a_px, a_px, 0.0, {0.0, 0.0}, 0.042, 7);
    const StickZoneFit f =
        fit_stick_zone(t.reference, t.current, contact_disk({400.0, 300.0}, a_px, a_px, 0.0), 0.4);
    ASSERT_EQ(f.status, StickZoneStatus::kFit) << c_over_a;
    EXPECT_NEAR(f.radius_px / (m.stick_radius_m() * kPxPerM), 1.0, 0.02) << c_over_a;  // within 2 %
    EXPECT_NEAR(f.residual_rms_px, 0.042, 0.005);
    // The stuck core follows the plate: t = δ along the loading direction.
    EXPECT_NEAR(f.shift_px.y, -m.rigid_shift_m() * kPxPerM, 0.02) << c_over_a;
    EXPECT_NEAR(f.shift_px.x, 0.0, 0.02) << c_over_a;
  }
}

// The paper camera's contact: 4.5 × 5.5 mm semi-axes at 5°, the model on the equivalent circle
// a = sqrt(4.5 · 5.5) mm (how samples/ renders it); c = k·a.
TEST(StickZone, RecoversTheModelsStickRadiusOnAnEllipticalContact) {
  const double major_px = 5.5 * 52.0, minor_px = 4.5 * 52.0, angle = 5.0 * std::numbers::pi / 180.0;
  const double a_eq_m = std::sqrt(4.5e-3 * 5.5e-3);
  const double e_star = 1.0e6 / (1.0 - 0.4 * 0.4);
  const double radius_m = 4.0 * e_star * a_eq_m * a_eq_m * a_eq_m / (3.0 * kP);
  for (double c_over_a : {0.3, 0.6, 0.8}) {
    const double q = 1.0 - c_over_a * c_over_a * c_over_a;
    const model::CattaneoMindlin m(params(q, 1.5 * std::numbers::pi, radius_m));
    ASSERT_NEAR(m.hertz().contact_radius_m, a_eq_m, 1e-12);
    // The ellipse's major axis is along y rotated by 5°: semi-major at angle + 90°.
    const Tracks t =
        make_tracks(&m, major_px, minor_px, angle + 0.5 * std::numbers::pi, {0.3, -2.0}, 0.042, 11);
    const StickZoneFit f =
        fit_stick_zone(t.reference, t.current,
                       contact_disk({400.0, 300.0}, major_px, minor_px, angle + 0.5 * std::numbers::pi), 0.4);
    ASSERT_EQ(f.status, StickZoneStatus::kFit) << c_over_a;
    EXPECT_NEAR(f.radius_px / (m.stick_radius_m() * kPxPerM), 1.0, 0.02) << c_over_a;
  }
}

// c → 0: Q = μP gives the single-block field; the fit returns c = 0 (not NaN), also when the plate has moved
// on beyond the frozen skin (the stuck-core shift is free).
TEST(StickZone, FullSlipGivesZeroRadius) {
  const model::CattaneoMindlin m(params(1.0, 0.0));
  const double a_px = m.hertz().contact_radius_m * kPxPerM;
  const Tracks t = make_tracks(&m, a_px, a_px, 0.0, {25.0, 0.0}, 0.042, 3);
  const StickZoneFit f =
      fit_stick_zone(t.reference, t.current, contact_disk({400.0, 300.0}, a_px, a_px, 0.0), 0.4);
  EXPECT_EQ(f.status, StickZoneStatus::kFit);
  EXPECT_EQ(f.ratio, 0.0);  // a stick zone does not beat the full-slip fit: c = 0 exactly
  EXPECT_EQ(f.radius_px, 0.0);
}

// c → a: no tangential load (u = 0), or a load so small that neither the slip nor the stuck core's shift
// rises above the noise: no detectable slip, c = a exactly, never NaN.
TEST(StickZone, NoTangentialLoadGivesTheContactRadius) {
  const double a_px = 152.0;
  const ContactDisk disk = contact_disk({400.0, 300.0}, a_px, a_px, 0.0);
  for (double sigma : {0.0, 0.042}) {
    const Tracks t = make_tracks(nullptr, a_px, a_px, 0.0, {0.0, 0.0}, sigma, 5);
    const StickZoneFit f = fit_stick_zone(t.reference, t.current, disk, 0.4);
    EXPECT_EQ(f.status, StickZoneStatus::kNoSlip) << sigma;
    EXPECT_EQ(f.ratio, 1.0);
    EXPECT_DOUBLE_EQ(f.radius_px, a_px);
    EXPECT_NEAR(f.shift_px.x, 0.0, 0.01);
    EXPECT_NEAR(f.shift_px.y, 0.0, 0.01);
  }
  // Q = 1e-4 μP: c = 0.99997 a and the slip is far below the noise.
  const model::CattaneoMindlin m(params(1e-4, 0.0));
  const double a = m.hertz().contact_radius_m * kPxPerM;
  const Tracks t = make_tracks(&m, a, a, 0.0, {0.0, 0.0}, 0.042, 9);
  const StickZoneFit f = fit_stick_zone(t.reference, t.current, contact_disk({400.0, 300.0}, a, a, 0.0), 0.4);
  EXPECT_EQ(f.status, StickZoneStatus::kNoSlip);
  EXPECT_NEAR(f.radius_px, m.stick_radius_m() * kPxPerM, 1e-3 * a);
}

// A core that moved without slip inside the tracks: a rigid motion, or a load whose slip annulus lies beyond
// the outermost track (Cattaneo–Mindlin slips at the rim first). The tracks cannot tell these apart, so c is
// not reported as a but as not measured (NaN), with how far the tracks reached.
TEST(StickZone, SlipBeyondTheTracksLeavesTheRadiusUnmeasured) {
  const double a_px = 152.0;
  const ContactDisk disk = contact_disk({400.0, 300.0}, a_px, a_px, 0.0);
  for (double sigma : {0.0, 0.042}) {
    const Tracks t = make_tracks(nullptr, a_px, a_px, 0.0, {3.0, -1.5}, sigma, 5);
    const StickZoneFit f = fit_stick_zone(t.reference, t.current, disk, 0.4);
    EXPECT_EQ(f.status, StickZoneStatus::kSlipBeyondTracks) << sigma;
    EXPECT_TRUE(std::isnan(f.ratio));
    EXPECT_TRUE(std::isnan(f.radius_px));
    EXPECT_NEAR(f.shift_px.x, 3.0, 0.01);
    EXPECT_NEAR(f.shift_px.y, -1.5, 0.01);
    EXPECT_GT(f.reach, 0.9);  // the tracks fill the fit's extent, 0.95
    EXPECT_LE(f.reach, 0.95);
  }
  // c = 0.9 a with tracks out to 0.8 a only, at the default scene's tracking noise.
  const double c_over_a = 0.9;
  const model::CattaneoMindlin m(params(1.0 - c_over_a * c_over_a * c_over_a, 1.5 * std::numbers::pi));
  const double a = m.hertz().contact_radius_m * kPxPerM;
  const Tracks t = make_tracks(&m, a, a, 0.0, {0.0, 0.0}, 0.042, 11, 0.8);
  const StickZoneFit f = fit_stick_zone(t.reference, t.current, contact_disk({400.0, 300.0}, a, a, 0.0), 0.4);
  EXPECT_EQ(f.status, StickZoneStatus::kSlipBeyondTracks);
  EXPECT_TRUE(std::isnan(f.radius_px));
  EXPECT_NEAR(f.shift_px.y, -m.rigid_shift_m() * kPxPerM, 0.02);  // the core follows the plate
  EXPECT_GT(f.reach, 0.75);
  EXPECT_LE(f.reach * a, m.stick_radius_m() * kPxPerM);  // the annulus does lie beyond the tracks here
}

TEST(StickZone, TooFewTracksOrNoContactGiveNaNWithAStatus) {
  const std::vector<Vec2> ref = {{400.0, 300.0}, {410.0, 300.0}, {400.0, 310.0}};
  const std::vector<Vec2> cur = {{401.0, 300.0}, {411.0, 300.0}, {401.0, 310.0}};
  const StickZoneFit f = fit_stick_zone(ref, cur, contact_disk({400.0, 300.0}, 100.0, 100.0, 0.0), 0.4);
  EXPECT_EQ(f.status, StickZoneStatus::kTooFewPoints);
  EXPECT_TRUE(std::isnan(f.radius_px));
  const StickZoneFit empty = fit_stick_zone({}, {}, contact_disk({0.0, 0.0}, 100.0, 100.0, 0.0), 0.4);
  EXPECT_EQ(empty.status, StickZoneStatus::kTooFewPoints);
  const StickZoneFit no_contact = fit_stick_zone(ref, cur, contact_disk({0.0, 0.0}, 0.0, 0.0, 0.0), 0.4);
  EXPECT_EQ(no_contact.status, StickZoneStatus::kTooFewPoints);
  EXPECT_TRUE(std::isnan(no_contact.ratio));
}

}  // namespace
}  // namespace tirstrain::strain
