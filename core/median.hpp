#pragma once
// The median of a sample: one definition for every module, so that "median" means the same everywhere.
#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

namespace tirstrain {

// Median of `values`, the mean of the two middle values when their count is even; NaN when empty.
// Reorders `values` (nth_element: linear time, no copy).
inline double median_in_place(std::vector<double>& values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  if (values.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(values.begin(), mid));
}

// The same on a copy, leaving the caller's sample as it was.
inline double median(std::vector<double> values) {
  return median_in_place(values);
}

// The sample's (n/2)-th smallest value: the median of an odd count, the upper of the two middle values of an
// even one. For large samples (a row of pixels, the noise of a whole image) whose two middle values are as
// good as each other; skips the second pass. NaN when empty. Reorders `values`.
template <typename T>
T upper_median_in_place(std::vector<T>& values) {
  if (values.empty()) return std::numeric_limits<T>::quiet_NaN();
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace tirstrain
