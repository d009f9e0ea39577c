// Friction, plateau and events against a synthetic Cattaneo–Mindlin loading history with closed-form
// truth, and the power-law fit against known parameters.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.hpp"
#include "signals/friction.hpp"

namespace ts = tirstrain::signals;

namespace {

// Normal load W, plate at rest until t0, then moving at v; the tangential force follows the
// Cattaneo–Mindlin loading curve Q = μW(1 − (1 − δ/δ*)^{3/2}) until δ* (full slip), then μW.
struct Trial {
  double fs = 1000.0, t0 = 0.5, v = 0.01, delta_star = 0.002, mu = 0.8, w = 2.0, duration = 2.0;
  std::vector<double> t, x, f, n;
  explicit Trial(double noise = 0.0, unsigned seed = 1) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    for (int i = 0; i <= static_cast<int>(duration * fs); ++i) {
      const double ti = i / fs;
      const double d = std::max(0.0, v * (ti - t0));
      const double u = std::min(1.0, d / delta_star);
      t.push_back(ti);
      x.push_back(0.01 + d);
      f.push_back(mu * w * (1.0 - std::pow(1.0 - u, 1.5)) + noise * mu * w * g(rng));
      n.push_back(w + noise * w * g(rng));
    }
  }
  // Closed forms: 90 % point u90 = 1 − 0.1^{2/3}; U_ext = μWδ*[u − 0.4(1 − (1 − u)^{5/2})].
  double u90() const { return 1.0 - std::pow(0.1, 2.0 / 3.0); }
  double t90() const { return t0 + u90() * delta_star / v; }
  double work() const {
    const double u = u90();
    return mu * w * delta_star * (u - 0.4 * (1.0 - std::pow(1.0 - u, 2.5)));
  }
};

}  // namespace

TEST(Friction, MuMarksLowNormalForceInvalid) {
  const auto s = ts::friction_coefficient({0.1, 0.5, 1.0}, {0.01, 1.0, 2.0}, 0.05);
  EXPECT_EQ(s.valid, (std::vector<char>{0, 1, 1}));
  EXPECT_EQ(s.invalid_count, 1u);
  EXPECT_DOUBLE_EQ(s.mu[1], 0.5);
  EXPECT_THROW(ts::friction_coefficient({1.0}, {1.0, 2.0}, 0.05), tirstrain::Error);
}

TEST(Friction, DynamicMuAndEventsOfACleanTrial) {
  const Trial trial;
  const auto mu = ts::friction_coefficient(trial.f, trial.n, 0.05);
  const auto plateau = ts::detect_plateau(trial.t, mu.mu, mu.valid, {});
  ASSERT_TRUE(plateau);
  EXPECT_NEAR(plateau->mean, trial.mu, 1e-9);
  // Full slip at t0 + δ*/v = 0.7 s; the plateau starts within one window of it.
  EXPECT_NEAR(plateau->start_s, 0.7, 0.05);
  const auto ev = ts::detect_events(trial.t, trial.f, &trial.x, {});
  EXPECT_EQ(ev.onset_source, "position");
  EXPECT_NEAR(ev.onset_s, trial.t0, 1.0 / trial.fs);
  EXPECT_NEAR(ev.fraction_s, trial.t90(), 1e-3);
  EXPECT_NEAR(ev.tangential_plateau.mean, trial.mu * trial.w, 1e-9);
  // Q approaches μW tangentially, so the 1 % band is entered at 1 − 0.01^{2/3} ≈ 95.4 % of δ*.
  EXPECT_NEAR(ev.full_slip_s, trial.t0 + (1.0 - std::pow(0.01, 2.0 / 3.0)) * 0.2, 2e-3);
  ASSERT_TRUE(ev.external_work_J);
  EXPECT_NEAR(*ev.external_work_J, trial.work(), 0.002 * trial.work());
}

// The plate moves 0.05 s into the record while the baseline window is 0.1 s (the shipped scenes' rest):
// the baseline is cut before the movement, so the onset, t90 and the work are those of the clean trial, and
// the cut is reported. Without the movement in the window, nothing is cut.
TEST(Friction, MovementInsideTheBaselineWindowCutsTheBaseline) {
  for (const double noise : {0.0, 0.005}) {
    Trial trial(noise, 5);
    trial.t0 = 0.05;
    trial = [&] {
      Trial t = trial;
      t.t.clear(), t.x.clear(), t.f.clear(), t.n.clear();
      std::mt19937_64 rng(5);
      std::normal_distribution<double> g(0.0, 1.0);
      for (int i = 0; i <= static_cast<int>(t.duration * t.fs); ++i) {
        const double ti = i / t.fs, d = std::max(0.0, t.v * (ti - t.t0));
        t.t.push_back(ti);
        t.x.push_back(0.01 + d + 1e-7 * noise * g(rng));
        t.f.push_back(t.mu * t.w * (1.0 - std::pow(1.0 - std::min(1.0, d / t.delta_star), 1.5)) +
                      noise * t.mu * t.w * g(rng));
      }
      return t;
    }();
    const auto ev = ts::detect_events(trial.t, trial.f, &trial.x, {});  // baseline_s 0.1
    EXPECT_TRUE(ev.baseline_shortened) << noise;
    EXPECT_NEAR(ev.baseline_end_s, 0.05, 0.002) << noise;
    EXPECT_NEAR(ev.onset_s, trial.t0, 2e-3) << noise;
    EXPECT_NEAR(ev.fraction_s, trial.t90(), 3e-3) << noise;
    ASSERT_TRUE(ev.external_work_J);
    EXPECT_NEAR(*ev.external_work_J, trial.work(), 0.02 * trial.work()) << noise;
  }
  const Trial quiet;  // moves at 0.5 s
  const auto ev = ts::detect_events(quiet.t, quiet.f, &quiet.x, {});
  EXPECT_FALSE(ev.baseline_shortened);
  EXPECT_NEAR(ev.baseline_end_s, 0.1, 0.0011);
}

TEST(Friction, NoisyTrialStillFindsMuAndTheNinetyPercentPoint) {
  const Trial trial(0.005, 3);
  const auto mu = ts::friction_coefficient(trial.f, trial.n, 0.05);
  const auto plateau = ts::detect_plateau(trial.t, mu.mu, mu.valid, {});
  ASSERT_TRUE(plateau);
  EXPECT_NEAR(plateau->mean, trial.mu, 0.005 * trial.mu);
  const auto ev = ts::detect_events(trial.t, trial.f, &trial.x, {});
  EXPECT_NEAR(ev.fraction_s, trial.t90(), 3e-3);
  EXPECT_NEAR(ev.onset_s, trial.t0, 2e-3);
  EXPECT_NEAR(*ev.external_work_J, trial.work(), 0.02 * trial.work());
  // Without the position channel the onset comes from the force itself.
  const auto ev_f = ts::detect_events(trial.t, trial.f, nullptr, {});
  EXPECT_EQ(ev_f.onset_source, "tangential");
  EXPECT_NEAR(ev_f.onset_s, trial.t0, 0.02);
  EXPECT_FALSE(ev_f.external_work_J);
}

TEST(Friction, ExternalWorkOfConstantForceIsForceTimesDistance) {
  const std::vector<double> t{0, 1, 2, 3}, f{2, 2, 2, 2}, x{0, 0.1, 0.2, 0.3};
  EXPECT_NEAR(ts::external_work_J(t, f, x, 0.5, 2.5), 2.0 * 0.2, 1e-12);
}

TEST(Friction, StudentTQuantilesMatchTables) {
  EXPECT_NEAR(ts::student_t_quantile(0.975, 10), 2.2281388519649385, 1e-9);
  EXPECT_NEAR(ts::student_t_quantile(0.975, 1), 12.706204736174698, 1e-7);
  EXPECT_NEAR(ts::student_t_quantile(0.995, 5), 4.032142983557536, 1e-9);
  EXPECT_NEAR(ts::student_t_quantile(0.975, 1e7), 1.959963984540054, 1e-5);
  EXPECT_NEAR(ts::student_t_quantile(0.025, 10), -2.2281388519649385, 1e-9);
}

TEST(Friction, PowerLawRecoversParametersWithConfidenceIntervals) {
  // μ = 1.63·W^−0.33 with 3 % multiplicative noise, W from 0.2 to 5 N (80 trials).
  std::mt19937_64 rng(2016);
  std::normal_distribution<double> g(0.0, 0.03);
  std::vector<double> w, mu;
  for (int i = 0; i < 80; ++i) {
    const double wi = 0.2 * std::pow(25.0, i / 79.0);
    w.push_back(wi);
    mu.push_back(1.63 * std::pow(wi, -0.33) * (1.0 + g(rng)));
  }
  const auto fit = ts::fit_power_law(w, mu, 0.95);
  EXPECT_NEAR(fit.a, 1.63, 0.02 * 1.63);
  EXPECT_NEAR(fit.b, -0.33, 0.015);
  EXPECT_LT(fit.a_low, 1.63);
  EXPECT_GT(fit.a_high, 1.63);
  EXPECT_LT(fit.b_low, -0.33);
  EXPECT_GT(fit.b_high, -0.33);
  EXPECT_GT(fit.a_stderr, 0.0);
  EXPECT_LT(fit.b_high - fit.b_low, 0.05);
  // Exact data: exact parameters and vanishing intervals.
  std::vector<double> exact(w.size());
  for (std::size_t i = 0; i < w.size(); ++i) exact[i] = 1.63 * std::pow(w[i], -0.33);
  const auto e = ts::fit_power_law(w, exact);
  EXPECT_NEAR(e.a, 1.63, 1e-8);
  EXPECT_NEAR(e.b, -0.33, 1e-8);
  EXPECT_THROW(ts::fit_power_law({1.0, -1.0, 2.0}, {1.0, 1.0, 1.0}), tirstrain::Error);
}
