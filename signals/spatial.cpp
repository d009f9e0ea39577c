#include "signals/spatial.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/median.hpp"

namespace tirstrain::signals {
namespace {

// Largest |x(t_j) − x(t_i)| / (t_j − t_i) with t_j the first sample at least `window_s` after t_i.
double peak_speed(const std::vector<double>& time_s, const std::vector<double>& position_m, std::size_t begin,
                  std::size_t end, double window_s) {
  if (!(window_s >= 0.0) || !std::isfinite(window_s))
    throw Error("speed window must be a finite number of seconds >= 0", {.key = "speed_window_s"});
  double peak = 0.0;
  std::size_t j = begin + 1;
  for (std::size_t i = begin; i + 1 < end; ++i) {
    j = std::max(j, i + 1);
    while (j + 1 < end && time_s[j] - time_s[i] < window_s) ++j;
    if (time_s[j] - time_s[i] < window_s && i > begin) break;  // no full window left
    peak = std::max(peak, std::abs(position_m[j] - position_m[i]) / (time_s[j] - time_s[i]));
  }
  return peak;
}

}  // namespace

SpatialSeries to_spatial_domain(const std::vector<double>& time_s, const std::vector<double>& position_m,
                                const std::vector<double>& values, double dx_m, std::size_t begin,
                                std::size_t end, double speed_window_s) {
  if (time_s.size() != position_m.size() || time_s.size() != values.size())
    throw Error("time, position and value channels have different lengths");
  end = std::min(end, time_s.size());
  if (end < begin + 3) throw Error("spatial resampling needs at least 3 samples in the stroke");
  const double direction = position_m[begin + 1] > position_m[begin] ? 1.0 : -1.0;
  std::vector<double> steps;
  steps.reserve(end - begin);
  for (std::size_t i = begin + 1; i < end; ++i) {
    const double step = (position_m[i] - position_m[i - 1]) * direction;
    if (!(step > 0.0))
      throw Error(
          "position " + std::string(step == 0.0 ? "stalls" : "reverses") + " at sample " + std::to_string(i) +
              " (t = " + std::to_string(time_s[i]) +
              " s): spatial resampling needs a stroke that moves one way; low-pass the position or restrict "
              "the time range",
          {.key = "position"});
    steps.push_back(step);
  }
  if (!(dx_m > 0.0)) {
    dx_m = upper_median_in_place(steps);
  }
  SpatialSeries out;
  out.dx_m = dx_m;
  const double x0 = position_m[begin], x1 = position_m[end - 1];
  const double travel = std::abs(x1 - x0);
  out.mean_speed_m_s = travel / (time_s[end - 1] - time_s[begin]);
  out.peak_speed_m_s = peak_speed(time_s, position_m, begin, end, speed_window_s);
  const std::size_t count = static_cast<std::size_t>(std::floor(travel / dx_m + 1e-9)) + 1;
  out.x_m.resize(count);
  out.values.resize(count);
  std::size_t k = begin;
  for (std::size_t j = 0; j < count; ++j) {
    const double x = x0 + direction * dx_m * static_cast<double>(j);
    while (k + 2 < end && (position_m[k + 1] - x) * direction < 0.0) ++k;
    const double w = (x - position_m[k]) / (position_m[k + 1] - position_m[k]);
    out.x_m[j] = x;
    out.values[j] = values[k] + std::clamp(w, 0.0, 1.0) * (values[k + 1] - values[k]);
  }
  return out;
}

SpatialSpectrum spatial_spectrum(const SpatialSeries& series, const WelchOptions& options) {
  const PowerSpectrum p = welch(series.values, 1.0 / series.dx_m, options);
  return {p.freq_Hz, p.psd, series.mean_speed_m_s, series.peak_speed_m_s};
}

}  // namespace tirstrain::signals
