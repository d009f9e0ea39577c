// Axial circular statistics against closed forms: the wrapped normal's resultant length e^{−σ²/2} and zero
// kurtosis, a uniform sample's near-zero resultant, Kuiper's V by hand, and the calibration of its p-value
// under the null hypothesis.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/circular_statistics.hpp"
#include "core/error.hpp"
#include "core/rose_plot.hpp"

namespace tirstrain {
namespace {

constexpr double kPi = std::numbers::pi;

// Axial angles whose doubled angle is wrapped normal about 2·mean with standard deviation sigma (radians).
std::vector<double> wrapped_normal_axes(std::size_t n, double mean_rad, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<double> out(n);
  for (double& a : out) a = 0.5 * (2.0 * mean_rad + g(rng));
  return out;
}

TEST(CircularStatistics, WrappedNormalMatchesItsClosedForms) {
  const double sigma = 0.8;                                                  // of the doubled angle
  const auto s = axial_summary(wrapped_normal_axes(200000, 2.9, sigma, 1));  // mean near π: wraps
  EXPECT_NEAR(s.resultant_length, std::exp(-0.5 * sigma * sigma), 0.003);
  EXPECT_NEAR(s.circular_variance, 1.0 - std::exp(-0.5 * sigma * sigma), 0.003);
  EXPECT_NEAR(s.mean_direction_rad, 2.9, 0.005);
  EXPECT_NEAR(s.kurtosis, 0.0, 0.02);
  // θ and θ + π are one axis: shifting half the sample by π changes nothing.
  auto shifted = wrapped_normal_axes(1000, 0.3, 0.2, 2);
  const auto before = axial_summary(shifted);
  for (std::size_t i = 0; i < shifted.size(); i += 2) shifted[i] += kPi;
  const auto after = axial_summary(shifted);
  EXPECT_NEAR(after.mean_direction_rad, before.mean_direction_rad, 1e-12);
  EXPECT_NEAR(after.resultant_length, before.resultant_length, 1e-12);
}

TEST(CircularStatistics, UniformAxesHaveNoMeanDirection) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, kPi);
  std::vector<double> a(40000);
  for (double& v : a) v = u(rng);
  const auto s = axial_summary(a);
  EXPECT_LT(s.resultant_length, 3.0 / std::sqrt(40000.0));
  EXPECT_THROW(axial_summary({}), Error);
  EXPECT_THROW(axial_summary({0.1, std::nan("")}), Error);
}

TEST(CircularStatistics, KuiperStatisticByHandAndItsPValueUnderTheNull) {
  // Disjoint samples: one distribution function reaches 1 before the other leaves 0, V = 1.
  EXPECT_DOUBLE_EQ(kuiper_two_sample_axial({0.1, 0.2}, {1.0, 1.1}).statistic, 1.0);
  // Interleaved a b a b on the circle: the difference swings between 1/2 and 0, V = 1/2.
  EXPECT_DOUBLE_EQ(kuiper_two_sample_axial({0.1, 1.0}, {0.5, 1.5}).statistic, 0.5);
  // Under the null the p-value is about uniform: about 5 % of tests fall below 0.05.
  int below = 0;
  const int tests = 400;
  for (int t = 0; t < tests; ++t) {
    const auto a = wrapped_normal_axes(150, 1.0, 1.2, 100 + t),
               b = wrapped_normal_axes(120, 1.0, 1.2, 9000 + t);
    below += kuiper_two_sample_axial(a, b).p_value < 0.05;
  }
  EXPECT_GT(below, tests * 0.02);
  EXPECT_LT(below, tests * 0.09);
  // A 20 deg shift between 300-sample groups of spread 0.5 rad is found.
  const auto shifted = kuiper_two_sample_axial(wrapped_normal_axes(300, 1.0, 0.5, 7),
                                               wrapped_normal_axes(300, 1.0 + 20 * kPi / 180, 0.5, 8));
  EXPECT_LT(shifted.p_value, 1e-4);
}

TEST(CircularStatistics, HistogramAndRoseDiagram) {
  const auto counts = axial_histogram({0.01, 0.02, kPi / 2 + 0.01, kPi - 0.01, -0.01}, 4);
  ASSERT_EQ(counts.size(), 4u);
  EXPECT_EQ(counts[0], 2u);
  EXPECT_EQ(counts[2], 1u);
  EXPECT_EQ(counts[3], 2u);  // π − 0.01 and −0.01 are the same axis
  const cv::Mat img = render_rose({{"a", counts, 0.0}}, {.title = "t", .radius_px = 100});
  EXPECT_GT(img.rows, 200);
  EXPECT_LT(cv::mean(img)[0], 254.0);  // something is drawn
}

}  // namespace
}  // namespace tirstrain
