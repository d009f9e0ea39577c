#include "signals/friction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <ceres/ceres.h>

#include "core/error.hpp"
#include "core/median.hpp"
#include "signals/channels.hpp"

namespace tirstrain::signals {
namespace {

void require_same_length(std::size_t a, std::size_t b, const char* what) {
  if (a != b)
    throw Error(std::string(what) + ": lengths differ (" + std::to_string(a) + " and " + std::to_string(b) +
                " samples)");
}

std::size_t first_index_at_or_after(const std::vector<double>& time_s, double t) {
  return static_cast<std::size_t>(std::lower_bound(time_s.begin(), time_s.end(), t) - time_s.begin());
}

double interpolate_at(const std::vector<double>& time_s, const std::vector<double>& v, double t) {
  return resample_linear(time_s, v, {t}).front();
}

struct PowerLawResidual {
  double w, mu;
  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    residual[0] = T(mu) - a[0] * exp(b[0] * T(std::log(w)));
    return true;
  }
};

// Regularised incomplete beta I_x(a, b) by its continued fraction (modified Lentz), using the symmetry
// I_x(a,b) = 1 − I_{1−x}(b,a) where the fraction converges slowly.
double incomplete_beta(double x, double a, double b) {
  if (x <= 0.0) return 0.0;
  if (x >= 1.0) return 1.0;
  if (x > (a + 1.0) / (a + b + 2.0)) return 1.0 - incomplete_beta(1.0 - x, b, a);
  const double log_front =
      std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
  const double tiny = 1e-300;
  double c = 1.0, d = 1.0 - (a + b) * x / (a + 1.0);
  if (std::abs(d) < tiny) d = tiny;
  d = 1.0 / d;
  double f = d;
  for (int m = 1; m < 500; ++m) {
    const double m2 = 2.0 * m;
    double num = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
    d = 1.0 + num * d;
    d = std::abs(d) < tiny ? 1.0 / tiny : 1.0 / d;
    c = 1.0 + num / c;
    if (std::abs(c) < tiny) c = tiny;
    f *= d * c;
    num = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
    d = 1.0 + num * d;
    d = std::abs(d) < tiny ? 1.0 / tiny : 1.0 / d;
    c = 1.0 + num / c;
    if (std::abs(c) < tiny) c = tiny;
    const double delta = d * c;
    f *= delta;
    if (std::abs(delta - 1.0) < 1e-15) break;
  }
  return std::exp(log_front) * f / a;
}

double student_t_cdf(double t, double dof) {
  const double tail = 0.5 * incomplete_beta(dof / (dof + t * t), 0.5 * dof, 0.5);
  return t >= 0.0 ? 1.0 - tail : tail;
}

}  // namespace

FrictionSeries friction_coefficient(const std::vector<double>& tangential_N,
                                    const std::vector<double>& normal_N, double min_normal_N) {
  require_same_length(tangential_N.size(), normal_N.size(), "tangential and normal force");
  if (!(min_normal_N > 0.0))
    throw Error("minimum normal force must be positive (μ is undefined at W = 0)", {.key = "min_normal_N"});
  FrictionSeries out;
  out.mu.assign(tangential_N.size(), 0.0);
  out.valid.assign(tangential_N.size(), 0);
  for (std::size_t i = 0; i < tangential_N.size(); ++i) {
    if (normal_N[i] >= min_normal_N) {
      out.mu[i] = tangential_N[i] / normal_N[i];
      out.valid[i] = 1;
    } else {
      ++out.invalid_count;
    }
  }
  return out;
}

std::optional<Plateau> detect_plateau(const std::vector<double>& time_s, const std::vector<double>& values,
                                      const std::vector<char>& valid, const PlateauOptions& options,
                                      std::size_t start_index) {
  require_same_length(time_s.size(), values.size(), "plateau detection");
  if (!valid.empty()) require_same_length(valid.size(), values.size(), "plateau validity mask");
  const std::size_t n = values.size();
  if (n < 3 || start_index >= n) return std::nullopt;
  const double dt = (time_s.back() - time_s.front()) / static_cast<double>(n - 1);
  const std::size_t half =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(0.5 * options.window_s / dt)));
  if (2 * half + 1 > n - start_index) return std::nullopt;
  // Prefix sums make every window's mean and least-squares slope O(1).
  std::vector<double> sum_y(n + 1, 0.0), sum_ky(n + 1, 0.0);
  std::vector<std::size_t> invalid(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    sum_y[i + 1] = sum_y[i] + values[i];
    sum_ky[i + 1] = sum_ky[i] + static_cast<double>(i) * values[i];
    invalid[i + 1] = invalid[i] + (!valid.empty() && !valid[i]);
  }
  const double h = static_cast<double>(half);
  const double sum_kk = h * (h + 1.0) * (2.0 * h + 1.0) / 3.0;
  const double count = 2.0 * h + 1.0;
  std::vector<char> flat(n, 0);
  for (std::size_t i = start_index + half; i + half < n; ++i) {
    const std::size_t lo = i - half, hi = i + half + 1;
    if (invalid[hi] - invalid[lo] > 0) continue;
    const double sy = sum_y[hi] - sum_y[lo];
    const double sky = sum_ky[hi] - sum_ky[lo] - static_cast<double>(i) * sy;
    const double mean = sy / count;
    const double change = std::abs(sky / sum_kk) * 2.0 * h;
    flat[i] = change <= options.max_relative_change * std::abs(mean) ? 1 : 0;
  }
  std::optional<Plateau> best;
  for (std::size_t i = start_index; i < n;) {
    if (!flat[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < n && flat[j + 1]) ++j;
    // Window centres stop half a window short of the plateau's true ends.
    std::size_t lo = i >= start_index + half ? i - half : start_index;
    std::size_t hi = std::min(n - 1, j + half);
    while (lo < i && !valid.empty() && !valid[lo]) ++lo;
    while (hi > j && !valid.empty() && !valid[hi]) --hi;
    // A loading curve can meet its plateau with zero slope (Cattaneo–Mindlin does), so the window test
    // accepts the last stretch of the approach too; trim the ends to the plateau's own spread (robust:
    // median and MAD of the candidate stretch) so the approach does not bias the level.
    if (hi > lo + 2) {
      std::vector<double> sorted(values.begin() + static_cast<std::ptrdiff_t>(lo),
                                 values.begin() + static_cast<std::ptrdiff_t>(hi + 1));
      const double median = upper_median_in_place(sorted);
      for (double& v : sorted) v = std::abs(v - median);
      const double band = std::max(3.0 * 1.4826 * upper_median_in_place(sorted), 1e-9 * std::abs(median));
      while (lo < hi && std::abs(values[lo] - median) > band) ++lo;
      while (hi > lo && std::abs(values[hi] - median) > band) --hi;
    }
    if (time_s[hi] - time_s[lo] >= options.min_duration_s) {
      double mean = 0.0;
      for (std::size_t k = lo; k <= hi; ++k) mean += values[k];
      mean /= static_cast<double>(hi - lo + 1);
      if (!best || std::abs(mean) > std::abs(best->mean)) {
        double var = 0.0;
        for (std::size_t k = lo; k <= hi; ++k) var += (values[k] - mean) * (values[k] - mean);
        best =
            Plateau{lo, hi, time_s[lo], time_s[hi], mean, std::sqrt(var / static_cast<double>(hi - lo + 1))};
      }
    }
    i = j + 1;
  }
  return best;
}

double external_work_J(const std::vector<double>& time_s, const std::vector<double>& force_N,
                       const std::vector<double>& position_m, double t0_s, double t1_s) {
  require_same_length(time_s.size(), force_N.size(), "force");
  require_same_length(time_s.size(), position_m.size(), "position");
  if (t1_s < t0_s) std::swap(t0_s, t1_s);
  std::vector<double> t{t0_s}, f{interpolate_at(time_s, force_N, t0_s)},
      x{interpolate_at(time_s, position_m, t0_s)};
  for (std::size_t i = first_index_at_or_after(time_s, t0_s); i < time_s.size() && time_s[i] < t1_s; ++i) {
    if (time_s[i] <= t0_s) continue;
    t.push_back(time_s[i]);
    f.push_back(force_N[i]);
    x.push_back(position_m[i]);
  }
  t.push_back(t1_s);
  f.push_back(interpolate_at(time_s, force_N, t1_s));
  x.push_back(interpolate_at(time_s, position_m, t1_s));
  double work = 0.0;
  for (std::size_t i = 1; i < t.size(); ++i) work += 0.5 * (f[i] + f[i - 1]) * (x[i] - x[i - 1]);
  return work;
}

namespace {

struct BaselineStats {
  double mean = 0.0, sigma = 0.0;
};

BaselineStats baseline_stats(const std::vector<double>& v, std::size_t end) {
  BaselineStats b;
  for (std::size_t i = 0; i < end; ++i) b.mean += v[i];
  b.mean /= static_cast<double>(end);
  double var = 0.0;
  for (std::size_t i = 0; i < end; ++i) var += (v[i] - b.mean) * (v[i] - b.mean);
  b.sigma = std::sqrt(var / static_cast<double>(end - 1));
  return b;
}

// Checks the inputs and returns the end of the baseline stretch.
std::size_t event_baseline_end(const std::vector<double>& time_s, const std::vector<double>& tangential_N,
                               const std::vector<double>* position_m, const EventOptions& options) {
  require_same_length(time_s.size(), tangential_N.size(), "tangential force");
  if (position_m) require_same_length(time_s.size(), position_m->size(), "position");
  const std::size_t n = time_s.size();
  if (n < 4) throw Error("event detection needs at least 4 samples");
  const std::size_t baseline_end = first_index_at_or_after(time_s, time_s.front() + options.baseline_s);
  if (baseline_end < 2 || baseline_end >= n)
    throw Error("baseline of " + std::to_string(options.baseline_s) +
                    " s must cover at least 2 samples and end before the record does",
                {.key = "baseline_s"});
  return baseline_end;
}

// How the driver leaves a baseline: its largest excursion from the baseline's level, the threshold of a
// departure (onset_fraction of the excursion, at least onset_sigma σ) and the noise band (onset_sigma σ).
struct Departure {
  double level = 0.0, excursion = 0.0, detect = 0.0, band = 0.0;
  bool moves = false;  // the excursion leaves the noise band at all

  Departure(const std::vector<double>& driver, const BaselineStats& b, const EventOptions& options)
      : level(b.mean) {
    for (double v : driver) excursion = std::max(excursion, std::abs(v - level));
    moves = excursion > 0.0 && excursion > options.onset_sigma * b.sigma;
    detect = std::max(options.onset_fraction * excursion, options.onset_sigma * b.sigma);
    band = std::max(options.onset_sigma * b.sigma, 1e-12 * excursion);
  }

  // The first sample of the run outside the band that first crosses the threshold at or after `from`;
  // driver.size() when nothing crosses it.
  std::size_t start(const std::vector<double>& driver, std::size_t from) const {
    std::size_t cross = from;
    while (cross < driver.size() && std::abs(driver[cross] - level) < detect) ++cross;
    if (cross == driver.size()) return cross;
    while (cross > 0 && std::abs(driver[cross - 1] - level) > band) --cross;
    return cross;
  }
};

// The baseline window must end before the movement starts: a record whose movement begins inside it (a
// short rest before the plate moves) would take part of the movement for the baseline, its level and noise
// band. The window's first quarter is taken as quiet, and the departure from it is found as find_onset
// finds it; when it starts inside the window, the window ends there.
std::size_t quiet_baseline_end(const std::vector<double>& driver, std::size_t baseline_end,
                               const EventOptions& options) {
  const std::size_t seed_end = std::max<std::size_t>(2, baseline_end / 4);
  if (seed_end >= baseline_end) return baseline_end;
  const std::size_t end =
      Departure(driver, baseline_stats(driver, seed_end), options).start(driver, seed_end);
  if (end >= baseline_end) return baseline_end;
  if (end < 2)
    throw Error("the movement starts at the record's start: no quiet stretch before it for the baseline",
                {.key = "baseline_s"});
  return end;
}

// The driver leaves its baseline by onset_fraction of its excursion; the onset is the last sample before
// that still inside the baseline noise band.
void find_onset(const std::vector<double>& time_s, const std::vector<double>& driver,
                std::size_t baseline_end, const EventOptions& options, TrialEvents& ev) {
  const Departure departure(driver, baseline_stats(driver, baseline_end), options);
  if (!departure.moves)
    throw Error("no movement: the " + ev.onset_source + " channel never leaves its baseline noise band");
  const std::size_t start = departure.start(driver, baseline_end);
  if (start == driver.size())
    throw Error("no movement onset after the baseline period", {.key = "baseline_s"});
  const std::size_t onset = start > 0 ? start - 1 : 0;  // the last sample still inside the band
  ev.onset_index = onset;
  ev.onset_s = time_s[onset];
}

// t90 and full slip from the rise above the baseline and its plateau (level relative to the baseline).
void find_fraction_and_slip(const std::vector<double>& time_s, const std::vector<double>& rise,
                            const Plateau& plateau, const EventOptions& options, TrialEvents& ev) {
  const std::size_t n = time_s.size(), onset = ev.onset_index;
  const double level = plateau.mean;
  const double sign = level >= 0.0 ? 1.0 : -1.0;
  const double target = options.plateau_fraction * std::abs(level);
  bool found = false;
  for (std::size_t i = std::max<std::size_t>(onset, 1); i < n && !found; ++i) {
    const double now = sign * rise[i], before = sign * rise[i - 1];
    if (now < target) continue;
    ev.fraction_s = before < target && i > onset
                        ? time_s[i - 1] + (target - before) / (now - before) * (time_s[i] - time_s[i - 1])
                        : time_s[i];
    ev.fraction_index = i;
    found = true;
  }
  if (!found) throw Error("tangential force never reaches the requested fraction of its plateau");
  const double slip_tol = std::max(options.slip_band * std::abs(level), 3.0 * plateau.stddev);
  ev.full_slip_index = std::max(plateau.start_index, ev.fraction_index);
  for (std::size_t i = ev.fraction_index; i <= plateau.end_index && i < n; ++i)
    if (std::abs(rise[i] - level) <= slip_tol) {
      ev.full_slip_index = i;
      break;
    }
  ev.full_slip_s = time_s[ev.full_slip_index];
}

// Shared by both entry points: onset, then the rise above the baseline handed to `plateau_of`.
template <typename PlateauOf>
TrialEvents detect_events_with(const std::vector<double>& time_s, const std::vector<double>& tangential_N,
                               const std::vector<double>* position_m, const EventOptions& options,
                               PlateauOf plateau_of) {
  const std::size_t window_end = event_baseline_end(time_s, tangential_N, position_m, options);
  TrialEvents ev;
  ev.onset_source = position_m ? "position" : "tangential";
  const std::vector<double>& driver = position_m ? *position_m : tangential_N;
  const std::size_t baseline_end = quiet_baseline_end(driver, window_end, options);
  ev.baseline_end_s = time_s[baseline_end - 1];
  ev.baseline_shortened = baseline_end < window_end;
  find_onset(time_s, driver, baseline_end, options, ev);
  ev.baseline_tangential_N = baseline_stats(tangential_N, baseline_end).mean;
  std::vector<double> rise(time_s.size());
  for (std::size_t i = 0; i < rise.size(); ++i) rise[i] = tangential_N[i] - ev.baseline_tangential_N;
  const Plateau plateau = plateau_of(rise, ev.onset_index);
  ev.tangential_plateau = plateau;
  ev.tangential_plateau.mean += ev.baseline_tangential_N;
  find_fraction_and_slip(time_s, rise, plateau, options, ev);
  if (position_m)
    ev.external_work_J = external_work_J(time_s, tangential_N, *position_m, ev.onset_s, ev.fraction_s);
  return ev;
}

}  // namespace

TrialEvents detect_events(const std::vector<double>& time_s, const std::vector<double>& tangential_N,
                          const std::vector<double>* position_m, const EventOptions& options) {
  return detect_events_with(
      time_s, tangential_N, position_m, options, [&](const std::vector<double>& rise, std::size_t onset) {
        const auto plateau = detect_plateau(time_s, rise, {}, options.plateau, onset);
        if (!plateau)
          throw Error("no tangential-force plateau found after the onset (window " +
                          std::to_string(options.plateau.window_s) + " s, tolerance " +
                          std::to_string(options.plateau.max_relative_change) + ", minimum duration " +
                          std::to_string(options.plateau.min_duration_s) + " s)",
                      {.key = "plateau"});
        return *plateau;
      });
}

TrialEvents detect_events_on_plateau(const std::vector<double>& time_s,
                                     const std::vector<double>& tangential_N,
                                     const std::vector<double>* position_m, const Plateau& plateau,
                                     const EventOptions& options) {
  return detect_events_with(time_s, tangential_N, position_m, options,
                            [&](const std::vector<double>& rise, std::size_t) {
                              if (plateau.end_index >= rise.size() || plateau.start_index > plateau.end_index)
                                throw Error("internal: the given plateau lies outside the samples");
                              Plateau relative = plateau;
                              relative.mean = plateau.mean - (tangential_N[0] - rise[0]);
                              return relative;
                            });
}

double student_t_quantile(double p, double dof) {
  if (!(p > 0.0 && p < 1.0) || !(dof > 0.0)) throw Error("internal: t quantile needs 0 < p < 1 and dof > 0");
  if (p < 0.5) return -student_t_quantile(1.0 - p, dof);
  double lo = 0.0, hi = 1.0;
  while (student_t_cdf(hi, dof) < p) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (student_t_cdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

void check_power_law_samples(const std::vector<double>& normal_N, const std::vector<double>& mu,
                             double confidence) {
  require_same_length(normal_N.size(), mu.size(), "power-law samples");
  const std::size_t n = mu.size();
  if (n < 3) throw Error("power-law fit needs at least 3 samples, got " + std::to_string(n));
  if (!(confidence > 0.0 && confidence < 1.0))
    throw Error("confidence must lie in (0, 1)", {.key = "confidence"});
  for (std::size_t i = 0; i < n; ++i) {
    if (!(normal_N[i] > 0.0) || !std::isfinite(normal_N[i]))
      throw Error("normal force must be positive for a power law, sample " + std::to_string(i) + " has " +
                  std::to_string(normal_N[i]) + " N");
    if (!std::isfinite(mu[i]))
      throw Error("friction coefficient of sample " + std::to_string(i) + " is not finite");
  }
}

// The start: the log–log line when every μ is positive (the nonlinear fit then only polishes), else a
// constant at the mean μ.
void power_law_start(const std::vector<double>& normal_N, const std::vector<double>& mu, double& a,
                     double& b) {
  const std::size_t n = mu.size();
  a = b = 0.0;
  if (!std::all_of(mu.begin(), mu.end(), [](double v) { return v > 0.0; })) {
    for (double v : mu) a += v;
    a /= static_cast<double>(n);
    return;
  }
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double lx = std::log(normal_N[i]), ly = std::log(mu[i]);
    sx += lx;
    sy += ly;
    sxx += lx * lx;
    sxy += lx * ly;
  }
  const double nn = static_cast<double>(n);
  const double denom = nn * sxx - sx * sx;
  b = denom > 0.0 ? (nn * sxy - sx * sy) / denom : 0.0;
  a = std::exp((sy - b * sx) / nn);
}

// Standard errors and confidence bounds from Ceres' (JᵀJ)⁻¹ for unit-variance residuals, scaled by the
// estimated residual variance.
void power_law_uncertainty(ceres::Problem& problem, double* a, double* b, double ssr, PowerLawFit& fit) {
  ceres::Covariance::Options cov_options;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks{{a, a}, {a, b}, {b, b}};
  if (!covariance.Compute(blocks, &problem))
    throw Error("power-law fit: the Jacobian is rank deficient (are all normal forces equal?)");
  double caa = 0.0, cab = 0.0, cbb = 0.0;
  covariance.GetCovarianceBlock(a, a, &caa);
  covariance.GetCovarianceBlock(a, b, &cab);
  covariance.GetCovarianceBlock(b, b, &cbb);
  const double dof = static_cast<double>(fit.samples - 2);
  const double s2 = ssr / dof;
  fit.a_stderr = std::sqrt(caa * s2);
  fit.b_stderr = std::sqrt(cbb * s2);
  fit.covariance_ab = cab * s2;
  const double t = student_t_quantile(1.0 - 0.5 * (1.0 - fit.confidence), dof);
  fit.a_low = fit.a - t * fit.a_stderr;
  fit.a_high = fit.a + t * fit.a_stderr;
  fit.b_low = fit.b - t * fit.b_stderr;
  fit.b_high = fit.b + t * fit.b_stderr;
}

}  // namespace

PowerLawFit fit_power_law(const std::vector<double>& normal_N, const std::vector<double>& mu,
                          double confidence) {
  check_power_law_samples(normal_N, mu, confidence);
  const std::size_t n = mu.size();
  double a = 0.0, b = 0.0;
  power_law_start(normal_N, mu, a, b);
  ceres::Problem problem;
  for (std::size_t i = 0; i < n; ++i)
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<PowerLawResidual, 1, 1, 1>(new PowerLawResidual{normal_N[i], mu[i]}),
        nullptr, &a, &b);
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.logging_type = ceres::SILENT;
  solver_options.function_tolerance = 1e-14;
  solver_options.parameter_tolerance = 1e-14;
  solver_options.gradient_tolerance = 1e-16;
  solver_options.max_num_iterations = 200;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  if (!summary.IsSolutionUsable()) throw Error("power-law fit did not converge: " + summary.message);

  PowerLawFit fit;
  fit.a = a;
  fit.b = b;
  fit.samples = n;
  fit.confidence = confidence;
  double ssr = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = mu[i] - a * std::pow(normal_N[i], b);
    ssr += r * r;
  }
  fit.residual_rms = std::sqrt(ssr / static_cast<double>(n));
  power_law_uncertainty(problem, &a, &b, ssr, fit);
  return fit;
}

}  // namespace tirstrain::signals
