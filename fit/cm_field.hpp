#pragma once
// The Cattaneo–Mindlin surface displacement written for Ceres' automatic differentiation: the same closed
// forms as model/cattaneo_mindlin.cpp (docs/model.md), in pixels and in the fit's parameters rather than
// in P, R, μ. Templated on the scalar so Jets flow through; tests/fit checks it against model/.
//
// With W(ρ, θ) the shape of the building block U[q0, a] = (q0 a / 4G) W(r/a) and s = μp0/G (dimensionless):
//   partial slip  u = (s a / 4) [W(r/a) − k² W(r/(k a))],  k = c/a
//   full stick    u = (A a / 4) [2 W − ρ ∂W/∂ρ](r/a),      the Q → 0 limit (Mindlin's no-slip traction)
// Loads: μP = (2π/3) G s a², Q = μP (1 − k³); full stick Q = 2π G a² A.
#include <cmath>
#include <numbers>

namespace tirstrain::fit {

// Which field a frame is fitted with. The values are stored in fit.h5 (/fit/model).
enum class FieldModel : int { rest = 0, full_stick = 1, partial_slip = 2, full_slip = 3 };
inline constexpr int kFieldModels = 4;

inline const char* field_model_name(FieldModel m) {
  switch (m) {
    case FieldModel::rest:
      return "rest";
    case FieldModel::full_stick:
      return "full_stick";
    case FieldModel::partial_slip:
      return "partial_slip";
    case FieldModel::full_slip:
      return "full_slip";
  }
  return "unknown";
}

namespace detail {

using std::asin;
using std::sqrt;

// W(ξ) for a unit block of radius 1 at the point (x, y) = ξ in the loading frame: (wx, wy).
template <typename T>
void block_shape(const T& x, const T& y, double nu, T& wx, T& wy) {
  const T r2 = x * x + y * y;
  const double pi = std::numbers::pi;
  if (r2 <= T(1.0)) {
    // Johnson's inner polynomial, Cartesian so that r = 0 needs no angle.
    wx = (pi / 8.0) * (4.0 * (2.0 - nu) - (4.0 - 3.0 * nu) * x * x - (4.0 - nu) * y * y);
    wy = (pi / 4.0) * nu * x * y;
    return;
  }
  const T rho = sqrt(r2);
  const T inv_rho = T(1.0) / rho;
  const T root = sqrt((rho - 1.0) * (rho + 1.0));
  const T as = asin(inv_rho);
  const T phi = (2.0 - r2) * as + root;
  const T d = -r2 * as + root * (1.0 - 2.0 / r2);
  const T c2 = (x * x - y * y) / r2;
  const T s2 = 2.0 * x * y / r2;
  wx = (1.0 - 0.5 * nu) * phi - 0.25 * nu * d * c2;
  wy = -0.25 * nu * d * s2;
}

// [2W − ρ ∂W/∂ρ](ξ): the full-stick shape (traction q_s (1 − r²/a²)^(−1/2)), times 4.
template <typename T>
void stick_shape(const T& x, const T& y, double nu, T& wx, T& wy) {
  const T r2 = x * x + y * y;
  const double pi = std::numbers::pi;
  if (r2 <= T(1.0)) {
    // The quadratic terms cancel: a uniform shift, π (2 − ν) · (a/4) per unit A.
    wx = T(pi * (2.0 - nu));
    wy = T(0.0);
    return;
  }
  const T rho = sqrt(r2);
  const T root = sqrt((rho - 1.0) * (rho + 1.0));
  const T tail = root / r2;  // sqrt(ρ² − 1)/ρ²
  const T c2 = (x * x - y * y) / r2;
  const T s2 = 2.0 * x * y / r2;
  wx = (4.0 - 2.0 * nu) * asin(T(1.0) / rho) + 2.0 * nu * tail * c2;
  wy = 2.0 * nu * tail * s2;
}

}  // namespace detail

// Displacement (px) in the loading frame at the point (x, y) px from the contact centre, for contact radius
// a_px, stick ratio k = c/a in [0, 1] and strain scale s = μp0/G. k = 1 gives zero.
template <typename T>
void partial_slip_px(const T& x, const T& y, const T& a_px, const T& k, const T& s, double nu, T& ux, T& uy) {
  T wx, wy;
  detail::block_shape(T(x / a_px), T(y / a_px), nu, wx, wy);
  if (k > T(1e-9)) {
    T vx, vy;
    const T c_px = k * a_px;
    detail::block_shape(T(x / c_px), T(y / c_px), nu, vx, vy);
    wx -= k * k * vx;
    wy -= k * k * vy;
  }
  const T scale = 0.25 * s * a_px;
  ux = scale * wx;
  uy = scale * wy;
}

// Full stick: displacement (px) for the no-slip amplitude A = q_s/G (Q = 2π G a² A).
template <typename T>
void full_stick_px(const T& x, const T& y, const T& a_px, const T& amplitude, double nu, T& ux, T& uy) {
  T wx, wy;
  detail::stick_shape(T(x / a_px), T(y / a_px), nu, wx, wy);
  const T scale = 0.25 * amplitude * a_px;
  ux = scale * wx;
  uy = scale * wy;
}

}  // namespace tirstrain::fit
