// Smoothing of position series in time (flow/temporal_smoothing.hpp) against series whose truth is known:
// white noise about a constant, a loading ramp and hold, a jump, a line, and the bound on how far any
// sample may move.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <vector>

#include "flow/temporal_smoothing.hpp"

namespace tirstrain::flow {
namespace {

struct Series {
  std::vector<double> t_s, truth, measured;
};

// n frames at 100 Hz with 0.2 ms of jitter, the truth x(frame) plus white noise of `sigma`.
Series make_series(int n, const std::function<double(int)>& truth, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::uniform_real_distribution<double> jitter(-2e-4, 2e-4);
  Series s;
  for (int i = 0; i < n; ++i) {
    s.t_s.push_back(0.01 * i + jitter(rng));
    s.truth.push_back(truth(i));
    s.measured.push_back(s.truth.back() + noise(rng));
  }
  return s;
}

double rms(const std::vector<double>& a, const std::vector<double>& b, int from = 0, int to = -1) {
  if (to < 0) to = static_cast<int>(a.size());
  double sum = 0.0;
  for (int i = from; i < to; ++i)
    sum += (a[static_cast<std::size_t>(i)] - b[static_cast<std::size_t>(i)]) *
           (a[static_cast<std::size_t>(i)] - b[static_cast<std::size_t>(i)]);
  return std::sqrt(sum / (to - from));
}

// A loading trial's shape: at rest for 5 frames, a ramp to 12 px by frame 18, then a hold.
double ramp_and_hold(int i) {
  return i < 5 ? 0.0 : i < 18 ? 12.0 * (i - 5) / 13.0 : 12.0;
}

TEST(TemporalSmoothing, NoiseLevelFromDifferences) {
  const Series s = make_series(2000, ramp_and_hold, 0.1, 1);
  // A normal σ from the median absolute deviation of 2000 samples: within a few per cent (the ramp's two
  // kinks are outliers the median ignores).
  EXPECT_NEAR(series_noise(s.measured), 0.1, 0.006);
  EXPECT_EQ(series_noise(std::vector<double>{1.0, 2.0}), 0.0);
  // A track that accelerates in every frame (4 px at 0.3 rad per frame): its second differences are mostly
  // motion (they alone read 0.14-0.15 px), its third differences mostly noise.
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const Series moving = make_series(
        200, [](int i) { return 4.0 * std::sin(0.3 * i); }, 0.05, seed);
    EXPECT_NEAR(series_noise(moving.measured), 0.05, 0.012) << seed;
  }
}

TEST(TemporalSmoothing, AveragesNoiseAboutAConstant) {
  double raw = 0.0, smoothed = 0.0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const Series s = make_series(
        60, [](int) { return 3.0; }, 0.1, seed);
    const auto out = smooth_in_time(s.t_s, s.measured, series_noise(s.measured));
    raw += rms(s.measured, s.truth) / 20;
    smoothed += rms(out, s.truth) / 20;
  }
  std::cout << "  constant: raw " << raw << " px, smoothed " << smoothed << " px\n";
  // Windows of up to 65 frames on a 60-frame series: the error drops several-fold (measured 0.1 -> 0.03).
  EXPECT_LT(smoothed, 0.4 * raw);
}

TEST(TemporalSmoothing, FollowsTheLoadsOnsetAndEnd) {
  double raw = 0.0, smoothed = 0.0, raw_kinks = 0.0, smoothed_kinks = 0.0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const Series s = make_series(60, ramp_and_hold, 0.1, seed);
    const auto out = smooth_in_time(s.t_s, s.measured, series_noise(s.measured));
    raw += rms(s.measured, s.truth) / 20;
    smoothed += rms(out, s.truth) / 20;
    // Frames 3-7 and 16-20: the onset and the end of the ramp, where a fixed window would cut the corners.
    const double r1 = rms(s.measured, s.truth, 3, 8), r2 = rms(s.measured, s.truth, 16, 21);
    const double s1 = rms(out, s.truth, 3, 8), s2 = rms(out, s.truth, 16, 21);
    raw_kinks += std::sqrt((r1 * r1 + r2 * r2) / 2) / 20;
    smoothed_kinks += std::sqrt((s1 * s1 + s2 * s2) / 2) / 20;
  }
  std::cout << "  ramp and hold: raw " << raw << " px, smoothed " << smoothed << " px; at the kinks raw "
            << raw_kinks << ", smoothed " << smoothed_kinks << " px\n";
  EXPECT_LT(smoothed, 0.6 * raw);
  // The corners are not cut: no worse than the raw measurement there (a 5-frame centred line through the
  // onset is 0.37 px off at the corner with 0.92 px per frame).
  EXPECT_LT(smoothed_kinks, raw_kinks);
}

TEST(TemporalSmoothing, KeepsAJump) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const Series s = make_series(
        60, [](int i) { return i < 30 ? 0.0 : 3.0; }, 0.1, seed);
    const auto out = smooth_in_time(s.t_s, s.measured, series_noise(s.measured));
    // A jump of 30 σ between frames 29 and 30 stays a jump: each side's windows stop at it.
    for (int i : {28, 29, 30, 31})
      EXPECT_LT(std::abs(out[static_cast<std::size_t>(i)] - s.truth[static_cast<std::size_t>(i)]), 0.3)
          << "seed " << seed << " frame " << i;
  }
}

TEST(TemporalSmoothing, NoSampleMovesFurtherThanTwoGammaSigma) {
  // Whatever the series, the estimate kept at a frame has an interval that overlaps the sample's own
  // (±γσ), so it lies within 2γσ of the sample: here with the motion of a stick-slip record.
  const TemporalSmoothing options;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    const Series s = make_series(
        200, [](int i) { return 4.0 * std::sin(0.3 * i) + (i % 37 < 3 ? 1.5 : 0.0); }, 0.05, seed);
    const double sigma = series_noise(s.measured);
    const auto out = smooth_in_time(s.t_s, s.measured, sigma, options);
    for (std::size_t i = 0; i < out.size(); ++i)
      ASSERT_LE(std::abs(out[i] - s.measured[i]), 2.0 * options.gamma * sigma + 1e-12) << i;
  }
}

TEST(TemporalSmoothing, LinesAndDegenerateInputsComeBackUnchanged) {
  // Exact on a line in time (every window is a line fit), whatever the noise level it is told, with the
  // frames' jittered times.
  const Series frames = make_series(
      40, [](int) { return 0.0; }, 0.0, 3);
  std::vector<double> line;
  for (double t : frames.t_s) line.push_back(1.0 - 25.0 * t);
  const auto out = smooth_in_time(frames.t_s, line, 0.1);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], line[i], 1e-9);
  const Series s = make_series(40, ramp_and_hold, 0.1, 4);
  EXPECT_EQ(smooth_in_time(s.t_s, s.measured, 0.0), s.measured);   // no noise level: nothing to do
  EXPECT_EQ(smooth_in_time(s.t_s, s.measured, -1.0), s.measured);  // nor a meaningless one
  const std::vector<double> t4(s.t_s.begin(), s.t_s.begin() + 4),
      x4(s.measured.begin(), s.measured.begin() + 4);
  EXPECT_EQ(smooth_in_time(t4, x4, 0.1), x4);  // shorter than min_samples
}

}  // namespace
}  // namespace tirstrain::flow
