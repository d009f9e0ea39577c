// Recurrence analysis: hand-computed small matrices exactly, the fixed-rate threshold on a hand example,
// a sine's determinism, and white noise against its analytic chance baselines.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "signals/rqa.hpp"

namespace ts = tirstrain::signals;

namespace {
ts::RqaMeasures measures(const std::vector<double>& x, std::size_t dim, std::size_t delay, double eps,
                         ts::RecurrenceNorm norm = ts::RecurrenceNorm::euclidean) {
  const auto e = ts::delay_embed(x, dim, delay);
  return ts::rqa_measures(ts::line_histograms(ts::recurrence_matrix(e, eps, norm)), 2);
}
}  // namespace

TEST(Rqa, AlternatingSeriesByHand) {
  // x = 0,1,0,1,0,1, ε = 0.5: R_ij = 1 iff i ≢ j has the same parity. Off-diagonal ones: 6·2 = 12 of 30.
  // Diagonals: offset 2 is one line of 4, offset 4 one line of 2 (×2 triangles): DET = (8+4)/12·... = 1,
  // L = (4+4+2+2)/4 = 3. Every column's ones are isolated (alternate rows): LAM = 0.
  const auto m = measures({0, 1, 0, 1, 0, 1}, 1, 1, 0.5);
  EXPECT_DOUBLE_EQ(m.recurrence_rate, 12.0 / 30.0);
  EXPECT_DOUBLE_EQ(m.determinism, 1.0);
  EXPECT_DOUBLE_EQ(m.mean_diagonal_length, 3.0);
  EXPECT_DOUBLE_EQ(m.laminarity, 0.0);
  EXPECT_EQ(m.max_diagonal_length, 4u);
}

TEST(Rqa, TwoBlocksByHand) {
  // x = 0,0,0,1,1, ε = 0.5: blocks {0,1,2} and {3,4}. Off-diagonal ones 6 + 2 = 8 of 20 → RR = 0.4.
  // Upper diagonals: offset 1 has runs (0,1)(1,2) = 2 and (3,4) = 1; offset 2 has (0,2) = 1. Lines ≥ 2:
  // one per triangle, length 2 → DET = 4/8, L = 2. Vertical: columns 0 and 2 hold a run of 2 (rows 1–2 and
  // 0–1), columns 1, 3, 4 only runs of 1 (the diagonal splits them) → LAM = 4/8.
  const auto m = measures({0, 0, 0, 1, 1}, 1, 1, 0.5);
  EXPECT_DOUBLE_EQ(m.recurrence_rate, 0.4);
  EXPECT_DOUBLE_EQ(m.determinism, 0.5);
  EXPECT_DOUBLE_EQ(m.mean_diagonal_length, 2.0);
  EXPECT_DOUBLE_EQ(m.laminarity, 0.5);
  EXPECT_DOUBLE_EQ(m.trapping_time, 2.0);
  // Threshold is inclusive: distance exactly ε recurs.
  EXPECT_DOUBLE_EQ(measures({0, 1}, 1, 1, 1.0).recurrence_rate, 1.0);
  EXPECT_DOUBLE_EQ(measures({0, 1}, 1, 1, 0.999).recurrence_rate, 0.0);
}

TEST(Rqa, EmbeddingAndNorms) {
  const auto e = ts::delay_embed({1, 2, 3, 4, 5, 6}, 3, 2);
  ASSERT_EQ(e.points, 2u);
  EXPECT_EQ(e.point(1)[0], 2.0);
  EXPECT_EQ(e.point(1)[2], 6.0);
  EXPECT_DOUBLE_EQ(ts::embedded_distance(e, 0, 1, ts::RecurrenceNorm::euclidean), std::sqrt(3.0));
  EXPECT_DOUBLE_EQ(ts::embedded_distance(e, 0, 1, ts::RecurrenceNorm::supremum), 1.0);
  EXPECT_THROW(ts::delay_embed({1, 2, 3}, 3, 1), tirstrain::Error);
  EXPECT_THROW(ts::delay_embed({1, 2, 3}, 1, 0), tirstrain::Error);
}

TEST(Rqa, FixedRecurrenceRateThreshold) {
  // x = 0,1,3,7: pair distances 1,2,3,4,6,7. Rate 0.5 needs 3 of 6 pairs → ε = 3; rate 0.51 needs 4 → 4.
  const auto e = ts::delay_embed({0, 1, 3, 7}, 1, 1);
  EXPECT_DOUBLE_EQ(ts::threshold_for_recurrence_rate(e, 0.5, ts::RecurrenceNorm::euclidean), 3.0);
  EXPECT_DOUBLE_EQ(ts::threshold_for_recurrence_rate(e, 0.51, ts::RecurrenceNorm::euclidean), 4.0);
  EXPECT_DOUBLE_EQ(ts::threshold_for_recurrence_rate(e, 1.0, ts::RecurrenceNorm::euclidean), 7.0);
  // Larger series: the achieved rate hits the target within one pair.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(1500);
  for (double& v : x) v = u(rng);
  const auto big = ts::delay_embed(x, 3, 2);
  const double eps = ts::threshold_for_recurrence_rate(big, 0.05, ts::RecurrenceNorm::euclidean);
  const auto r = ts::recurrence_matrix(big, eps, ts::RecurrenceNorm::euclidean);
  const double pairs = 0.5 * big.points * (big.points - 1.0);
  EXPECT_NEAR(static_cast<double>(r.count()) / 2.0, std::ceil(0.05 * pairs), 1.0);
  // Constant series: every distance is 0.
  const auto flat = ts::delay_embed(std::vector<double>(50, 2.0), 2, 1);
  EXPECT_EQ(ts::threshold_for_recurrence_rate(flat, 0.1, ts::RecurrenceNorm::supremum), 0.0);
}

TEST(Rqa, SineIsDeterministic) {
  // A sine embedded in 2-D with a quarter-period delay is a circle traversed periodically: every
  // recurrence lies on a long diagonal.
  std::vector<double> x(2000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::sin(2 * std::numbers::pi * i / 100.0);
  const auto e = ts::delay_embed(x, 2, 25);
  const double eps = ts::threshold_for_recurrence_rate(e, 0.05, ts::RecurrenceNorm::euclidean);
  const auto m =
      ts::rqa_measures(ts::line_histograms(ts::recurrence_matrix(e, eps, ts::RecurrenceNorm::euclidean)));
  EXPECT_NEAR(m.recurrence_rate, 0.05, 0.002);
  EXPECT_GT(m.determinism, 0.98);
  EXPECT_GT(m.mean_diagonal_length, 50.0);
}

TEST(Rqa, WhiteNoiseSitsAtItsChanceBaselines) {
  // Uniform i.i.d. noise, D = 1, ε = 0.1: P(|x_i − x_j| ≤ ε) = 2ε − ε² = 0.19. Diagonal neighbours involve
  // independent samples, so a recurrent point lies on a line ≥ 2 with probability 1 − (1 − p)² (boundary
  // effects O(1/M)). Vertical neighbours share x_j: with q(x) = |[x−ε, x+ε] ∩ [0,1]| the chance baseline is
  // E[q·(1 − (1 − q)²)] / E[q], integrated here numerically.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(3000);
  for (double& v : x) v = u(rng);
  const double eps = 0.1, p = 2 * eps - eps * eps;
  const auto m = measures(x, 1, 1, eps);
  EXPECT_NEAR(m.recurrence_rate, p, 0.005);
  EXPECT_NEAR(m.determinism, 1 - (1 - p) * (1 - p), 0.01);
  double num = 0.0, den = 0.0;
  for (int i = 0; i < 100000; ++i) {
    const double xv = (i + 0.5) / 100000.0;
    const double q = std::min(1.0, xv + eps) - std::max(0.0, xv - eps);
    num += q * (1 - (1 - q) * (1 - q));
    den += q;
  }
  EXPECT_NEAR(m.laminarity, num / den, 0.01);
}

TEST(Rqa, JointRecurrenceAndEnsembles) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> a(1200), b(1200);
  for (double& v : a) v = u(rng);
  for (double& v : b) v = u(rng);
  const auto ra = ts::recurrence_matrix(ts::delay_embed(a, 1, 1), 0.1, ts::RecurrenceNorm::euclidean);
  const auto rb = ts::recurrence_matrix(ts::delay_embed(b, 1, 1), 0.1, ts::RecurrenceNorm::euclidean);
  EXPECT_EQ((ra & ra).count(), ra.count());
  // Independent series: the joint rate is the product of the rates.
  const double cells = 1200.0 * 1199.0;
  EXPECT_NEAR(static_cast<double>((ra & rb).count()) / cells, 0.19 * 0.19, 0.004);
  EXPECT_THROW(ra & ts::RecurrenceMatrix(5), tirstrain::Error);
  // Pooled histograms over trials: measures of two identical trials equal those of one.
  auto h = ts::line_histograms(ra);
  auto pooled = h;
  pooled += h;
  EXPECT_DOUBLE_EQ(ts::rqa_measures(pooled).determinism, ts::rqa_measures(h).determinism);
  EXPECT_EQ(pooled.cells, 2 * h.cells);
  const auto small_a =
      ts::recurrence_matrix(ts::delay_embed({0, 0, 0, 1, 1}, 1, 1), 0.5, ts::RecurrenceNorm::euclidean);
  const auto small_b =
      ts::recurrence_matrix(ts::delay_embed({0, 1, 0, 1, 0}, 1, 1), 0.5, ts::RecurrenceNorm::euclidean);
  const auto sum = ts::ensemble_sum({small_a, small_b, small_a});
  EXPECT_EQ(sum[0 * 5 + 1], 2);  // (0,1): recurrent in a only
  EXPECT_EQ(sum[0 * 5 + 2], 3);  // (0,2): recurrent in both
  EXPECT_EQ(sum[0 * 5 + 0], 0);  // identity excluded
}
