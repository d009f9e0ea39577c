// The contact centre smoothed in time (pipeline/contact_centre_smoothing.hpp): noise averaged where the
// centre holds still or moves steadily, a jump kept, gaps and short runs left as they are.
#include "pipeline/contact_centre_smoothing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>
#include <vector>

namespace tirstrain::pipeline {
namespace {

struct Series {
  std::vector<Vec2> truth;
  std::vector<std::optional<Vec2>> measured;
};

// `truth(i)` plus white noise of `sigma_px` on each axis.
template <typename Truth>
Series noisy_series(int rows, double sigma_px, Truth truth, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_px);
  Series s;
  for (int i = 0; i < rows; ++i) {
    const Vec2 t = truth(i);
    s.truth.push_back(t);
    s.measured.push_back(Vec2{t.x + noise(rng), t.y + noise(rng)});
  }
  return s;
}

// A contact holding still at `at`.
Series still_series(int rows, double sigma_px, Vec2 at, std::uint32_t seed) {
  return noisy_series(
      rows, sigma_px, [at](int) { return at; }, seed);
}

double rms_error(const std::vector<std::optional<Vec2>>& centres, const std::vector<Vec2>& truth) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    if (!centres[i]) continue;
    sum += std::pow(centres[i]->x - truth[i].x, 2) + std::pow(centres[i]->y - truth[i].y, 2);
    ++n;
  }
  return std::sqrt(sum / n);
}

TEST(ContactCentreSmoothing, AveragesTheScatterOfAContactThatHoldsStill) {
  // A hold: the segmenter's centre scatters by ~0.1 px per axis (the shipped scenes: 0.10-0.14 px).
  Series s = still_series(60, 0.1, Vec2{320.0, 250.0}, 1);
  s.measured[30].reset();  // a frame without an ellipse splits the run
  const CentreSmoothing smoothed = smooth_centres_in_time(s.measured);
  const double before = rms_error(s.measured, s.truth), after = rms_error(smoothed.centre_px, s.truth);
  // Measured: 0.146 -> 0.054 px.
  EXPECT_LT(after, 0.4 * before) << before << " -> " << after;
  std::printf("  hold: %.3f -> %.3f px\n", before, after);
  EXPECT_NEAR(smoothed.noise_px, 0.1, 0.03);
  EXPECT_FALSE(smoothed.centre_px[30].has_value());
  EXPECT_FALSE(smoothed.changed[30]);
  EXPECT_EQ(smoothed.frames_changed, 59);
}

TEST(ContactCentreSmoothing, KeepsAJumpAndFollowsAContactThatMovesSteadily) {
  // Steady motion (0.2 px a frame along x), then a jump of 3 px in y at row 40: the line fits follow the
  // motion without lag, and no window reaches across the jump (each row stays on its own side).
  const auto truth = [](int i) { return Vec2{300.0 + 0.2 * i, i < 40 ? 250.0 : 253.0}; };
  const Series s = noisy_series(70, 0.05, truth, 2);
  const CentreSmoothing smoothed = smooth_centres_in_time(s.measured);
  const double before = rms_error(s.measured, s.truth), after = rms_error(smoothed.centre_px, s.truth);
  EXPECT_LT(after, 0.7 * before) << before << " -> " << after;
  std::printf("  motion and jump: %.3f -> %.3f px\n", before, after);
  for (int i = 0; i < 70; ++i) {
    const auto row = static_cast<std::size_t>(i);
    EXPECT_NEAR(smoothed.centre_px[row]->y, s.truth[row].y, 0.25) << "row " << i;
    EXPECT_NEAR(smoothed.centre_px[row]->x, s.truth[row].x, 0.15) << "row " << i;
  }
}

double worst_error(const std::vector<std::optional<Vec2>>& centres, const std::vector<Vec2>& truth) {
  double worst = 0.0;
  for (std::size_t i = 0; i < centres.size(); ++i)
    worst = std::max(worst, std::hypot(centres[i]->x - truth[i].x, centres[i]->y - truth[i].y));
  return worst;
}

TEST(ContactCentreSmoothing, FollowsAContactThatStartsToMoveAfterARest) {
  // A rest, then the contact shifts under shear at a steady speed: at the onset the windows on either side
  // disagree with the sample and shrink, and the one-sided fits follow each side, so the kink is not rounded
  // (a causal average lags there by several times its noise). Noise 0.1 px per axis as on the shipped
  // scenes; speeds from a tenth of a pixel to a pixel per frame.
  for (const double speed : {0.1, 0.2, 0.5, 1.0}) {
    const auto truth = [speed](int i) { return Vec2{300.0 + speed * std::max(0, i - 30), 250.0}; };
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      const Series s = noisy_series(60, 0.1, truth, seed);
      const CentreSmoothing smoothed = smooth_centres_in_time(s.measured);
      const double raw = worst_error(s.measured, s.truth), after = worst_error(smoothed.centre_px, s.truth);
      EXPECT_LT(after, raw + 0.05) << "speed " << speed << " seed " << seed;
      EXPECT_LT(rms_error(smoothed.centre_px, s.truth), 0.7 * rms_error(s.measured, s.truth))
          << "speed " << speed << " seed " << seed;
      std::printf("  onset at %.1f px/frame, seed %u: worst %.3f -> %.3f px\n", speed, seed, raw, after);
    }
  }
}

TEST(ContactCentreSmoothing, LeavesRunsTooShortToKnowTheirNoise) {
  Series s = still_series(15, 0.1, Vec2{100.0, 100.0}, 3);
  s.measured[9].reset();  // runs of 9 and 5 frames, both under the 10 the noise estimate needs
  const CentreSmoothing smoothed = smooth_centres_in_time(s.measured);
  EXPECT_EQ(smoothed.frames_changed, 0);
  EXPECT_EQ(smoothed.noise_px, 0.0);
  for (std::size_t i = 0; i < s.measured.size(); ++i) {
    ASSERT_EQ(smoothed.centre_px[i].has_value(), s.measured[i].has_value());
    if (s.measured[i]) {
      EXPECT_EQ(smoothed.centre_px[i]->x, s.measured[i]->x);
    }
  }
}

}  // namespace
}  // namespace tirstrain::pipeline
