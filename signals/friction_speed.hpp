#pragma once
// Friction against sliding speed across trials or strokes: the power law μ = a·v^b (the same fit as μ
// against the normal force, signals/friction.hpp) and the logarithmic law μ = μ_ref + β·ln(v / v_ref) of
// rate-dependent friction, each with confidence intervals and an information criterion so a user can keep
// the simpler description the data support.
#include <cstddef>
#include <vector>

#include "signals/friction.hpp"

namespace tirstrain::signals {

struct LogSpeedFit {
  double mu_ref = 0.0, beta = 0.0;  // μ at v_ref; change of μ per e-fold of speed
  double mu_ref_stderr = 0.0, beta_stderr = 0.0;
  double mu_ref_low = 0.0, mu_ref_high = 0.0;
  double beta_low = 0.0, beta_high = 0.0;
  double reference_speed_m_s = 0.0;  // v_ref
  double confidence = 0.95;
  double residual_rms = 0.0;
  std::size_t samples = 0;
};

// Linear least squares on μ = μ_ref + β·ln(v / v_ref); intervals estimate ± t(n−2)·standard error.
// Needs v > 0 and at least 3 samples with two distinct speeds; throws Error naming the sample otherwise.
LogSpeedFit fit_log_speed_law(const std::vector<double>& speed_m_s, const std::vector<double>& mu,
                              double reference_speed_m_s = 0.01, double confidence = 0.95);

// Akaike's criterion of a least-squares fit with `parameters` fitted values: n·ln(RSS/n) + 2·parameters.
double least_squares_aic(double residual_rms, std::size_t samples, std::size_t parameters);

}  // namespace tirstrain::signals
