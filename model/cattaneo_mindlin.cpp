#include "model/cattaneo_mindlin.hpp"

#include <charconv>
#include <cmath>
#include <numbers>
#include <string>

#include "model/detail/contact_kernels.hpp"

namespace tirstrain::model {
namespace {

// Shortest round-trip form, so that a refused Q = μP·(1 + 1e-16) shows why it was refused.
std::string fmt(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

void require(bool ok, const char* parameter, const std::string& message) {
  if (!ok) throw InvalidParameter(parameter, std::string("Cattaneo–Mindlin model: ") + message);
}

void require_positive(double value, const char* parameter, const char* what, const char* unit) {
  require(std::isfinite(value) && value > 0.0, parameter,
          std::string(what) + " (" + parameter + ") must be finite and > 0, got " + fmt(value) + unit);
}

void validate_hertz_inputs(double normal_N, double radius_m, double young_Pa, double poisson) {
  require_positive(normal_N, "normal_N", "normal load P", " N");
  require_positive(radius_m, "radius_m", "sphere radius R", " m");
  require_positive(young_Pa, "young_Pa", "Young's modulus E", " Pa");
  require(std::isfinite(poisson) && poisson > -1.0 && poisson < 0.5, "poisson",
          "Poisson's ratio nu (poisson) must lie in (-1, 0.5), got " + fmt(poisson));
}

HertzContact hertz_unchecked(double normal_N, double radius_m, double young_Pa, double poisson) {
  HertzContact h;
  h.effective_modulus_Pa = young_Pa / ((1.0 - poisson) * (1.0 + poisson));
  h.contact_radius_m = std::cbrt(3.0 * normal_N * radius_m / (4.0 * h.effective_modulus_Pa));
  h.peak_pressure_Pa = 3.0 * normal_N / (2.0 * std::numbers::pi * h.contact_radius_m * h.contact_radius_m);
  h.approach_m = h.contact_radius_m * h.contact_radius_m / radius_m;
  // Individually valid inputs can still over- or underflow together (P = 1e300 on R = 1e300); refuse them
  // here rather than let inf and 0 turn into NaN in the field.
  const bool finite = std::isfinite(h.effective_modulus_Pa) && std::isfinite(h.contact_radius_m) &&
                      std::isfinite(h.peak_pressure_Pa) && std::isfinite(h.approach_m);
  const bool positive = h.effective_modulus_Pa > 0.0 && h.contact_radius_m > 0.0 &&
                        h.peak_pressure_Pa > 0.0 && h.approach_m > 0.0;
  require(finite && positive, "normal_N",
          "P (normal_N) = " + fmt(normal_N) + " N, R (radius_m) = " + fmt(radius_m) +
              " m, E (young_Pa) = " + fmt(young_Pa) +
              " Pa give a Hertz contact outside floating-point range (a = " + fmt(h.contact_radius_m) +
              " m, p0 = " + fmt(h.peak_pressure_Pa) + " Pa)");
  return h;
}

// Displacement and gradient of one field contribution, in whatever frame the caller works in.
struct Field {
  Vec2 u;
  Gradient2 h;
};

// U[q0, a] inside its circle: Johnson's polynomial, with k = π q0 / (32 G a) and the point in the
// loading frame. Cartesian, so no angle is needed at r = 0.
void add_inner_block(Field& f, double k, double a_m, double nu, double x, double y) noexcept {
  const double cx = 4.0 - 3.0 * nu;
  const double cy = 4.0 - nu;
  f.u.x += k * (4.0 * (2.0 - nu) * a_m * a_m - cx * x * x - cy * y * y);
  f.u.y += 2.0 * k * nu * x * y;
  f.h.xx += -2.0 * k * cx * x;
  f.h.xy += -2.0 * k * cy * y;
  f.h.yx += 2.0 * k * nu * y;
  f.h.yy += 2.0 * k * nu * x;
}

// sign·U[q0, a] outside its circle, with K = q0 a / (4G), Kg = K / a, rho = r / a >= 1 and (cs, sn) the
// direction of the point in the loading frame.
void add_outer_block(Field& f, double sign, double k_m, double k_grad, double nu, double rho, double cs,
                     double sn) noexcept {
  const detail::OuterShape s = detail::outer_shape(rho);
  const double sym = 1.0 - 0.5 * nu;  // (1 − ν/2)
  const double anti = 0.25 * nu;      // ν/4
  const double c2 = (cs - sn) * (cs + sn);
  const double s2 = 2.0 * cs * sn;
  const double k = sign * k_m;
  const double kg = sign * k_grad;
  f.u.x += k * (sym * s.phi - anti * s.d * c2);
  f.u.y += -k * anti * s.d * s2;
  const double two_d_r = 2.0 * s.d_over_rho;  // 2d·a/r
  f.h.xx += kg * (sym * s.dphi * cs - anti * (s.dd * c2 * cs + two_d_r * s2 * sn));
  f.h.xy += kg * (sym * s.dphi * sn - anti * (s.dd * c2 * sn - two_d_r * s2 * cs));
  f.h.yx += -kg * anti * (s.dd * s2 * cs - two_d_r * c2 * sn);
  f.h.yy += -kg * anti * (s.dd * s2 * sn + two_d_r * c2 * cs);
}

}  // namespace

HertzContact hertz_contact(double normal_N, double radius_m, double young_Pa, double poisson) {
  validate_hertz_inputs(normal_N, radius_m, young_Pa, poisson);
  return hertz_unchecked(normal_N, radius_m, young_Pa, poisson);
}

CattaneoMindlin::CattaneoMindlin(const CattaneoMindlinParams& params) : params_(params) {
  const auto& p = params_;
  validate_hertz_inputs(p.normal_N, p.radius_m, p.young_Pa, p.poisson);
  require_positive(p.friction, "friction", "friction coefficient mu", "");
  require(std::isfinite(p.direction_rad), "direction_rad",
          "loading direction (direction_rad) must be finite, got " + fmt(p.direction_rad) + " rad");
  const double limit_N = p.friction * p.normal_N;
  require(std::isfinite(limit_N), "friction",
          "friction limit mu*P = " + fmt(p.friction) + " * " + fmt(p.normal_N) + " N overflows");
  require(std::isfinite(p.tangential_N) && p.tangential_N >= 0.0, "tangential_N",
          "tangential load Q (tangential_N) must be finite and >= 0, got " + fmt(p.tangential_N) + " N");
  require(p.tangential_N <= limit_N, "tangential_N",
          "tangential load Q (tangential_N) = " + fmt(p.tangential_N) +
              " N exceeds the friction limit mu*P = " + fmt(limit_N) + " N (mu = " + fmt(p.friction) +
              ", P = " + fmt(p.normal_N) +
              " N); Cattaneo–Mindlin covers 0 <= Q <= mu*P only (gross sliding at Q = mu*P)");

  hertz_ = hertz_unchecked(p.normal_N, p.radius_m, p.young_Pa, p.poisson);
  const double a = hertz_.contact_radius_m;
  const double nu = p.poisson;
  g_Pa_ = tirstrain::shear_modulus_Pa(p.young_Pa, nu);

  // Q <= fl(μP) makes the rounded ratio <= 1, so 1 − ratio is never negative.
  const double slip_fraction = p.tangential_N / limit_N;
  stick_ratio_ = std::cbrt(1.0 - slip_fraction);
  stick_radius_m_ = a * stick_ratio_;
  // 1 − (1 − Q/μP)^(2/3) through expm1/log1p: the direct difference loses all digits as Q → 0, and the
  // compliance limit δ_x/Q → (2−ν)/(8Ga) is exactly what the small-Q end is used for.
  const double released = slip_fraction >= 1.0   ? 1.0
                          : slip_fraction <= 0.0 ? 0.0
                                                 : -std::expm1((2.0 / 3.0) * std::log1p(-slip_fraction));
  rigid_shift_m_ = 3.0 * limit_N * (2.0 - nu) / (16.0 * g_Pa_ * a) * released;

  const double q0_Pa = p.friction * hertz_.peak_pressure_Pa;
  inner_k_per_m_ = std::numbers::pi * q0_Pa / (32.0 * g_Pa_ * a);
  outer_k_a_m_ = q0_Pa * a / (4.0 * g_Pa_);
  outer_kgrad_a_ = q0_Pa / (4.0 * g_Pa_);
  outer_k_c_m_ = q0_Pa * stick_ratio_ * stick_radius_m_ / (4.0 * g_Pa_);
  outer_kgrad_c_ = q0_Pa * stick_ratio_ / (4.0 * g_Pa_);
  cos_dir_ = std::cos(p.direction_rad);
  sin_dir_ = std::sin(p.direction_rad);
  radial_coeff_ = (1.0 - 2.0 * nu) * hertz_.peak_pressure_Pa / (6.0 * g_Pa_);
  radial_far_m2_ = (1.0 - 2.0 * nu) * p.normal_N / (4.0 * std::numbers::pi * g_Pa_);
  // The strain scale μp0/G and displacement scale μp0·a/G bound every field value. A finite Hertz contact
  // keeps p0/G below ~1e170 (p0/E* ~ a/R with a² and R representable), so only a huge μ can push them out
  // of double range: refuse that here instead of returning inf or NaN later.
  const double strain_scale = q0_Pa / g_Pa_;
  const double displacement_scale_m = strain_scale * a;
  require(std::isfinite(strain_scale) && std::isfinite(displacement_scale_m) && std::isfinite(rigid_shift_m_),
          "friction",
          "friction coefficient mu (friction) = " + fmt(p.friction) + " with P = " + fmt(p.normal_N) +
              " N, E = " + fmt(p.young_Pa) + " Pa gives a strain scale mu*p0/G = " + fmt(strain_scale) +
              " outside floating-point range");
}

double CattaneoMindlin::pressure_Pa(double r_m) const noexcept {
  const double rho = std::abs(r_m) / hertz_.contact_radius_m;
  if (!(rho < 1.0)) return rho >= 1.0 ? 0.0 : rho;  // NaN stays NaN
  return hertz_.peak_pressure_Pa * std::sqrt((1.0 - rho) * (1.0 + rho));
}

double CattaneoMindlin::traction_Pa(double r_m) const noexcept {
  const double r = std::abs(r_m);
  double q = params_.friction * pressure_Pa(r);
  if (r < stick_radius_m_) {
    const double rho_c = r / stick_radius_m_;
    q -= params_.friction * hertz_.peak_pressure_Pa * stick_ratio_ * std::sqrt((1.0 - rho_c) * (1.0 + rho_c));
  }
  return q;
}

template <bool kWithGradient>
void CattaneoMindlin::field(double x_m, double y_m, Vec2& u, Gradient2& h) const noexcept {
  const double a = hertz_.contact_radius_m;
  const double c = stick_radius_m_;
  const double nu = params_.poisson;
  // glibc's hypot costs as much as the rest of the tangential field; the plain root is as accurate (1 ulp)
  // wherever x² + y² neither overflows nor underflows, so hypot is kept for the extremes only.
  const double r2 = x_m * x_m + y_m * y_m;
  const double r = r2 > 1e-290 && r2 < 1e290 ? std::sqrt(r2) : std::hypot(x_m, y_m);

  // Tangential part in the loading frame, where the traction is along +x'.
  const double xl = cos_dir_ * x_m + sin_dir_ * y_m;
  const double yl = -sin_dir_ * x_m + cos_dir_ * y_m;
  Field t;
  if (r <= c) {
    // The quadratic terms of the two inner polynomials cancel identically; return the exact result rather
    // than a difference of rounded numbers.
    t.u.x = rigid_shift_m_;
  } else {
    const double inv_r = 1.0 / r;
    const double cs = xl * inv_r;
    const double sn = yl * inv_r;
    if (r <= a) {
      add_inner_block(t, inner_k_per_m_, a, nu, xl, yl);
    } else {
      add_outer_block(t, 1.0, outer_k_a_m_, outer_kgrad_a_, nu, r / a, cs, sn);
    }
    if (c > 0.0) add_outer_block(t, -1.0, outer_k_c_m_, outer_kgrad_c_, nu, r / c, cs, sn);
  }

  // Back to the scene frame: u = R u', H = R H' Rᵀ.
  const double co = cos_dir_;
  const double si = sin_dir_;
  u.x = co * t.u.x - si * t.u.y;
  u.y = si * t.u.x + co * t.u.y;
  if constexpr (kWithGradient) {
    // R H'
    const double m_xx = co * t.h.xx - si * t.h.yx;
    const double m_xy = co * t.h.xy - si * t.h.yy;
    const double m_yx = si * t.h.xx + co * t.h.yx;
    const double m_yy = si * t.h.xy + co * t.h.yy;
    // (R H') Rᵀ
    h.xx = m_xx * co - m_xy * si;
    h.xy = m_xx * si + m_xy * co;
    h.yx = m_yx * co - m_yy * si;
    h.yy = m_yx * si + m_yy * co;
  }

  if (params_.hertz_radial) {
    const detail::RadialTerm rt = detail::hertz_radial_term(r, a, radial_coeff_, radial_far_m2_);
    // The direction is arbitrary at r = 0, where the anisotropic part vanishes.
    const double nx = r > 0.0 ? x_m / r : 1.0;
    const double ny = r > 0.0 ? y_m / r : 0.0;
    u.x += rt.ur_over_r * x_m;
    u.y += rt.ur_over_r * y_m;
    if constexpr (kWithGradient) {
      h.xx += rt.ur_over_r + rt.aniso * nx * nx;
      h.xy += rt.aniso * nx * ny;
      h.yx += rt.aniso * nx * ny;
      h.yy += rt.ur_over_r + rt.aniso * ny * ny;
    }
  }
}

double CattaneoMindlin::shear_modulus_Pa() const noexcept {
  return g_Pa_;
}

Vec2 CattaneoMindlin::displacement_m(double x_m, double y_m) const noexcept {
  Vec2 u;
  Gradient2 h;
  field<false>(x_m, y_m, u, h);
  return u;
}

Gradient2 CattaneoMindlin::gradient(double x_m, double y_m) const noexcept {
  Vec2 u;
  Gradient2 h;
  field<true>(x_m, y_m, u, h);
  return h;
}

FieldSample CattaneoMindlin::evaluate(double x_m, double y_m) const noexcept {
  FieldSample s;
  field<true>(x_m, y_m, s.displacement_m, s.gradient);
  s.strain = green_lagrange(s.gradient);
  s.principal = principal_strains(s.strain);
  s.energy_density_J_m3 = plane_strain_energy_density_J_m3(s.strain, params_.young_Pa, params_.poisson);
  return s;
}

}  // namespace tirstrain::model
