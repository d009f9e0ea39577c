#pragma once
// Small 2-D continuum-mechanics types and closed forms shared by model/ (analytic fields) and strain/
// (measured fields), so both compute strain, principal values and energy with the same formulas.
#include <cmath>

namespace tirstrain {

struct Vec2 {
  double x = 0.0;
  double y = 0.0;
};

// Displacement gradient H_ij = du_i/dX_j (Lagrangian); F = I + H.
struct Gradient2 {
  double xx = 0.0, xy = 0.0, yx = 0.0, yy = 0.0;
};

// Symmetric 2-D strain (tensor shear component, not engineering shear).
struct Strain2 {
  double xx = 0.0, yy = 0.0, xy = 0.0;
};

// Principal strains e1 >= e2 and the angle of e1 from +x (image x right, y down), in (-pi/2, pi/2].
struct Principal2 {
  double e1 = 0.0, e2 = 0.0, angle_rad = 0.0;
};

// Green–Lagrange E = ½(FᵀF − I) with F = I + H.
inline Strain2 green_lagrange(const Gradient2& h) {
  return {h.xx + 0.5 * (h.xx * h.xx + h.yx * h.yx), h.yy + 0.5 * (h.xy * h.xy + h.yy * h.yy),
          0.5 * (h.xy + h.yx) + 0.5 * (h.xx * h.xy + h.yx * h.yy)};
}

// The components of a symmetric tensor (a strain, or a position covariance) in axes turned by `angle_rad`
// from the image's (x' along (cos, sin)): Rᵀ E R.
inline Strain2 in_axes(const Strain2& e, double angle_rad) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return {c * c * e.xx + 2.0 * c * s * e.xy + s * s * e.yy, s * s * e.xx - 2.0 * c * s * e.xy + c * c * e.yy,
          c * s * (e.yy - e.xx) + (c * c - s * s) * e.xy};
}

// Small-strain (infinitesimal) tensor ½(H + Hᵀ).
inline Strain2 infinitesimal_strain(const Gradient2& h) {
  return {h.xx, h.yy, 0.5 * (h.xy + h.yx)};
}

// Infinitesimal rotation ω = ½(∂v/∂X − ∂u/∂Y), radians, positive from +x towards +y.
inline double infinitesimal_rotation_rad(const Gradient2& h) {
  return 0.5 * (h.yx - h.xy);
}

// Closed-form eigen decomposition of a symmetric 2×2 tensor; the radius uses hypot, which neither
// overflows nor loses the small difference of nearly equal principal values.
inline Principal2 principal_strains(const Strain2& e) {
  const double mean = 0.5 * (e.xx + e.yy);
  const double half_diff = 0.5 * (e.xx - e.yy);
  const double radius = std::hypot(half_diff, e.xy);
  double angle = 0.5 * std::atan2(2.0 * e.xy, e.xx - e.yy);
  return {mean + radius, mean - radius, angle};
}

// Lamé's first parameter λ = Eν/((1+ν)(1−2ν)) and shear modulus G = E/(2(1+ν)).
inline double lame_lambda_Pa(double young_Pa, double poisson) {
  return young_Pa * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
}
inline double shear_modulus_Pa(double young_Pa, double poisson) {
  return young_Pa / (2.0 * (1.0 + poisson));
}

// Plane-strain (St Venant–Kirchhoff) energy density W = (λ/2)(E_xx + E_yy)² + G(E_xx² + E_yy² + 2E_xy²),
// J/m³. Algebraically identical to docs/design.md's form in E and ν.
inline double plane_strain_energy_density_J_m3(const Strain2& e, double young_Pa, double poisson) {
  const double lambda = lame_lambda_Pa(young_Pa, poisson);
  const double g = shear_modulus_Pa(young_Pa, poisson);
  const double trace = e.xx + e.yy;
  return 0.5 * lambda * trace * trace + g * (e.xx * e.xx + e.yy * e.yy + 2.0 * e.xy * e.xy);
}

}  // namespace tirstrain
