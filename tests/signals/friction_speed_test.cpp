// Friction against speed: the logarithmic law against a NumPy least-squares reference, the power law
// recovered from exact data, and the AIC that picks between them.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/error.hpp"
#include "signals/friction_speed.hpp"

namespace ts = tirstrain::signals;

TEST(FrictionSpeed, LogLawMatchesANumpyReference) {
  // Reference: numpy.linalg.lstsq on [1, ln(v/0.01)], standard errors from σ̂²(AᵀA)⁻¹, σ̂² = SSR/(n−2);
  // t(0.975, 5) = 2.5705818.
  const std::vector<double> v{0.004, 0.008, 0.015, 0.03, 0.06, 0.12, 0.25};
  const std::vector<double> mu{0.92, 0.88, 0.86, 0.81, 0.79, 0.74, 0.73};
  const auto fit = ts::fit_log_speed_law(v, mu, 0.01, 0.95);
  EXPECT_NEAR(fit.mu_ref, 0.87230911, 1e-8);
  EXPECT_NEAR(fit.beta, -0.04785686, 1e-8);
  EXPECT_NEAR(fit.mu_ref_stderr, 0.00487199, 1e-8);
  EXPECT_NEAR(fit.beta_stderr, 0.00274773, 1e-8);
  EXPECT_NEAR(fit.residual_rms, 0.008431096726, 1e-10);
  EXPECT_NEAR(fit.beta_high - fit.beta, 2.5705818 * 0.00274773, 1e-7);
  EXPECT_THROW(ts::fit_log_speed_law({0.01, 0.01, 0.01}, {0.5, 0.6, 0.7}), tirstrain::Error);
  EXPECT_THROW(ts::fit_log_speed_law({0.01, -0.02, 0.03}, {0.5, 0.6, 0.7}), tirstrain::Error);
}

TEST(FrictionSpeed, EachLawIsPreferredOnItsOwnData) {
  std::vector<double> v, mu_power, mu_log;
  for (int i = 0; i < 12; ++i) {
    const double speed = 0.002 * std::pow(1.6, i);    // 2 mm/s to 0.35 m/s
    const double wobble = 0.004 * std::sin(1.7 * i);  // deterministic, small against either law's curvature
    v.push_back(speed);
    mu_power.push_back(0.6 * std::pow(speed, -0.25) + wobble);
    mu_log.push_back(0.9 - 0.08 * std::log(speed / 0.01) + wobble);
  }
  const auto pp = ts::fit_power_law(v, mu_power), pl = ts::fit_power_law(v, mu_log);
  const auto lp = ts::fit_log_speed_law(v, mu_power), ll = ts::fit_log_speed_law(v, mu_log);
  EXPECT_NEAR(pp.b, -0.25, 0.01);
  EXPECT_NEAR(ll.beta, -0.08, 0.002);
  EXPECT_LT(ts::least_squares_aic(pp.residual_rms, 12, 2), ts::least_squares_aic(lp.residual_rms, 12, 2) - 2);
  EXPECT_LT(ts::least_squares_aic(ll.residual_rms, 12, 2), ts::least_squares_aic(pl.residual_rms, 12, 2) - 2);
}
