#pragma once
// Hertz + Cattaneo–Mindlin partial-slip contact of an elastic sphere on a rigid flat: closed-form surface
// displacement, displacement gradient, Green–Lagrange strain and plane-strain energy density.
// Formulas: docs/model.md (Johnson 1985 §3.4, §3.6, §7.2; Hamilton & Goodman 1966).
// Allocation-free: every evaluation is a handful of flops on the stack.
#include <stdexcept>
#include <string>
#include <utility>

#include "core/tensor2.hpp"

namespace tirstrain::model {

// Thrown for inputs outside the model; parameter() names the offending field of CattaneoMindlinParams
// (e.g. "tangential_N") so a caller can map it to its own option or key name.
class InvalidParameter : public std::invalid_argument {
 public:
  InvalidParameter(std::string parameter, const std::string& message)
      : std::invalid_argument(message), parameter_(std::move(parameter)) {}
  const std::string& parameter() const noexcept { return parameter_; }

 private:
  std::string parameter_;
};

struct CattaneoMindlinParams {
  double normal_N = 1.0;       // P > 0
  double tangential_N = 0.0;   // 0 <= Q <= friction * P
  double radius_m = 0.01;      // R > 0
  double young_Pa = 1.0e6;     // E > 0
  double poisson = 0.4;        // -1 < nu < 0.5 (0.5 excluded: the energy density's lambda diverges)
  double friction = 1.0;       // mu > 0
  double direction_rad = 0.0;  // direction of the tangential traction on the skin, from +x towards +y
  bool hertz_radial = false;   // add the Hertz normal-pressure radial displacement (reference before loading)
};

struct HertzContact {
  double contact_radius_m = 0.0;      // a
  double peak_pressure_Pa = 0.0;      // p0
  double approach_m = 0.0;            // delta = a^2 / R
  double effective_modulus_Pa = 0.0;  // E* = E / (1 - nu^2) against a rigid flat
};

// One evaluation of the surface field at a point (metres, contact centre at the origin).
struct FieldSample {
  Vec2 displacement_m;
  Gradient2 gradient;    // H_ij = du_i/dx_j, dimensionless
  Strain2 strain;        // Green–Lagrange, from gradient
  Principal2 principal;  // of strain
  double energy_density_J_m3 = 0.0;
};

class CattaneoMindlin {
 public:
  // Validates every parameter; throws InvalidParameter naming the field.
  explicit CattaneoMindlin(const CattaneoMindlinParams& params);

  const CattaneoMindlinParams& params() const noexcept { return params_; }
  const HertzContact& hertz() const noexcept { return hertz_; }
  double stick_radius_m() const noexcept { return stick_radius_m_; }  // c = a (1 - Q/(mu P))^(1/3)
  double rigid_shift_m() const noexcept { return rigid_shift_m_; }    // delta_x (along the loading direction)
  double shear_modulus_Pa() const noexcept;

  // Hertz pressure p(r) and partial-slip tangential traction magnitude q(r) (along the loading direction).
  double pressure_Pa(double r_m) const noexcept;
  double traction_Pa(double r_m) const noexcept;

  // Surface field at a point in the scene frame (contact centre at the origin). Finite for every finite
  // point, including r = 0, r = c, r = a and the far field; a NaN coordinate gives NaN.
  Vec2 displacement_m(double x_m, double y_m) const noexcept;
  Gradient2 gradient(double x_m, double y_m) const noexcept;
  FieldSample evaluate(double x_m, double y_m) const noexcept;

 private:
  template <bool kWithGradient>
  void field(double x_m, double y_m, Vec2& u, Gradient2& h) const noexcept;

  CattaneoMindlinParams params_;
  HertzContact hertz_;
  double stick_radius_m_ = 0.0;
  double rigid_shift_m_ = 0.0;
  // Derived once so an evaluation is a few flops: G, c/a, the coefficients of the two traction blocks
  // (inner polynomial of the a-block; outer K and K/radius of the a- and c-blocks), the loading direction
  // and the Hertz radial term's inner and outer coefficients.
  double g_Pa_ = 0.0;
  double stick_ratio_ = 0.0;
  double inner_k_per_m_ = 0.0;
  double outer_k_a_m_ = 0.0;
  double outer_kgrad_a_ = 0.0;
  double outer_k_c_m_ = 0.0;
  double outer_kgrad_c_ = 0.0;
  double cos_dir_ = 1.0;
  double sin_dir_ = 0.0;
  double radial_coeff_ = 0.0;
  double radial_far_m2_ = 0.0;
};

// Hertz quantities alone (validates radius, modulus, Poisson ratio and load like the full model).
HertzContact hertz_contact(double normal_N, double radius_m, double young_Pa, double poisson);

}  // namespace tirstrain::model
