#include "signals/friction_speed.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.hpp"

namespace tirstrain::signals {

LogSpeedFit fit_log_speed_law(const std::vector<double>& speed_m_s, const std::vector<double>& mu,
                              double reference_speed_m_s, double confidence) {
  if (speed_m_s.size() != mu.size())
    throw Error("speed and mu have different lengths (" + std::to_string(speed_m_s.size()) + " vs " +
                std::to_string(mu.size()) + ")");
  if (!(reference_speed_m_s > 0.0) || !std::isfinite(reference_speed_m_s))
    throw Error("reference speed must be a positive number of m/s", {.key = "reference_speed_m_s"});
  if (!(confidence > 0.0 && confidence < 1.0))
    throw Error("confidence must lie in (0, 1)", {.key = "confidence"});
  const std::size_t n = mu.size();
  if (n < 3) throw Error("a speed law needs at least 3 samples, got " + std::to_string(n));
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!(speed_m_s[i] > 0.0) || !std::isfinite(speed_m_s[i]) || !std::isfinite(mu[i]))
      throw Error("sample " + std::to_string(i + 1) + ": speed must be positive and mu finite",
                  {.key = "speed"});
    x[i] = std::log(speed_m_s[i] / reference_speed_m_s);
  }
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mx += x[i];
    my += mu[i];
  }
  mx /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (mu[i] - my);
  }
  if (!(sxx > 0.0)) throw Error("a speed law needs at least two different speeds", {.key = "speed"});
  LogSpeedFit fit;
  fit.beta = sxy / sxx;
  fit.mu_ref = my - fit.beta * mx;
  double ssr = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = mu[i] - fit.mu_ref - fit.beta * x[i];
    ssr += r * r;
  }
  const double dof = static_cast<double>(n - 2);
  const double sigma2 = ssr / dof;
  fit.beta_stderr = std::sqrt(sigma2 / sxx);
  fit.mu_ref_stderr = std::sqrt(sigma2 * (1.0 / static_cast<double>(n) + mx * mx / sxx));
  const double t = student_t_quantile(1.0 - 0.5 * (1.0 - confidence), dof);
  fit.beta_low = fit.beta - t * fit.beta_stderr;
  fit.beta_high = fit.beta + t * fit.beta_stderr;
  fit.mu_ref_low = fit.mu_ref - t * fit.mu_ref_stderr;
  fit.mu_ref_high = fit.mu_ref + t * fit.mu_ref_stderr;
  fit.reference_speed_m_s = reference_speed_m_s;
  fit.confidence = confidence;
  fit.residual_rms = std::sqrt(ssr / static_cast<double>(n));
  fit.samples = n;
  return fit;
}

double least_squares_aic(double residual_rms, std::size_t samples, std::size_t parameters) {
  const double n = static_cast<double>(samples);
  // A perfect fit has no finite AIC; the smallest positive RSS stands in so comparisons stay ordered.
  const double rss_per_sample = std::max(residual_rms * residual_rms, std::numeric_limits<double>::min());
  return n * std::log(rss_per_sample) + 2.0 * static_cast<double>(parameters);
}

}  // namespace tirstrain::signals
