#include "signals/rqa.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

// Comparisons use a "key" that is monotone in the distance and cheap: the squared distance for the
// Euclidean norm (no square root per pair), the distance itself for the supremum norm.
inline double pair_key(const Embedding& e, std::size_t i, std::size_t j, RecurrenceNorm norm) {
  const double* a = e.point(i);
  const double* b = e.point(j);
  double acc = 0.0;
  if (norm == RecurrenceNorm::euclidean) {
    for (std::size_t d = 0; d < e.dim; ++d) {
      const double diff = a[d] - b[d];
      acc += diff * diff;
    }
  } else {
    for (std::size_t d = 0; d < e.dim; ++d) acc = std::max(acc, std::abs(a[d] - b[d]));
  }
  return acc;
}

double key_of_threshold(double eps, RecurrenceNorm norm) {
  return norm == RecurrenceNorm::euclidean ? eps * eps : eps;
}
double threshold_of_key(double key, RecurrenceNorm norm) {
  return norm == RecurrenceNorm::euclidean ? std::sqrt(key) : key;
}

template <typename Visit>
void for_each_pair(const Embedding& e, RecurrenceNorm norm, Visit visit) {
  for (std::size_t i = 0; i < e.points; ++i)
    for (std::size_t j = i + 1; j < e.points; ++j) visit(i, j, pair_key(e, i, j, norm));
}

double upper_bound_key(const Embedding& e, RecurrenceNorm norm) {
  double sum_sq = 0.0, max_range = 0.0;
  for (std::size_t d = 0; d < e.dim; ++d) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < e.points; ++i) {
      lo = std::min(lo, e.point(i)[d]);
      hi = std::max(hi, e.point(i)[d]);
    }
    sum_sq += (hi - lo) * (hi - lo);
    max_range = std::max(max_range, hi - lo);
  }
  return norm == RecurrenceNorm::euclidean ? sum_sq : max_range;
}

void add_run(std::vector<std::uint64_t>& hist, std::size_t length, std::uint64_t weight) {
  if (length == 0) return;
  if (hist.size() <= length) hist.resize(length + 1, 0);
  hist[length] += weight;
}

// The key of the target-th smallest pair (1-based): a few histogram passes narrow the range, then the
// pairs in the last bin are collected and selected exactly.
double key_at_rank(const Embedding& e, RecurrenceNorm norm, std::uint64_t target) {
  constexpr std::size_t kBins = 1 << 16;
  constexpr std::uint64_t kCollectLimit = 1 << 22;
  double lo = 0.0, hi = upper_bound_key(e, norm);
  std::uint64_t below = 0;  // pairs with key < lo
  std::vector<std::uint64_t> hist(kBins);
  std::vector<double> bin_min(kBins), bin_max(kBins);
  for (int pass = 0; pass < 64; ++pass) {
    if (!(hi > lo)) return lo;
    const double width = (hi - lo) / static_cast<double>(kBins);
    auto bin_of = [&](double k) {
      return std::min<std::size_t>(kBins - 1, static_cast<std::size_t>((k - lo) / width));
    };
    std::fill(hist.begin(), hist.end(), 0);
    std::fill(bin_min.begin(), bin_min.end(), std::numeric_limits<double>::infinity());
    std::fill(bin_max.begin(), bin_max.end(), -std::numeric_limits<double>::infinity());
    std::uint64_t new_below = 0;
    for_each_pair(e, norm, [&](std::size_t, std::size_t, double k) {
      if (k < lo) {
        ++new_below;
      } else if (k <= hi) {
        const std::size_t b = bin_of(k);
        ++hist[b];
        bin_min[b] = std::min(bin_min[b], k);
        bin_max[b] = std::max(bin_max[b], k);
      }
    });
    below = new_below;
    std::uint64_t cumulative = below;
    std::size_t b = 0;
    for (; b < kBins; ++b) {
      if (cumulative + hist[b] >= target) break;
      cumulative += hist[b];
    }
    if (b == kBins) return hi;
    if (bin_min[b] == bin_max[b]) return bin_min[b];
    if (hist[b] <= kCollectLimit) {
      std::vector<double> keys;
      keys.reserve(hist[b]);
      const double bmin = bin_min[b], bmax = bin_max[b];
      for_each_pair(e, norm, [&](std::size_t, std::size_t, double k) {
        if (k >= bmin && k <= bmax && k >= lo && k <= hi && bin_of(k) == b) keys.push_back(k);
      });
      const std::size_t rank = static_cast<std::size_t>(target - cumulative - 1);
      std::nth_element(keys.begin(), keys.begin() + static_cast<std::ptrdiff_t>(rank), keys.end());
      return keys[rank];
    }
    lo = bin_min[b];
    hi = bin_max[b];
  }
  return hi;
}

std::uint64_t pair_count(std::size_t points) {
  return static_cast<std::uint64_t>(points) * (points > 0 ? points - 1 : 0) / 2;
}

// ceil(rate · pairs) as an integer, at least 1: the promise of a fixed recurrence rate.
std::uint64_t pairs_for_rate(double rate, std::uint64_t pairs, const char* key) {
  if (!(rate > 0.0 && rate <= 1.0)) throw Error("recurrence rate must lie in (0, 1]", {.key = key});
  // A decimal rate such as 0.05 is not exact in binary: the product is allowed a relative 1e-12 so that
  // 0.05 · 100 pairs asks for 5 pairs, not 6.
  const double wanted = rate * static_cast<double>(pairs);
  const auto target = static_cast<std::uint64_t>(std::ceil(wanted * (1.0 - 1e-12)));
  return std::clamp<std::uint64_t>(target, 1, std::max<std::uint64_t>(pairs, 1));
}

RecurrenceMatrix matrix_at_key(const Embedding& e, double key, RecurrenceNorm norm) {
  RecurrenceMatrix r(e.points);
  for_each_pair(e, norm, [&](std::size_t i, std::size_t j, double k) {
    if (k <= key) r.set_pair(i, j);
  });
  return r;
}

std::uint64_t joint_pairs_within(const Embedding& x, const Embedding& y, double key_x, double key_y,
                                 RecurrenceNorm norm) {
  std::uint64_t n = 0;
  for_each_pair(x, norm, [&](std::size_t i, std::size_t j, double k) {
    if (k <= key_x && pair_key(y, i, j, norm) <= key_y) ++n;
  });
  return n;
}

}  // namespace

Embedding delay_embed(const std::vector<double>& x, std::size_t dim, std::size_t delay) {
  if (dim == 0) throw Error("embedding dimension must be at least 1", {.key = "dim"});
  if (delay == 0) throw Error("embedding delay must be at least 1 sample", {.key = "delay"});
  const std::size_t span = (dim - 1) * delay;
  if (x.size() < span + 2)
    throw Error("series of " + std::to_string(x.size()) + " samples is too short for dimension " +
                    std::to_string(dim) + " and delay " + std::to_string(delay) + " (needs at least " +
                    std::to_string(span + 2) + ")",
                {.key = "dim"});
  Embedding e;
  e.points = x.size() - span;
  e.dim = dim;
  e.data.resize(e.points * dim);
  for (std::size_t i = 0; i < e.points; ++i)
    for (std::size_t d = 0; d < dim; ++d) e.data[i * dim + d] = x[i + d * delay];
  return e;
}

double embedded_distance(const Embedding& e, std::size_t i, std::size_t j, RecurrenceNorm norm) {
  return threshold_of_key(pair_key(e, i, j, norm), norm);
}

RecurrenceMatrix::RecurrenceMatrix(std::size_t size)
    : size_(size), words_((size + 63) / 64), bits_(size * words_, 0) {}

void RecurrenceMatrix::set_pair(std::size_t i, std::size_t j) {
  bits_[i * words_ + j / 64] |= std::uint64_t{1} << (j % 64);
  bits_[j * words_ + i / 64] |= std::uint64_t{1} << (i % 64);
}

std::uint64_t RecurrenceMatrix::count() const {
  std::uint64_t total = 0;
  for (std::uint64_t w : bits_) total += static_cast<std::uint64_t>(std::popcount(w));
  return total;
}

RecurrenceMatrix RecurrenceMatrix::operator&(const RecurrenceMatrix& other) const {
  if (other.size_ != size_)
    throw Error("joint recurrence needs series of equal embedded length (" + std::to_string(size_) + " vs " +
                std::to_string(other.size_) + " points)");
  RecurrenceMatrix out(size_);
  for (std::size_t k = 0; k < bits_.size(); ++k) out.bits_[k] = bits_[k] & other.bits_[k];
  return out;
}

RecurrenceMatrix recurrence_matrix(const Embedding& e, double threshold, RecurrenceNorm norm) {
  if (!(threshold >= 0.0) || !std::isfinite(threshold))
    throw Error("recurrence threshold must be a finite number >= 0", {.key = "threshold"});
  return matrix_at_key(e, key_of_threshold(threshold, norm), norm);
}

double threshold_for_recurrence_rate(const Embedding& e, double rate, RecurrenceNorm norm) {
  const std::uint64_t target = pairs_for_rate(rate, pair_count(e.points), "recurrence_rate");
  return threshold_of_key(key_at_rank(e, norm, target), norm);
}

RateRecurrence recurrence_at_rate(const Embedding& e, double rate, RecurrenceNorm norm) {
  const std::uint64_t target = pairs_for_rate(rate, pair_count(e.points), "recurrence_rate");
  const double key = key_at_rank(e, norm, target);
  return {matrix_at_key(e, key, norm), threshold_of_key(key, norm)};
}

JointRateRecurrence joint_recurrence_at_rate(const Embedding& x, const Embedding& y, double joint_rate,
                                             RecurrenceNorm norm) {
  if (x.points != y.points)
    throw Error("joint recurrence needs series of equal embedded length (" + std::to_string(x.points) +
                " vs " + std::to_string(y.points) + " points)");
  const std::uint64_t pairs = pair_count(x.points);
  const std::uint64_t target = pairs_for_rate(joint_rate, pairs, "joint_recurrence_rate");
  // Each series keeps its own k nearest pairs; the joint count grows with k, so the smallest k whose joint
  // plot holds the target is found by bisection over k.
  std::uint64_t lo = target, hi = pairs;
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    const double kx = key_at_rank(x, norm, mid), ky = key_at_rank(y, norm, mid);
    if (joint_pairs_within(x, y, kx, ky, norm) >= target)
      hi = mid;
    else
      lo = mid + 1;
  }
  const double key_x = key_at_rank(x, norm, lo), key_y = key_at_rank(y, norm, lo);
  JointRateRecurrence out;
  out.matrix = matrix_at_key(x, key_x, norm) & matrix_at_key(y, key_y, norm);
  out.threshold_x = threshold_of_key(key_x, norm);
  out.threshold_y = threshold_of_key(key_y, norm);
  out.rate_each = static_cast<double>(lo) / static_cast<double>(pairs);
  return out;
}

LineHistograms& LineHistograms::operator+=(const LineHistograms& other) {
  if (diagonal.size() < other.diagonal.size()) diagonal.resize(other.diagonal.size(), 0);
  if (vertical.size() < other.vertical.size()) vertical.resize(other.vertical.size(), 0);
  for (std::size_t l = 0; l < other.diagonal.size(); ++l) diagonal[l] += other.diagonal[l];
  for (std::size_t l = 0; l < other.vertical.size(); ++l) vertical[l] += other.vertical[l];
  recurrent += other.recurrent;
  cells += other.cells;
  return *this;
}

LineHistograms line_histograms(const RecurrenceMatrix& r) {
  LineHistograms h;
  const std::size_t m = r.size();
  h.cells = static_cast<std::uint64_t>(m) * (m > 0 ? m - 1 : 0);
  // Diagonals k >= 1 of the upper triangle; the lower triangle mirrors them, so each line counts twice.
  for (std::size_t k = 1; k < m; ++k) {
    std::size_t run = 0;
    for (std::size_t i = 0; i + k < m; ++i) {
      if (r.get(i, i + k)) {
        ++run;
      } else {
        add_run(h.diagonal, run, 2);
        run = 0;
      }
    }
    add_run(h.diagonal, run, 2);
  }
  // Vertical lines of column j are the horizontal runs of row j (symmetry), read a word at a time; the
  // zero diagonal bit splits lines through the line of identity.
  const std::size_t words = r.words_per_row();
  for (std::size_t j = 0; j < m; ++j) {
    const std::uint64_t* row = r.row(j);
    std::size_t run = 0;
    for (std::size_t w = 0; w < words; ++w) {
      std::uint64_t bits = row[w];
      h.recurrent += static_cast<std::uint64_t>(std::popcount(bits));
      if (bits == 0) {
        add_run(h.vertical, run, 1);
        run = 0;
        continue;
      }
      if (bits == ~std::uint64_t{0}) {
        run += 64;
        continue;
      }
      int pos = 0;
      while (pos < 64) {
        const std::uint64_t shifted = bits >> pos;
        if (shifted & 1u) {
          const int ones = std::countr_one(shifted);
          run += static_cast<std::size_t>(ones);
          pos += ones;
        } else {
          add_run(h.vertical, run, 1);
          run = 0;
          if (shifted == 0) break;
          pos += std::countr_zero(shifted);
        }
      }
    }
    add_run(h.vertical, run, 1);
  }
  return h;
}

RqaMeasures rqa_measures(const LineHistograms& h, std::size_t min_line) {
  if (min_line < 1) throw Error("minimum line length must be at least 1", {.key = "min_line"});
  RqaMeasures out;
  if (h.cells > 0) out.recurrence_rate = static_cast<double>(h.recurrent) / static_cast<double>(h.cells);
  double diag_points = 0.0, diag_lines = 0.0;
  for (std::size_t l = min_line; l < h.diagonal.size(); ++l) {
    diag_points += static_cast<double>(l) * static_cast<double>(h.diagonal[l]);
    diag_lines += static_cast<double>(h.diagonal[l]);
  }
  for (std::size_t l = h.diagonal.size(); l-- > 1;)
    if (h.diagonal[l] > 0) {
      out.max_diagonal_length = l;
      break;
    }
  double vert_points = 0.0, vert_lines = 0.0;
  for (std::size_t l = min_line; l < h.vertical.size(); ++l) {
    vert_points += static_cast<double>(l) * static_cast<double>(h.vertical[l]);
    vert_lines += static_cast<double>(h.vertical[l]);
  }
  const double rec = static_cast<double>(h.recurrent);
  if (rec > 0.0) {
    out.determinism = diag_points / rec;
    out.laminarity = vert_points / rec;
  }
  if (diag_lines > 0.0) out.mean_diagonal_length = diag_points / diag_lines;
  if (vert_lines > 0.0) out.trapping_time = vert_points / vert_lines;
  return out;
}

RecurrenceMatrix ensemble_matrix(const std::vector<RecurrenceMatrix>& trials, std::size_t min_trials) {
  if (min_trials < 1 || min_trials > trials.size())
    throw Error("an ensemble cell needs between 1 and " + std::to_string(trials.size()) +
                    " recurring trials, not " + std::to_string(min_trials),
                {.key = "ensemble_min_trials"});
  const auto counts = ensemble_sum(trials);
  const std::size_t m = trials.front().size();
  RecurrenceMatrix out(m);
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t j = i + 1; j < m; ++j)
      if (counts[i * m + j] >= min_trials) out.set_pair(i, j);
  return out;
}

std::vector<std::uint16_t> ensemble_sum(const std::vector<RecurrenceMatrix>& trials) {
  if (trials.empty()) return {};
  if (trials.size() > 65535) throw Error("ensemble sum supports at most 65535 trials");
  const std::size_t m = trials.front().size();
  for (const auto& t : trials)
    if (t.size() != m) throw Error("ensemble sum needs trials of equal embedded length");
  std::vector<std::uint16_t> sum(m * m, 0);
  for (const auto& t : trials)
    for (std::size_t i = 0; i < m; ++i)
      for (std::size_t j = 0; j < m; ++j)
        sum[i * m + j] = static_cast<std::uint16_t>(sum[i * m + j] + t.get(i, j));
  return sum;
}

}  // namespace tirstrain::signals
