#pragma once
// Recurrence analysis: delay embedding, recurrence matrices (fixed threshold or fixed recurrence rate),
// joint recurrence of two series, ensemble sums over trials, and the RQA measures.
//
// Conventions (also printed by `tirstrain signals rqa --help`):
//   - embedding y_i = (x_i, x_{i+τ}, …, x_{i+(D−1)τ}), i = 0 … N−(D−1)τ−1 (M vectors);
//   - distance: Euclidean (default) or supremum (max-abs) norm;
//   - R_ij = 1 when distance(y_i, y_j) <= ε (inclusive);
//   - the line of identity (i = j) is excluded from every measure: it is not a recurrence, it is not a
//     diagonal line, and it splits vertical lines; rates are over the M(M−1) off-diagonal cells;
//   - diagonal lines are counted in both triangles (the matrix is symmetric), vertical lines in every
//     column; minimum line length l_min = 2 for both;
//   - RR = Σ R / (M(M−1)); DET = Σ_{l≥lmin} l·P(l) / Σ R; L = Σ_{l≥lmin} l·P(l) / Σ_{l≥lmin} P(l);
//     LAM = Σ_{v≥lmin} v·P(v) / Σ R; a measure with an empty denominator is 0;
//   - fixed recurrence rate r: ε is the smallest off-diagonal distance d such that at least
//     ceil(r·M(M−1)/2) of the M(M−1)/2 pairs have distance <= d (ties may push RR slightly above r);
//     recurrence_at_rate builds the matrix from the very comparison key that chose ε, so the promise holds
//     exactly (ε as a distance is only reported);
//   - fixed joint recurrence rate r: each series keeps its k closest pairs, with the smallest k for which
//     at least ceil(r·M(M−1)/2) pairs recur in both (one more when two pairs enter at the same k, ties
//     aside); both series then recur at the same rate k / (M(M−1)/2);
//   - ensemble of trials: the recurrence matrices are summed cell by cell; a cell of the ensemble plot
//     recurs when it recurs in at least a given number of trials.
// Memory: the matrix is a bitset (M²/8 bytes: 12.5 MB for M = 10⁴); choosing ε for a fixed rate uses two
// or three histogram passes over the distances instead of storing them.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace tirstrain::signals {

enum class RecurrenceNorm { euclidean, supremum };

// Row-major M×D matrix of embedded vectors.
struct Embedding {
  std::size_t points = 0;
  std::size_t dim = 0;
  std::vector<double> data;
  const double* point(std::size_t i) const { return data.data() + i * dim; }
};

// Throws Error when dim or delay is 0 or the series is too short for at least 2 embedded points.
Embedding delay_embed(const std::vector<double>& x, std::size_t dim, std::size_t delay);

double embedded_distance(const Embedding& e, std::size_t i, std::size_t j, RecurrenceNorm norm);

// Symmetric M×M bit matrix with a zero diagonal.
class RecurrenceMatrix {
 public:
  RecurrenceMatrix() = default;
  explicit RecurrenceMatrix(std::size_t size);
  std::size_t size() const { return size_; }
  bool get(std::size_t i, std::size_t j) const { return (bits_[i * words_ + j / 64] >> (j % 64)) & 1u; }
  void set_pair(std::size_t i, std::size_t j);  // sets (i, j) and (j, i)
  std::uint64_t count() const;                  // off-diagonal recurrent cells
  // Joint recurrence: cell-wise AND; sizes must match.
  RecurrenceMatrix operator&(const RecurrenceMatrix& other) const;
  const std::uint64_t* row(std::size_t i) const { return bits_.data() + i * words_; }
  std::size_t words_per_row() const { return words_; }

 private:
  std::size_t size_ = 0;
  std::size_t words_ = 0;
  std::vector<std::uint64_t> bits_;
};

RecurrenceMatrix recurrence_matrix(const Embedding& e, double threshold, RecurrenceNorm norm);

// ε for a target recurrence rate in (0, 1], see the conventions above.
double threshold_for_recurrence_rate(const Embedding& e, double rate, RecurrenceNorm norm);

// The matrix at a fixed recurrence rate, and the threshold that gives it (see the conventions above).
struct RateRecurrence {
  RecurrenceMatrix matrix;
  double threshold = 0.0;  // ε, in the series' units
};
RateRecurrence recurrence_at_rate(const Embedding& e, double rate, RecurrenceNorm norm);

// The joint recurrence matrix of two embeddings of equal length at a fixed joint recurrence rate.
struct JointRateRecurrence {
  RecurrenceMatrix matrix;
  double threshold_x = 0.0, threshold_y = 0.0;  // each series' ε, in its units
  double rate_each = 0.0;                       // the recurrence rate each series is held at
};
JointRateRecurrence joint_recurrence_at_rate(const Embedding& x, const Embedding& y, double joint_rate,
                                             RecurrenceNorm norm);

// Line-length histograms; index l holds the number of lines of length l (both triangles for diagonals).
struct LineHistograms {
  std::vector<std::uint64_t> diagonal;
  std::vector<std::uint64_t> vertical;
  std::uint64_t recurrent = 0;                              // off-diagonal recurrent cells
  std::uint64_t cells = 0;                                  // M(M−1)
  LineHistograms& operator+=(const LineHistograms& other);  // ensemble pooling over trials
};

LineHistograms line_histograms(const RecurrenceMatrix& r);

struct RqaMeasures {
  double recurrence_rate = 0.0;
  double determinism = 0.0;
  double mean_diagonal_length = 0.0;
  double laminarity = 0.0;
  double trapping_time = 0.0;  // mean vertical line length (lines >= l_min)
  std::size_t max_diagonal_length = 0;
};

RqaMeasures rqa_measures(const LineHistograms& h, std::size_t min_line = 2);

// Ensemble sum over trials: cell (i, j) counts the trials in which i and j recur. All matrices must have
// the same size; the counts are M² 16-bit values, so callers should keep M moderate (2·M² bytes).
std::vector<std::uint16_t> ensemble_sum(const std::vector<RecurrenceMatrix>& trials);
// The ensemble recurrence plot: cells that recur in at least min_trials of the trials.
RecurrenceMatrix ensemble_matrix(const std::vector<RecurrenceMatrix>& trials, std::size_t min_trials);

}  // namespace tirstrain::signals
