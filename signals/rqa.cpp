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
  const double key = key_of_threshold(threshold, norm);
  RecurrenceMatrix r(e.points);
  for_each_pair(e, norm, [&](std::size_t i, std::size_t j, double k) {
    if (k <= key) r.set_pair(i, j);
  });
  return r;
}

double threshold_for_recurrence_rate(const Embedding& e, double rate, RecurrenceNorm norm) {
  if (!(rate > 0.0 && rate <= 1.0))
    throw Error("recurrence rate must lie in (0, 1]", {.key = "recurrence_rate"});
  const double pairs = 0.5 * static_cast<double>(e.points) * static_cast<double>(e.points - 1);
  const auto target = static_cast<std::uint64_t>(std::max(1.0, std::ceil(rate * pairs - 1e-9)));
  constexpr std::size_t kBins = 1 << 16;
  constexpr std::uint64_t kCollectLimit = 1 << 22;
  double lo = 0.0, hi = upper_bound_key(e, norm);
  std::uint64_t below = 0;  // pairs with key < lo
  std::vector<std::uint64_t> hist(kBins);
  std::vector<double> bin_min(kBins), bin_max(kBins);
  for (int pass = 0; pass < 64; ++pass) {
    if (!(hi > lo)) return threshold_of_key(lo, norm);
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
    if (b == kBins) return threshold_of_key(hi, norm);
    if (bin_min[b] == bin_max[b]) return threshold_of_key(bin_min[b], norm);
    if (hist[b] <= kCollectLimit) {
      std::vector<double> keys;
      keys.reserve(hist[b]);
      const double bmin = bin_min[b], bmax = bin_max[b];
      for_each_pair(e, norm, [&](std::size_t, std::size_t, double k) {
        if (k >= bmin && k <= bmax && k >= lo && k <= hi && bin_of(k) == b) keys.push_back(k);
      });
      const std::size_t rank = static_cast<std::size_t>(target - cumulative - 1);
      std::nth_element(keys.begin(), keys.begin() + static_cast<std::ptrdiff_t>(rank), keys.end());
      return threshold_of_key(keys[rank], norm);
    }
    lo = bin_min[b];
    hi = bin_max[b];
  }
  return threshold_of_key(hi, norm);
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
