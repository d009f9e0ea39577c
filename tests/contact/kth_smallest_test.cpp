// kth_smallest against std::nth_element: the same value at every k tested, and `values` left a permutation
// of its input, over sizes either side of the bucketing's threshold (64) and value sets that stress the
// buckets (ties, one repeated value, mixed signs, magnitudes 1e-30 to 1e30, infinities).
#include "contact/kth_smallest.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace tirstrain::contact {
namespace {

void expect_matches_nth_element(const std::vector<float>& input, const char* what) {
  std::vector<float> sorted = input;
  std::sort(sorted.begin(), sorted.end());
  const std::size_t n = input.size();
  for (const std::size_t k : {std::size_t{0}, n / 20, n / 2, n - 1 - n / 20, n - 1}) {
    std::vector<float> values = input;
    const float kth = kth_smallest(values, k);
    EXPECT_EQ(kth, sorted[k]) << what << ", n " << n << ", k " << k;
    std::sort(values.begin(), values.end());
    EXPECT_EQ(values, sorted) << what << ", n " << n << ": not a permutation of the input";
  }
}

TEST(KthSmallest, AgreesWithNthElement) {
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::uniform_int_distribution<int> small_integer(-3, 3);
  std::uniform_real_distribution<float> exponent(-30.0f, 30.0f);
  for (const std::size_t n : {1u, 2u, 63u, 64u, 65u, 200u, 1000u, 5000u}) {
    std::vector<float> level(n), ties(n), mixed(n), magnitudes(n), constant(n, 0.25f), with_infinities(n);
    for (std::size_t i = 0; i < n; ++i) {
      level[i] = 0.6f + 0.01f * noise(rng);  // a sector's background: noise about a level
      ties[i] = static_cast<float>(small_integer(rng));
      mixed[i] = noise(rng);
      magnitudes[i] = (i % 2 == 0 ? 1.0f : -1.0f) * std::pow(10.0f, exponent(rng));
      with_infinities[i] = i % 7 == 0   ? std::numeric_limits<float>::infinity()
                           : i % 7 == 1 ? -std::numeric_limits<float>::infinity()
                                        : noise(rng);
    }
    expect_matches_nth_element(level, "noise about a level");
    expect_matches_nth_element(ties, "seven distinct values");
    expect_matches_nth_element(mixed, "mixed signs");
    expect_matches_nth_element(magnitudes, "magnitudes 1e-30 to 1e30");
    expect_matches_nth_element(constant, "one value");
    expect_matches_nth_element(with_infinities, "infinities");
  }
}

}  // namespace
}  // namespace tirstrain::contact
