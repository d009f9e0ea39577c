#include "flow/temporal_smoothing.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/median.hpp"

namespace tirstrain::flow {
namespace {

// Window half-lengths tried, in frames: dense where windows are short, where a frame's difference matters.
constexpr std::array<int, 10> kHalfWindows = {1, 2, 3, 4, 6, 8, 12, 16, 24, 32};

struct Estimate {
  double value = 0.0;
  double variance_factor = 0.0;  // variance of the value over σ²
};

// Sums of a line fit about t0 (u = t − t0), grown a sample at a time as the window lengthens.
struct LineSums {
  double n = 0, su = 0, suu = 0, sx = 0, sux = 0;
  void add(double u, double x) {
    n += 1;
    su += u;
    suu += u * u;
    sx += x;
    sux += u * x;
  }
  // Value at u = 0 of the least-squares line, and its variance factor (AᵀA)⁻¹ for the column [u, 1].
  Estimate at_origin() const {
    const double d = n * suu - su * su;
    if (!(d > 0.0)) return {sx / n, 1.0 / n};
    return {(suu * sx - su * sux) / d, suu / d};
  }
};

}  // namespace

double series_noise(std::span<const double> x) {
  if (x.size() < 4) return 0.0;
  const auto median = [](std::vector<double>& v) { return upper_median_in_place(v); };
  // σ of white noise from the median absolute deviation of its k-th differences (variance 6σ² for the
  // second, 20σ² for the third; 1.4826 MAD estimates a normal σ). Motion adds to them too: a track that
  // accelerates in most frames (a plate faster than a frame's worth of the subset) puts its acceleration
  // into every second difference, while the third cancels a steady acceleration. The smaller of the two is
  // the one less taken by motion (for white noise both estimate σ).
  const auto from_differences = [&](int order, double variance_per_sigma2) {
    std::vector<double> d;
    for (std::size_t i = 0; i + static_cast<std::size_t>(order) < x.size(); ++i)
      d.push_back(order == 2 ? x[i + 2] - 2.0 * x[i + 1] + x[i]
                             : x[i + 3] - 3.0 * x[i + 2] + 3.0 * x[i + 1] - x[i]);
    const double m = median(d);
    for (double& v : d) v = std::abs(v - m);
    return 1.4826 * median(d) / std::sqrt(variance_per_sigma2);
  };
  return std::min(from_differences(2, 6.0), from_differences(3, 20.0));
}

std::vector<double> smooth_in_time(std::span<const double> t_s, std::span<const double> x, double sigma,
                                   const TemporalSmoothing& options) {
  std::vector<double> out(x.begin(), x.end());
  const int n = static_cast<int>(x.size());
  if (!(sigma > 0.0) || n < std::max(3, options.min_samples) || t_s.size() != x.size()) return out;
  enum Side { kCentred, kLeft, kRight };
  for (int i = 0; i < n; ++i) {
    const double t0 = t_s[static_cast<std::size_t>(i)];
    double weight_sum = 0.0, weighted = 0.0;
    for (Side side : {kCentred, kLeft, kRight}) {
      // The sample itself is the shortest window: a longer one must agree with it, so a kink or a jump
      // (the load's onset, a track's last frames) keeps its own value instead of the first line's.
      const double xi = x[static_cast<std::size_t>(i)];
      double low = xi - options.gamma * sigma, high = xi + options.gamma * sigma;
      Estimate best{xi, 1.0};
      LineSums sums;
      sums.add(0.0, xi);
      int reached = 0;  // half-length already in the sums
      for (int h : kHalfWindows) {
        if (h > options.max_half_window) break;
        const int a = side == kRight ? i : i - h, b = side == kLeft ? i : i + h;
        if (a < 0 || b > n - 1) break;
        for (int j = reached + 1; j <= h; ++j) {
          if (side != kRight)
            sums.add(t_s[static_cast<std::size_t>(i - j)] - t0, x[static_cast<std::size_t>(i - j)]);
          if (side != kLeft)
            sums.add(t_s[static_cast<std::size_t>(i + j)] - t0, x[static_cast<std::size_t>(i + j)]);
        }
        reached = h;
        if (b - a + 1 < 3) continue;  // a line through two points has no noise estimate to judge it by
        const Estimate e = sums.at_origin();
        const double sd = sigma * std::sqrt(e.variance_factor);
        low = std::max(low, e.value - options.gamma * sd);
        high = std::min(high, e.value + options.gamma * sd);
        if (low > high) break;  // disagrees with the shorter windows: motion a line cannot follow
        best = e;
      }
      const double w = 1.0 / best.variance_factor;
      weight_sum += w;
      weighted += w * best.value;
    }
    if (weight_sum > 0.0) out[static_cast<std::size_t>(i)] = weighted / weight_sum;
  }
  return out;
}

}  // namespace tirstrain::flow
