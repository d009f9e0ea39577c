#pragma once
// A smooth analytic ridge texture for the subset and mesh correlation tests: evaluated exactly at any
// (warped) position, so a rendered frame carries no interpolation error.
#include <cmath>
#include <numbers>

namespace tirstrain::flow::testing {

// Curved ridges of period ≈ 23 px around a near core plus a weaker ridge system around another core, so
// that every subset is well posed in both directions (a single system of nearly straight ridges leaves the
// motion along the ridges to the faint curvature: the aperture problem, tested in the tracker tests).
inline double ridge_texture(double x, double y) {
  const double r1 = std::hypot(x + 40.0, y + 30.0), r2 = std::hypot(x - 150.0, y + 60.0);
  return 0.5 + 0.25 * std::cos(2.0 * std::numbers::pi * r1 / 23.0) +
         0.12 * std::cos(2.0 * std::numbers::pi * r2 / 17.0);
}

}  // namespace tirstrain::flow::testing
