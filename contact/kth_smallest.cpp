#include "contact/kth_smallest.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>

namespace tirstrain::contact {
namespace {

// A float's bits as an unsigned key in the same order (negative floats' bits reversed).
std::uint32_t order_key(float value) {
  const auto bits = std::bit_cast<std::uint32_t>(value);
  return bits ^ (static_cast<std::uint32_t>(static_cast<std::int32_t>(bits) >> 31) | 0x80000000u);
}

}  // namespace

// Found mostly by bucketing: the ridge labels' sectors hold noise about a level, so nth_element's
// comparisons are coin flips for the branch predictor, and it took ~5 % of segment()'s time (perf) for ~1 %
// of its instructions. Each pass counts the values per bucket of their key range (independent of each
// other's outcomes) and keeps only the bucket holding the k-th; the last few go to nth_element.
float kth_smallest(std::vector<float>& values, std::size_t k) {
  constexpr std::size_t kMinBucketed = 64;
  std::size_t n = values.size();
  float* v = values.data();
  std::array<std::uint32_t, 2048> counts;
  while (n >= kMinBucketed) {
    std::uint32_t low = order_key(v[0]), high = low;
    for (std::size_t i = 1; i < n; ++i) {
      const std::uint32_t key = order_key(v[i]);
      low = std::min(low, key);
      high = std::max(high, key);
    }
    if (low == high) return v[k];
    // About n/4 buckets: most then hold a few values.
    const int bucket_bits = std::clamp(static_cast<int>(std::bit_width(n)) - 2, 6, 11);
    const int shift = std::max(0, static_cast<int>(std::bit_width(high - low)) - bucket_bits);
    const std::size_t buckets = ((high - low) >> shift) + 1;
    std::fill_n(counts.begin(), buckets, 0u);
    for (std::size_t i = 0; i < n; ++i) ++counts[(order_key(v[i]) - low) >> shift];
    std::size_t bucket = 0, before = 0;
    while (before + counts[bucket] <= k) before += counts[bucket++];
    // The bucket's values to the front, swapped rather than overwritten (a permutation: callers reuse them).
    std::size_t kept = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const float value = v[i];
      v[i] = v[kept];
      v[kept] = value;
      kept += ((order_key(value) - low) >> shift) == bucket ? 1 : 0;
    }
    k -= before;
    n = kept;
  }
  std::nth_element(v, v + k, v + n);
  return v[k];
}

}  // namespace tirstrain::contact
