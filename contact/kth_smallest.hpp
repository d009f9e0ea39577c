#pragma once
// The k-th smallest of a set of floats (what std::nth_element places at k), for the per-sector quantiles of
// the ridge labels (contact/ridge_labels.cpp).
#include <cstddef>
#include <vector>

namespace tirstrain::contact {

// The value std::nth_element would place at index k (0 <= k < values.size()); reorders `values` (a
// permutation: no value is lost). The values must not be NaN.
float kth_smallest(std::vector<float>& values, std::size_t k);

}  // namespace tirstrain::contact
