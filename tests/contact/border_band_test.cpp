// The border band's intensity fit (contact/border_band.cpp) on bands drawn from its own model with known
// truth: the ellipse and the border profile come back from an offset start, the sectors' wave vectors are
// refined when given a few percent off, noise costs little, and a band with no ridges gives no fit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "contact/border_band.hpp"
#include "core/smoothstep.hpp"

namespace tirstrain::contact {
namespace {

constexpr double kPeriodPx = 23.0;
constexpr int kSectors = 24;
constexpr double kEdgePx = 1.0, kFloor = 0.35, kFadePx = 20.0, kLevel = 0.2;

struct Band {
  std::vector<BorderBandSample> samples;
  std::vector<cv::Vec2d> true_waves;
};

// Samples on a 2 px lattice from 1.5 periods inside `truth` to 0.75 period outside, each sector's ridges a
// plane wave: in half the sectors along the border (a valley or a crest runs along it), in the others across
// it (ridges end against it), with phases that differ per sector. Ridge signal kLevel (1 + cos) under the
// border profile, plus Gaussian noise of `noise` (ridge-signal units).
Band draw_band(const Ellipse& truth, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  Band band;
  std::vector<double> phases(kSectors);
  const double k = 2.0 * std::numbers::pi / kPeriodPx;
  std::vector<cv::Point2d> origins(kSectors);
  for (int s = 0; s < kSectors; ++s) {
    const double phi = (s + 0.5) * 2.0 * std::numbers::pi / kSectors;
    // The normal direction of a near-circle is about radial: waves radial (along the border) or tangential.
    const double direction = phi + (s % 2 == 0 ? 0.0 : 0.5 * std::numbers::pi) + 0.1 * normal(rng);
    band.true_waves.emplace_back(k * std::cos(direction), k * std::sin(direction));
    phases[static_cast<std::size_t>(s)] = phase(rng);
    origins[static_cast<std::size_t>(s)] = {truth.cx_px + 0.9 * truth.semi_minor_px * std::cos(phi),
                                            truth.cy_px + 0.9 * truth.semi_minor_px * std::sin(phi)};
  }
  const double c = std::cos(truth.angle_rad), sn = std::sin(truth.angle_rad);
  const double reach = truth.semi_major_px + kPeriodPx;
  for (double y = truth.cy_px - reach; y <= truth.cy_px + reach; y += 2.0) {
    for (double x = truth.cx_px - reach; x <= truth.cx_px + reach; x += 2.0) {
      const double dx = x - truth.cx_px, dy = y - truth.cy_px;
      const double u = (c * dx + sn * dy) / truth.semi_major_px,
                   v = (-sn * dx + c * dy) / truth.semi_minor_px;
      const double q = std::hypot(u, v);
      if (q < 1e-9) continue;
      const double d = std::hypot(dx, dy) * (1.0 - 1.0 / q);
      if (d < -1.5 * kPeriodPx || d > 0.75 * kPeriodPx) continue;
      double phi = std::atan2(dy, dx);
      if (phi < 0.0) phi += 2.0 * std::numbers::pi;
      const int s = std::min(kSectors - 1, static_cast<int>(phi / (2.0 * std::numbers::pi) * kSectors));
      const cv::Point2d o = origins[static_cast<std::size_t>(s)];
      const cv::Vec2d w = band.true_waves[static_cast<std::size_t>(s)];
      const double ridge =
          1.0 + std::cos(w[0] * (x - o.x) + w[1] * (y - o.y) + phases[static_cast<std::size_t>(s)]);
      const double profile =
          1.0 / (1.0 + std::exp(d / kEdgePx)) * (kFloor + (1.0 - kFloor) * smoothstep5(-d / kFadePx));
      const double signal = kLevel * profile * ridge + noise * normal(rng);
      band.samples.push_back({s, static_cast<float>(x), static_cast<float>(y), static_cast<float>(signal),
                              static_cast<float>(x - o.x), static_cast<float>(y - o.y)});
    }
  }
  return band;
}

const Ellipse kTruth{300.3, 250.7, 150.0, 120.0, 0.3};

Ellipse offset_start() {
  Ellipse start = kTruth;
  start.cx_px += 2.0;
  start.cy_px -= 1.5;
  start.semi_major_px *= 1.03;
  start.semi_minor_px *= 0.98;
  start.angle_rad += 0.02;
  return start;
}

double centre_error_px(const Ellipse& e) {
  return std::hypot(e.cx_px - kTruth.cx_px, e.cy_px - kTruth.cy_px);
}

// Drawn from the model itself, without noise and with the true wave vectors: exact recovery (the distance
// approximation r (1 - 1/q) is the same on both sides). Measured: centre 2e-5 px.
TEST(BorderBand, RecoversTheEllipseAndProfileExactly) {
  const Band band = draw_band(kTruth, 0.0, 1);
  const auto fit = fit_border_band(band.samples, band.true_waves, offset_start(), kPeriodPx);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(centre_error_px(fit->ellipse), 1e-3);
  EXPECT_NEAR(fit->ellipse.semi_major_px, kTruth.semi_major_px, 1e-3);
  EXPECT_NEAR(fit->ellipse.semi_minor_px, kTruth.semi_minor_px, 1e-3);
  EXPECT_NEAR(fit->ellipse.angle_rad, kTruth.angle_rad, 1e-5);
  EXPECT_NEAR(fit->edge_px, kEdgePx, 1e-3);
  EXPECT_NEAR(fit->fade_floor, kFloor, 1e-3);
  EXPECT_NEAR(fit->fade_px, kFadePx, 1e-2);
  EXPECT_LT(fit->rms_residual, 1e-5);
}

// The fit's Jacobian is built from the profile's analytic derivatives: each against central differences,
// at a start off the truth with the soft edge and the fade both active (measured: relative error < 3e-9).
TEST(BorderBand, ProfileGradientMatchesCentralDifferences) {
  const Band band = draw_band(kTruth, 0.0, 4);
  const Ellipse e = offset_start();
  BorderBandParams p;
  p << e.cx_px, e.cy_px, e.semi_major_px, e.semi_minor_px, e.angle_rad, 1.4, 0.3, 18.0;
  BorderBandGradient gradient;
  const Eigen::VectorXd profile = border_profile(band.samples, p, &gradient);
  ASSERT_EQ(gradient.rows(), profile.size());
  ASSERT_GT(profile.size(), 1000);
  for (int j = 0; j < 8; ++j) {
    const double h = 1e-6 * std::max(1.0, std::abs(p(j)));
    BorderBandParams up = p, down = p;
    up(j) += h;
    down(j) -= h;
    const Eigen::VectorXd central =
        (border_profile(band.samples, up) - border_profile(band.samples, down)) / (2.0 * h);
    const double scale = central.cwiseAbs().maxCoeff();
    ASSERT_GT(scale, 1e-3) << "parameter " << j << " does not move the profile";
    EXPECT_LT((central - gradient.col(j)).cwiseAbs().maxCoeff() / scale, 1e-6) << "parameter " << j;
  }
}

// The window's wave vectors are a few percent off where the skin is stretched or the ridges curve: 4 % in
// period and 3 degrees in direction here. The refinement brings them back (measured: centre 0.0003 px with
// it, 0.014 px without; on the synthetic trials, where ridges curve, the refinement's gain is larger:
// BENCHMARKS.md, contact/).
TEST(BorderBand, RefinesWaveVectorsGivenOff) {
  const Band band = draw_band(kTruth, 0.0, 2);
  std::vector<cv::Vec2d> off;
  for (std::size_t s = 0; s < band.true_waves.size(); ++s) {
    const double scale = s % 2 == 0 ? 1.04 : 0.96,
                 turn = (s % 3 == 0 ? 3.0 : -3.0) * std::numbers::pi / 180.0;
    const cv::Vec2d w = band.true_waves[s];
    off.emplace_back(scale * (std::cos(turn) * w[0] - std::sin(turn) * w[1]),
                     scale * (std::sin(turn) * w[0] + std::cos(turn) * w[1]));
  }
  BorderBandOptions unrefined;
  unrefined.wave_rounds = 0;
  const auto without = fit_border_band(band.samples, off, offset_start(), kPeriodPx, unrefined);
  const auto with = fit_border_band(band.samples, off, offset_start(), kPeriodPx);
  ASSERT_TRUE(without && with);
  std::cout << "  waves off: centre error " << centre_error_px(without->ellipse) << " px unrefined, "
            << centre_error_px(with->ellipse) << " px refined\n";
  EXPECT_LT(centre_error_px(with->ellipse), 0.1);
  EXPECT_GT(centre_error_px(without->ellipse), 2.0 * centre_error_px(with->ellipse));
}

// Noise of a quarter of the ridge level per sample (the crests at 8 sigmas, 2.8 at the border's faded ones):
// the centre stays within 0.3 px (measured 0.02-0.21 px over the three draws) and the axes within 0.5 px.
TEST(BorderBand, NoiseCostsLittle) {
  for (const unsigned seed : {3u, 4u, 5u}) {
    const Band band = draw_band(kTruth, 0.25 * kLevel, seed);
    const auto fit = fit_border_band(band.samples, band.true_waves, offset_start(), kPeriodPx);
    ASSERT_TRUE(fit.has_value()) << "seed " << seed;
    std::cout << "  noise, seed " << seed << ": centre error " << centre_error_px(fit->ellipse) << " px\n";
    EXPECT_LT(centre_error_px(fit->ellipse), 0.3) << "seed " << seed;
    EXPECT_NEAR(fit->ellipse.semi_major_px, kTruth.semi_major_px, 0.5) << "seed " << seed;
    EXPECT_NEAR(fit->ellipse.semi_minor_px, kTruth.semi_minor_px, 0.5) << "seed " << seed;
  }
}

// Nothing to fit: no samples, no sector with a wave, a band of pure noise or of zeros (a uniform image), or a
// start that is not an ellipse. Each gives no fit, never a NaN.
TEST(BorderBand, NoFitWithoutRidges) {
  const Band band = draw_band(kTruth, 0.0, 6);
  EXPECT_FALSE(fit_border_band({}, band.true_waves, kTruth, kPeriodPx).has_value());
  EXPECT_FALSE(
      fit_border_band(band.samples, std::vector<cv::Vec2d>(kSectors, cv::Vec2d(0.0, 0.0)), kTruth, kPeriodPx)
          .has_value());
  std::vector<BorderBandSample> zeros = band.samples, noise = band.samples;
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 0.05);
  for (auto& s : zeros) s.signal = 0.0f;
  for (auto& s : noise) s.signal = static_cast<float>(normal(rng));
  EXPECT_FALSE(fit_border_band(zeros, band.true_waves, kTruth, kPeriodPx).has_value());
  EXPECT_FALSE(fit_border_band(noise, band.true_waves, kTruth, kPeriodPx).has_value());
  Ellipse flat = kTruth;
  flat.semi_minor_px = 0.0;
  EXPECT_FALSE(fit_border_band(band.samples, band.true_waves, flat, kPeriodPx).has_value());
  EXPECT_FALSE(fit_border_band(band.samples, band.true_waves, kTruth, 0.0).has_value());
}

}  // namespace
}  // namespace tirstrain::contact
