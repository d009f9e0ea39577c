// Recurrence options beyond the plain analysis: the exact fixed-rate promise, the joint plot at a fixed
// density, the ensemble of summed matrices, the plot as a picture, and the embedding helpers against
// closed forms (a Gaussian AR(1)'s mutual information, a sine's quarter period, the Hénon map's dimension).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "signals/embedding.hpp"
#include "signals/recurrence_plot.hpp"
#include "signals/rqa.hpp"

namespace ts = tirstrain::signals;

namespace {
std::vector<double> noise(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> x(n);
  for (double& v : x) v = g(rng);
  return x;
}
std::uint64_t pairs_of(const ts::RecurrenceMatrix& r) {
  return r.count() / 2;
}
}  // namespace

TEST(RecurrenceRate, KeepsExactlyTheCeilingOfTheAskedPairs) {
  // Random Euclidean distances have no ties, so the promise ceil(R·M(M−1)/2) is exact, also for rates whose
  // product with the pair count is not an integer.
  for (unsigned seed = 1; seed <= 6; ++seed) {
    const auto e = ts::delay_embed(noise(150 + seed * 7, seed), 3, 2);
    const std::uint64_t pairs = e.points * (e.points - 1) / 2;
    for (double rate : {0.013, 0.05, 0.2173}) {
      const auto want = static_cast<std::uint64_t>(std::ceil(rate * static_cast<double>(pairs) - 1e-9));
      const auto r = ts::recurrence_at_rate(e, rate, ts::RecurrenceNorm::euclidean);
      EXPECT_EQ(pairs_of(r.matrix), want) << "seed " << seed << " rate " << rate;
      // The supremum norm ties often (delay vectors share coordinates); ties are kept together.
      const auto sup = ts::recurrence_at_rate(e, rate, ts::RecurrenceNorm::supremum);
      EXPECT_GE(pairs_of(sup.matrix), want);
      EXPECT_LE(pairs_of(sup.matrix), want + 8);
    }
  }
  // A decimal rate whose product is an integer asks for that integer, though 0.05 is not exact in binary:
  // 0.05 of 3240 pairs (M = 81) is 162.
  const auto e = ts::delay_embed(noise(81, 9), 1, 1);
  EXPECT_EQ(pairs_of(ts::recurrence_at_rate(e, 0.05, ts::RecurrenceNorm::euclidean).matrix), 162u);
}

TEST(RecurrenceRate, JointPlotHoldsTheAskedDensity) {
  const auto x = ts::delay_embed(noise(300, 3), 2, 3), y = ts::delay_embed(noise(300, 4), 2, 3);
  const std::uint64_t pairs = x.points * (x.points - 1) / 2;
  for (double rate : {0.02, 0.1}) {
    const auto j = ts::joint_recurrence_at_rate(x, y, rate, ts::RecurrenceNorm::euclidean);
    const auto want = static_cast<std::uint64_t>(std::ceil(rate * static_cast<double>(pairs)));
    EXPECT_GE(pairs_of(j.matrix), want);
    EXPECT_LE(pairs_of(j.matrix), want + 1);
    // Independent series: each must recur far more often than the joint plot (about sqrt(rate)).
    EXPECT_NEAR(j.rate_each, std::sqrt(rate), 0.35 * std::sqrt(rate));
    // The matrix is the AND of the two series at the reported thresholds.
    const auto rebuilt =
        ts::recurrence_matrix(x, j.threshold_x * (1 + 1e-12), ts::RecurrenceNorm::euclidean) &
        ts::recurrence_matrix(y, j.threshold_y * (1 + 1e-12), ts::RecurrenceNorm::euclidean);
    EXPECT_EQ(rebuilt.count(), j.matrix.count());
  }
  EXPECT_THROW(ts::joint_recurrence_at_rate(x, ts::delay_embed(noise(200, 5), 2, 3), 0.1,
                                            ts::RecurrenceNorm::euclidean),
               tirstrain::Error);
}

TEST(RecurrenceEnsemble, SummedMatricesKeepCellsRecurringInEnoughTrials) {
  // Three 4-point trials by hand: pair (0,1) recurs in all three, (2,3) in two, (0,3) in one.
  std::vector<ts::RecurrenceMatrix> trials(3, ts::RecurrenceMatrix(4));
  for (auto& t : trials) t.set_pair(0, 1);
  trials[0].set_pair(2, 3);
  trials[1].set_pair(2, 3);
  trials[2].set_pair(0, 3);
  EXPECT_EQ(ts::ensemble_sum(trials)[0 * 4 + 1], 3);
  EXPECT_EQ(ts::ensemble_sum(trials)[3 * 4 + 2], 2);
  EXPECT_EQ(pairs_of(ts::ensemble_matrix(trials, 1)), 3u);
  EXPECT_EQ(pairs_of(ts::ensemble_matrix(trials, 2)), 2u);
  const auto all = ts::ensemble_matrix(trials, 3);
  EXPECT_EQ(pairs_of(all), 1u);
  EXPECT_TRUE(all.get(1, 0));
  EXPECT_THROW(ts::ensemble_matrix(trials, 4), tirstrain::Error);
}

TEST(RecurrencePlot, DarkCellsAreTheRecurrencesWithTheOriginAtTheBottomLeft) {
  ts::RecurrenceMatrix r(100);
  r.set_pair(10, 90);  // (i = 10, j = 90) is near the top-left; its mirror near the bottom-right
  ts::RecurrencePlotLayout l;
  const cv::Mat img = ts::render_recurrence_plot(r, {}, &l);
  ASSERT_EQ(l.block, 1u);
  ASSERT_EQ(l.side, 100);
  auto grey = [&](std::size_t i, std::size_t j) {
    return img.at<cv::Vec3b>(l.top + l.side - 1 - static_cast<int>(j), l.left + static_cast<int>(i))[0];
  };
  EXPECT_EQ(grey(10, 90), 0);
  EXPECT_EQ(grey(90, 10), 0);
  EXPECT_EQ(grey(50, 50), 255);  // the line of identity is not a recurrence
  // A 1000-point matrix in a 100-pixel plot: blocks of 10, each as dark as its recurring fraction.
  ts::RecurrenceMatrix big(1000);
  for (std::size_t i = 0; i < 5; ++i)
    for (std::size_t j = 10; j < 20; ++j) big.set_pair(i, j);  // half of block (0, 1)
  ts::RecurrencePlotOptions o;
  o.max_side_px = 100;
  const cv::Mat small = ts::render_recurrence_plot(big, o, &l);
  ASSERT_EQ(l.block, 10u);
  EXPECT_NEAR(small.at<cv::Vec3b>(l.top + l.side - 2, l.left)[0], 128, 1);
}

TEST(Embedding, MutualInformationOfAGaussianAr1MatchesItsClosedForm) {
  // x_{t+1} = φ x_t + e: corr(x_t, x_{t+τ}) = φ^τ and I(τ) = −½ ln(1 − φ^{2τ}) nats. The plug-in estimate's
  // bias, about (B−1)²/(2N) = 0.003 nats here, stays within 0.03 nats; at τ = 1 (0.83 nats) the 16 bins
  // lose up to 0.06 nats of the finer structure.
  const double phi = 0.9;
  const auto e = noise(40000, 11);
  std::vector<double> x(e.size());
  x[0] = e[0];
  for (std::size_t t = 1; t < x.size(); ++t) x[t] = phi * x[t - 1] + std::sqrt(1 - phi * phi) * e[t];
  ts::MutualInformationOptions o;
  o.max_delay = 12;
  const auto mi = ts::delayed_mutual_information(x, o);
  for (std::size_t tau : {1u, 2u, 3u, 6u, 12u}) {
    const double expected = -0.5 * std::log(1 - std::pow(phi, 2.0 * static_cast<double>(tau)));
    EXPECT_NEAR(mi[tau], expected, tau == 1 ? 0.06 : 0.03) << "tau " << tau;
  }
}

TEST(Embedding, SineDelayIsAQuarterPeriodAndHenonNeedsTwoDimensions) {
  // A noisy sine's mutual information is lowest near a quarter period (25 samples here) but flat around it:
  // the first minimum lands within a quarter of that.
  std::vector<double> sine(4000);
  const auto wobble = noise(sine.size(), 3);
  for (std::size_t t = 0; t < sine.size(); ++t)
    sine[t] = std::sin(2 * std::numbers::pi * static_cast<double>(t) / 100.37) + 0.05 * wobble[t];
  ts::MutualInformationOptions mio;
  mio.max_delay = 50;
  EXPECT_NEAR(static_cast<double>(ts::first_local_minimum(ts::delayed_mutual_information(sine, mio), 2)),
              25.0, 6.25);
  // The Hénon map's x series: one coordinate leaves many false neighbours, two unfold it.
  std::vector<double> henon(1500);
  double hx = 0.1, hy = 0.1;
  for (std::size_t t = 0; t < 1600; ++t) {
    const double nx = 1 - 1.4 * hx * hx + hy;
    hy = 0.3 * hx;
    hx = nx;
    if (t >= 100) henon[t - 100] = hx;
  }
  ts::FalseNeighbourOptions fo;
  fo.max_dim = 4;
  const auto fnn = ts::false_nearest_neighbours(henon, fo);
  EXPECT_GT(fnn[0], 0.3);
  EXPECT_LT(fnn[1], 0.01);
  EXPECT_LT(fnn[2], 0.01);
  EXPECT_EQ(ts::first_local_minimum({3, 2, 2.1, 1, 0.5, 1}, 1), 1u);
  EXPECT_EQ(ts::first_local_minimum({3, 2, 2.1, 1, 0.5, 1}, 2), 4u);
  EXPECT_THROW(ts::false_nearest_neighbours(std::vector<double>(30000, 1.0), fo), tirstrain::Error);
}
