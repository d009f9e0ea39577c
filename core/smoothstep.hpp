#pragma once
// The quintic smoothstep shared by the synthetic renderer (samples/) and the border band's model (contact/),
// so the contact model fits exactly the fade the trials are drawn with.
#include <algorithm>

namespace tirstrain {

// 0 at t <= 0, 1 at t >= 1, with zero first and second derivatives at both ends.
inline double smoothstep5(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

// The same, element by element, for an Eigen array (a vector register at a time).
template <typename Array>
auto smoothstep5_array(const Array& t) {
  const auto c = t.max(0.0).min(1.0).eval();
  return (c * c * c * (c * (6.0 * c - 15.0) + 10.0)).eval();
}

}  // namespace tirstrain
