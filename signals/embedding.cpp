#include "signals/embedding.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

void require_finite(const std::vector<double>& x) {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!std::isfinite(x[i]))
      throw Error("sample " + std::to_string(i) + " is not a finite number", {.key = "column"});
}

// Equiprobable bins: each holds the same number of samples (ties kept together), so the marginals are flat
// and the estimate follows the joint structure rather than the series' amplitude distribution.
std::vector<std::size_t> bin_indices(const std::vector<double>& x, std::size_t bins) {
  std::vector<std::size_t> order(x.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return x[a] < x[b]; });
  std::vector<std::size_t> out(x.size(), 0);
  std::size_t rank = 0;
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (k > 0 && x[order[k]] != x[order[k - 1]]) rank = k;
    out[order[k]] = std::min(bins - 1, rank * bins / x.size());
  }
  return out;
}

double mutual_information_at(const std::vector<std::size_t>& bin, std::size_t bins, std::size_t delay) {
  const std::size_t n = bin.size() - delay;
  std::vector<double> joint(bins * bins, 0.0), pa(bins, 0.0), pb(bins, 0.0);
  for (std::size_t t = 0; t < n; ++t) {
    joint[bin[t] * bins + bin[t + delay]] += 1.0;
    pa[bin[t]] += 1.0;
    pb[bin[t + delay]] += 1.0;
  }
  double mi = 0.0;
  const double total = static_cast<double>(n);
  for (std::size_t a = 0; a < bins; ++a)
    for (std::size_t b = 0; b < bins; ++b) {
      const double p = joint[a * bins + b];
      if (p > 0.0) mi += p / total * std::log(p * total / (pa[a] * pb[b]));
    }
  return mi;
}

double standard_deviation(const std::vector<double>& x) {
  const double mean = std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
  double ss = 0.0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return std::sqrt(ss / static_cast<double>(x.size()));
}

// Squared Euclidean distance between the D-dimensional delay vectors starting at i and j.
double distance_sq(const std::vector<double>& x, std::size_t i, std::size_t j, std::size_t dim,
                   std::size_t delay) {
  double acc = 0.0;
  for (std::size_t d = 0; d < dim; ++d) {
    const double diff = x[i + d * delay] - x[j + d * delay];
    acc += diff * diff;
  }
  return acc;
}

double false_fraction(const std::vector<double>& x, std::size_t dim, const FalseNeighbourOptions& o,
                      double size_sd) {
  const std::size_t points = x.size() - dim * o.delay;  // points that also have coordinate D + 1
  std::size_t false_count = 0, counted = 0;
  for (std::size_t i = 0; i < points; ++i) {
    double best = std::numeric_limits<double>::infinity();
    std::size_t nearest = points;
    for (std::size_t j = 0; j < points; ++j) {
      const std::size_t gap = i > j ? i - j : j - i;
      if (gap == 0 || gap < o.theiler_window) continue;
      const double d = distance_sq(x, i, j, dim, o.delay);
      if (d < best && d > 0.0) {
        best = d;
        nearest = j;
      }
    }
    if (nearest == points) continue;
    ++counted;
    const double extra = std::abs(x[i + dim * o.delay] - x[nearest + dim * o.delay]);
    const double grown = std::sqrt(best + extra * extra);
    if (extra > o.distance_ratio * std::sqrt(best) || grown > o.size_ratio * size_sd) ++false_count;
  }
  return counted == 0 ? 0.0 : static_cast<double>(false_count) / static_cast<double>(counted);
}

}  // namespace

std::vector<double> delayed_mutual_information(const std::vector<double>& x,
                                               const MutualInformationOptions& options) {
  if (options.bins < 2) throw Error("mutual information needs at least 2 bins", {.key = "bins"});
  if (x.size() < options.max_delay + 16)
    throw Error("series of " + std::to_string(x.size()) + " samples is too short for delays up to " +
                    std::to_string(options.max_delay) + " (needs at least " +
                    std::to_string(options.max_delay + 16) + ")",
                {.key = "max_delay"});
  require_finite(x);
  const auto bin = bin_indices(x, options.bins);
  std::vector<double> mi(options.max_delay + 1);
  for (std::size_t tau = 0; tau <= options.max_delay; ++tau)
    mi[tau] = mutual_information_at(bin, options.bins, tau);
  return mi;
}

std::size_t first_local_minimum(const std::vector<double>& values, std::size_t window) {
  window = std::max<std::size_t>(window, 1);
  for (std::size_t k = 1; k + 1 < values.size(); ++k) {
    bool lowest = values[k] < values[k - 1];
    const std::size_t last = std::min(values.size() - 1, k + window);
    for (std::size_t j = k - std::min(k, window); j <= last && lowest; ++j)
      if (j != k && values[j] < values[k]) lowest = false;
    if (lowest) return k;
  }
  return 0;
}

std::vector<double> false_nearest_neighbours(const std::vector<double>& x, const FalseNeighbourOptions& o) {
  if (o.max_dim < 1) throw Error("must be at least 1", {.key = "max_dim"});
  if (o.delay < 1) throw Error("must be at least 1 sample", {.key = "delay"});
  if (x.size() < o.max_dim * o.delay + 2 + o.theiler_window)
    throw Error("series of " + std::to_string(x.size()) + " samples is too short for dimension " +
                    std::to_string(o.max_dim) + " and delay " + std::to_string(o.delay),
                {.key = "max_dim"});
  if (x.size() > o.max_points)
    throw Error("series of " + std::to_string(x.size()) + " samples: the neighbour search is O(N^2); " +
                    "decimate or cut it to at most " + std::to_string(o.max_points) + " samples",
                {.key = "column"});
  require_finite(x);
  const double sd = standard_deviation(x);
  std::vector<double> fraction(o.max_dim);
  for (std::size_t dim = 1; dim <= o.max_dim; ++dim) fraction[dim - 1] = false_fraction(x, dim, o, sd);
  return fraction;
}

}  // namespace tirstrain::signals
