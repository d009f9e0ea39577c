#include "strain/uncertainty.hpp"

#include <cmath>
#include <limits>

#include "strain/deformation.hpp"

namespace tirstrain::strain {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ∂N_v/∂X of the three linear shape functions (rows of [X1−X0, X2−X0]⁻¹; N0 = 1 − N1 − N2).
bool shape_gradients(const std::array<Vec2, 3>& X, std::array<Vec2, 3>& b) {
  const double a = X[1].x - X[0].x, c = X[2].x - X[0].x;  // D = [[a, c], [d, e]] (columns X1−X0, X2−X0)
  const double d = X[1].y - X[0].y, e = X[2].y - X[0].y;
  const double det = a * e - c * d;
  if (!(std::abs(det) > 0.0)) return false;
  b[1] = {e / det, -c / det};  // first row of D⁻¹
  b[2] = {-d / det, a / det};  // second row
  b[0] = {-b[1].x - b[2].x, -b[1].y - b[2].y};
  return true;
}

}  // namespace

Strain2 strain_standard_deviation(const std::array<Vec2, 3>& reference_px,
                                  const std::array<Vec2, 3>& current_px,
                                  const std::array<PositionCovariance, 3>& covariance_px2) {
  std::array<Vec2, 3> b;
  if (!shape_gradients(reference_px, b)) return {kNaN, kNaN, kNaN};
  const Gradient2 h = displacement_gradient(reference_px, current_px);
  // F = I + H; column j of F is ∂x/∂X_j.
  const double F[2][2] = {{1.0 + h.xx, h.xy}, {h.yx, 1.0 + h.yy}};
  double var[3] = {0.0, 0.0, 0.0};
  for (std::size_t v = 0; v < 3; ++v) {
    const PositionCovariance& c = covariance_px2[v];
    if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) return {kNaN, kNaN, kNaN};
    const double bv[2] = {b[v].x, b[v].y};
    // ∂E_ab/∂x_v,k = ½(b_a F_kb + F_ka b_b), for k = x, y.
    double J[3][2];
    for (int k = 0; k < 2; ++k) {
      J[0][k] = bv[0] * F[k][0];
      J[1][k] = bv[1] * F[k][1];
      J[2][k] = 0.5 * (bv[0] * F[k][1] + F[k][0] * bv[1]);
    }
    for (int q = 0; q < 3; ++q)
      var[q] += J[q][0] * J[q][0] * c[0] + 2.0 * J[q][0] * J[q][1] * c[1] + J[q][1] * J[q][1] * c[2];
  }
  return {std::sqrt(var[0]), std::sqrt(var[1]), std::sqrt(var[2])};
}

}  // namespace tirstrain::strain
