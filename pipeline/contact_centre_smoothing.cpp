#include "pipeline/contact_centre_smoothing.hpp"

#include <numeric>

#include "core/median.hpp"

namespace tirstrain::pipeline {
namespace {

// Rows [first, last) of one run, smoothed into `out`; each axis's noise appended to `noise`.
void smooth_run(std::span<const std::optional<Vec2>> measured, std::size_t first, std::size_t last,
                const flow::TemporalSmoothing& options, CentreSmoothing& out, std::vector<double>& noise) {
  const std::size_t n = last - first;
  if (static_cast<int>(n) < options.min_samples) return;
  std::vector<double> t(n), x(n), y(n);
  std::iota(t.begin(), t.end(), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = measured[first + i]->x;
    y[i] = measured[first + i]->y;
  }
  const double sigma_x = flow::series_noise(x), sigma_y = flow::series_noise(y);
  noise.push_back(sigma_x);
  noise.push_back(sigma_y);
  const std::vector<double> sx = flow::smooth_in_time(t, x, sigma_x, options);
  const std::vector<double> sy = flow::smooth_in_time(t, y, sigma_y, options);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 smoothed{sx[i], sy[i]};
    if (smoothed.x == x[i] && smoothed.y == y[i]) continue;
    out.centre_px[first + i] = smoothed;
    out.changed[first + i] = true;
    ++out.frames_changed;
  }
}

}  // namespace

CentreSmoothing smooth_centres_in_time(std::span<const std::optional<Vec2>> measured_px,
                                       const flow::TemporalSmoothing& options) {
  CentreSmoothing out;
  out.centre_px.assign(measured_px.begin(), measured_px.end());
  out.changed.assign(measured_px.size(), false);
  std::vector<double> noise;
  std::size_t first = 0;
  for (std::size_t row = 0; row <= measured_px.size(); ++row) {
    if (row < measured_px.size() && measured_px[row]) continue;
    smooth_run(measured_px, first, row, options, out, noise);
    first = row + 1;
  }
  if (!noise.empty()) out.noise_px = upper_median_in_place(noise);
  return out;
}

}  // namespace tirstrain::pipeline
