// Closed-form checks of the Hertz + Cattaneo–Mindlin model: the list at the end of docs/model.md, the
// numerically delicate spots it names, and the refusal of inputs outside the model.
#include "model/cattaneo_mindlin.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "model/detail/contact_kernels.hpp"
#include "tests/model/adaptive_quadrature.hpp"

namespace tirstrain::model {
namespace {

using quadrature::integrate;
constexpr double kPi = std::numbers::pi;

// A fingertip-like contact: 1 N on a 10 mm sphere of 1 MPa skin, half-way to gross sliding (c ≈ 0.79a).
CattaneoMindlinParams base_params() {
  CattaneoMindlinParams p;
  p.normal_N = 1.0;
  p.tangential_N = 0.5;
  p.radius_m = 0.01;
  p.young_Pa = 1.0e6;
  p.poisson = 0.4;
  p.friction = 1.0;
  return p;
}

double norm(const Vec2& v) {
  return std::hypot(v.x, v.y);
}
double norm(const Gradient2& h) {
  return std::sqrt(h.xx * h.xx + h.xy * h.xy + h.yx * h.yx + h.yy * h.yy);
}
Vec2 diff(const Vec2& a, const Vec2& b) {
  return {a.x - b.x, a.y - b.y};
}
Gradient2 diff(const Gradient2& a, const Gradient2& b) {
  return {a.xx - b.xx, a.xy - b.xy, a.yx - b.yx, a.yy - b.yy};
}

// Natural scales: displacement μp0·a/G, displacement gradient (strain) μp0/G.
double displacement_scale_m(const CattaneoMindlin& m) {
  return m.params().friction * m.hertz().peak_pressure_Pa * m.hertz().contact_radius_m / m.shear_modulus_Pa();
}
double gradient_scale(const CattaneoMindlin& m) {
  return m.params().friction * m.hertz().peak_pressure_Pa / m.shear_modulus_Pa();
}

bool all_finite(const FieldSample& s) {
  const std::array<double, 13> v = {
      s.displacement_m.x, s.displacement_m.y,    s.gradient.xx,        s.gradient.xy, s.gradient.yx,
      s.gradient.yy,      s.strain.xx,           s.strain.yy,          s.strain.xy,   s.principal.e1,
      s.principal.e2,     s.principal.angle_rad, s.energy_density_J_m3};
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

TEST(Hertz, ClosedFormsAndLoadBalance) {
  const auto p = base_params();
  const HertzContact h = hertz_contact(p.normal_N, p.radius_m, p.young_Pa, p.poisson);
  const double e_star = p.young_Pa / (1.0 - p.poisson * p.poisson);
  EXPECT_NEAR(h.effective_modulus_Pa, e_star, 1e-12 * e_star);
  const double a = std::cbrt(3.0 * p.normal_N * p.radius_m / (4.0 * e_star));
  EXPECT_NEAR(h.contact_radius_m, a, 1e-12 * a);
  EXPECT_NEAR(h.peak_pressure_Pa, 3.0 * p.normal_N / (2.0 * kPi * a * a), 1e-12 * h.peak_pressure_Pa);
  EXPECT_NEAR(h.approach_m, a * a / p.radius_m, 1e-12 * h.approach_m);

  // ∫p dA = P, with r = a sin t absorbing the square-root edge.
  const CattaneoMindlin m(p);
  const auto load = integrate(
      [&](double t) {
        const double r = a * std::sin(t);
        return m.pressure_Pa(r) * 2.0 * kPi * r * a * std::cos(t);
      },
      0.0, kPi / 2, 1e-14);
  EXPECT_NEAR(load.value, p.normal_N, 1e-12 * p.normal_N);
  EXPECT_EQ(m.pressure_Pa(a), 0.0);
  EXPECT_EQ(m.pressure_Pa(2.0 * a), 0.0);
  EXPECT_DOUBLE_EQ(m.pressure_Pa(0.0), h.peak_pressure_Pa);

  const HertzContact mh = m.hertz();
  EXPECT_EQ(mh.contact_radius_m, h.contact_radius_m);
  EXPECT_EQ(mh.peak_pressure_Pa, h.peak_pressure_Pa);
  EXPECT_DOUBLE_EQ(m.shear_modulus_Pa(), p.young_Pa / (2.0 * (1.0 + p.poisson)));
}

TEST(CattaneoMindlin, StickRadiusAndRigidShiftForms) {
  for (double ratio : {0.0, 1e-9, 0.1, 0.5, 0.9, 0.999, 1.0}) {
    auto p = base_params();
    p.tangential_N = ratio * p.friction * p.normal_N;
    const CattaneoMindlin m(p);
    const double a = m.hertz().contact_radius_m;
    const double c = a * std::cbrt(1.0 - ratio);
    EXPECT_NEAR(m.stick_radius_m(), c, 1e-14 * a) << ratio;
    // Both printed forms of δ_x: π μ p0 (2−ν)(a² − c²)/(8Ga) and 3μP(2−ν)/(16Ga)·[1 − (1 − Q/μP)^(2/3)].
    const double g = m.shear_modulus_Pa();
    const double via_radii =
        kPi * p.friction * m.hertz().peak_pressure_Pa * (2.0 - p.poisson) * (a * a - c * c) / (8.0 * g * a);
    const double via_load = 3.0 * p.friction * p.normal_N * (2.0 - p.poisson) / (16.0 * g * a) *
                            (1.0 - std::pow(1.0 - ratio, 2.0 / 3.0));
    const double scale = displacement_scale_m(m);
    EXPECT_NEAR(m.rigid_shift_m(), via_radii, 1e-13 * scale) << ratio;
    EXPECT_NEAR(m.rigid_shift_m(), via_load, 1e-13 * scale) << ratio;
  }
}

// Inside r <= c the two quadratic fields cancel: u^T = (δ_x, 0) along the loading direction and ∇u^T = 0.
TEST(CattaneoMindlin, StickZoneIsUniform) {
  for (double dir : {0.0, 0.7, -2.5}) {
    auto p = base_params();
    p.direction_rad = dir;
    const CattaneoMindlin m(p);
    const double c = m.stick_radius_m();
    const double d = m.rigid_shift_m();
    ASSERT_GT(d, 0.0);
    // r = c itself is left to the continuity test: c·(cos φ, sin φ) rounds to either side of c, and just
    // outside the gradient already grows like sqrt(r − c) (1e-8 of its scale one ulp out).
    for (double rho : {0.0, 1e-12, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0 - 1e-12}) {
      for (int k = 0; k < 12; ++k) {
        const double ang = 2.0 * kPi * k / 12.0 + 0.1;
        const double x = rho * c * std::cos(ang);
        const double y = rho * c * std::sin(ang);
        const FieldSample s = m.evaluate(x, y);
        EXPECT_LE(norm(diff(s.displacement_m, {d * std::cos(dir), d * std::sin(dir)})), 1e-12 * d)
            << rho << " " << ang;
        EXPECT_LE(norm(s.gradient), 1e-12 * gradient_scale(m)) << rho << " " << ang;
        EXPECT_LE(std::abs(s.energy_density_J_m3), 1e-20 * p.young_Pa);
      }
    }
  }
}

// ∫q dA = Q over the stick disc (r = c sin t) and the slip annulus (r = a sin t); both substitutions make
// the square-root edges smooth.
TEST(CattaneoMindlin, TractionIntegratesToTangentialLoad) {
  for (double ratio : {1e-6, 0.2, 0.5, 0.8, 0.99, 1.0}) {
    auto p = base_params();
    p.tangential_N = ratio * p.friction * p.normal_N;
    const CattaneoMindlin m(p);
    const double a = m.hertz().contact_radius_m;
    const double c = m.stick_radius_m();
    const auto ring = [&](double radius) {
      return [&m, radius](double t) {
        const double r = radius * std::sin(t);
        return m.traction_Pa(r) * 2.0 * kPi * r * radius * std::cos(t);
      };
    };
    const double stick = c > 0.0 ? integrate(ring(c), 0.0, kPi / 2, 1e-14).value : 0.0;
    const double slip = integrate(ring(a), std::asin(c / a), kPi / 2, 1e-14).value;
    // The two parts are O(μP) each and cancel to Q, so the tolerance carries an absolute μP part.
    EXPECT_NEAR(stick + slip, p.tangential_N, 1e-10 * p.tangential_N + 1e-14 * p.friction * p.normal_N)
        << ratio;
  }
}

TEST(CattaneoMindlin, TractionBoundedByFriction) {
  const auto p = base_params();
  const CattaneoMindlin m(p);
  const double a = m.hertz().contact_radius_m;
  const double c = m.stick_radius_m();
  const double limit_scale = p.friction * m.hertz().peak_pressure_Pa;
  for (int i = 0; i <= 2400; ++i) {
    const double r = 1.2 * a * i / 2400.0;
    const double q = m.traction_Pa(r);
    const double mu_p = p.friction * m.pressure_Pa(r);
    EXPECT_LE(q, mu_p + 1e-14 * limit_scale) << r / a;
    EXPECT_GE(q, 0.0) << r / a;
    if (r > c) {  // slip annulus: q = μp
      EXPECT_NEAR(q, mu_p, 1e-14 * limit_scale) << r / a;
    }
    if (r < 0.999 * c) {  // stick zone: strictly below
      EXPECT_LT(q, mu_p) << r / a;
    }
  }
}

// Mindlin compliance: δ_x/Q → (2 − ν)/(8Ga) as Q → 0; the next term is (Q/μP)/6 relative.
TEST(CattaneoMindlin, SmallLoadComplianceLimit) {
  for (double ratio : {1e-12, 1e-9, 1e-6, 1e-3}) {
    auto p = base_params();
    p.tangential_N = ratio * p.friction * p.normal_N;
    const CattaneoMindlin m(p);
    const double compliance = (2.0 - p.poisson) / (8.0 * m.shear_modulus_Pa() * m.hertz().contact_radius_m);
    const double rel = m.rigid_shift_m() / p.tangential_N / compliance - 1.0;
    EXPECT_NEAR(rel, ratio / 6.0, 1e-12 + ratio * ratio) << ratio;
  }
}

// At Q = μP the stick zone vanishes and the field is the single block U[μp0, a] (Johnson's polynomial).
TEST(CattaneoMindlin, GrossSlidingLimit) {
  auto p = base_params();
  p.tangential_N = p.friction * p.normal_N;
  const CattaneoMindlin m(p);
  EXPECT_EQ(m.stick_radius_m(), 0.0);
  const double a = m.hertz().contact_radius_m;
  const double g = m.shear_modulus_Pa();
  const double q0 = p.friction * m.hertz().peak_pressure_Pa;
  const double nu = p.poisson;
  EXPECT_NEAR(m.rigid_shift_m(), 3.0 * p.tangential_N * (2.0 - nu) / (16.0 * g * a), 1e-14 * a);
  for (double x : {0.0, 0.3, -0.6, 0.95}) {
    for (double y : {0.0, 0.2, -0.25}) {
      const double xm = x * a;
      const double ym = y * a;
      const double k = kPi * q0 / (32.0 * g * a);
      const Vec2 expected{k * (4.0 * (2.0 - nu) * a * a - (4.0 - 3.0 * nu) * xm * xm - (4.0 - nu) * ym * ym),
                          2.0 * k * nu * xm * ym};
      EXPECT_LE(norm(diff(m.displacement_m(xm, ym), expected)), 1e-13 * displacement_scale_m(m)) << x << y;
    }
  }
  // Continuous approach: just below gross sliding c = 1e-4·a, and its block is O((c/a)²) small.
  auto p_near = p;
  p_near.tangential_N = p.tangential_N * (1.0 - 1e-12);
  const CattaneoMindlin near(p_near);
  for (double x : {0.0, 0.5, 1.5}) {
    EXPECT_LE(norm(diff(near.displacement_m(x * a, 0.1 * a), m.displacement_m(x * a, 0.1 * a))),
              1e-7 * displacement_scale_m(m));
  }
}

// u and ∇u are continuous at r = c and r = a. The second derivatives grow like |r − r_edge|^(-1/2), so ∇u
// across a gap of ±ε·r_edge may differ by O(sqrt(ε)); u by O(ε).
TEST(CattaneoMindlin, ContinuousAcrossStickAndContactEdges) {
  for (bool radial : {false, true}) {
    auto p = base_params();
    p.direction_rad = 0.4;
    p.hertz_radial = radial;
    const CattaneoMindlin m(p);
    const double us = displacement_scale_m(m);
    const double gs = gradient_scale(m);
    for (double edge : {m.stick_radius_m(), m.hertz().contact_radius_m}) {
      for (double eps : {1e-8, 1e-12}) {
        for (int k = 0; k < 16; ++k) {
          const double ang = 2.0 * kPi * k / 16.0 + 0.05;
          const auto at = [&](double r) { return m.evaluate(r * std::cos(ang), r * std::sin(ang)); };
          const FieldSample in = at(edge * (1.0 - eps));
          const FieldSample on = at(edge);
          const FieldSample out = at(edge * (1.0 + eps));
          EXPECT_LE(norm(diff(in.displacement_m, out.displacement_m)), 10.0 * eps * us + 1e-14 * us);
          EXPECT_LE(norm(diff(in.displacement_m, on.displacement_m)), 10.0 * eps * us + 1e-14 * us);
          EXPECT_LE(norm(diff(in.gradient, out.gradient)), 10.0 * std::sqrt(eps) * gs) << edge << " " << eps;
          EXPECT_LE(norm(diff(in.gradient, on.gradient)), 10.0 * std::sqrt(eps) * gs) << edge << " " << eps;
        }
      }
    }
  }
}

// Traction along +x: u_x even in x and in y, u_y odd in both; hence H_xx, H_yy odd in x and even in y,
// H_xy, H_yx even in x and odd in y. The Hertz radial term is mirror-symmetric the other way round (u_x odd
// in x), so it is checked on its own.
TEST(CattaneoMindlin, MirrorSymmetry) {
  for (double q : {0.5, 0.0}) {
    auto p = base_params();
    p.tangential_N = q;
    p.hertz_radial = q == 0.0;
    const double odd_x = q == 0.0 ? -1.0 : 1.0;  // tangential: u_x even in x; radial: u_x odd in x
    const CattaneoMindlin m(p);
    const double a = m.hertz().contact_radius_m;
    const double tol_u = 1e-15 * displacement_scale_m(m);
    const double tol_h = 1e-15 * gradient_scale(m);
    for (double x : {0.1, 0.5, 0.85, 0.97, 1.3, 6.0, 1e3}) {
      for (double y : {0.05, 0.4, 0.9, 2.0}) {
        const Vec2 u = m.displacement_m(x * a, y * a);
        const Gradient2 h = m.gradient(x * a, y * a);
        for (double sx : {-1.0, 1.0}) {
          for (double sy : {-1.0, 1.0}) {
            const Vec2 um = m.displacement_m(sx * x * a, sy * y * a);
            const Gradient2 hm = m.gradient(sx * x * a, sy * y * a);
            // For the radial field flip the x-parity of every component: u_x → odd in x, u_y → even in x.
            const double fx = odd_x < 0.0 ? sx : 1.0;
            EXPECT_NEAR(um.x, fx * u.x, tol_u);
            EXPECT_NEAR(um.y, fx * sx * sy * u.y, tol_u);
            EXPECT_NEAR(hm.xx, fx * sx * h.xx, tol_h);
            EXPECT_NEAR(hm.yy, fx * sx * h.yy, tol_h);
            EXPECT_NEAR(hm.xy, fx * sy * h.xy, tol_h);
            EXPECT_NEAR(hm.yx, fx * sy * h.yx, tol_h);
          }
        }
      }
    }
  }
}

// Sign convention: the traction on the skin points along the loading direction (the plate's motion relative
// to the finger). The leading edge is the contact edge that traction points to (+x for direction 0): the
// skin there is pushed against the still-stuck material ahead and is compressed; the trailing edge (−x) is
// stretched.
TEST(CattaneoMindlin, LeadingEdgeCompressedTrailingEdgeStretched) {
  for (double dir : {0.0, kPi / 2, 2.0}) {
    auto p = base_params();
    p.direction_rad = dir;
    const CattaneoMindlin m(p);
    const double a = m.hertz().contact_radius_m;
    const double cd = std::cos(dir);
    const double sd = std::sin(dir);
    for (double rho : {0.85, 0.95, 1.05}) {
      const FieldSample lead = m.evaluate(rho * a * cd, rho * a * sd);
      const FieldSample trail = m.evaluate(-rho * a * cd, -rho * a * sd);
      // Normal strain along the loading direction: t·E·t.
      const auto along = [&](const Strain2& e) {
        return e.xx * cd * cd + 2.0 * e.xy * cd * sd + e.yy * sd * sd;
      };
      EXPECT_LT(along(lead.strain), -1e-3 * gradient_scale(m)) << dir << " " << rho;
      EXPECT_GT(along(trail.strain), 1e-3 * gradient_scale(m)) << dir << " " << rho;
      EXPECT_LT(lead.principal.e2, 0.0);
      EXPECT_GT(trail.principal.e1, 0.0);
    }
  }
}

// With Q = 0 the tangential field is exactly zero, so the field is the Hertz radial term alone.
TEST(CattaneoMindlin, HertzRadialTerm) {
  auto p = base_params();
  p.tangential_N = 0.0;
  p.hertz_radial = true;
  const CattaneoMindlin m(p);
  const double a = m.hertz().contact_radius_m;
  const double g = m.shear_modulus_Pa();
  const double nu = p.poisson;
  const double p0 = m.hertz().peak_pressure_Pa;
  const double gs = (1.0 - 2.0 * nu) * p0 / g;

  // Exactly zero at the centre, gradient −(1−2ν)p0/(4G)·I there.
  const FieldSample centre = m.evaluate(0.0, 0.0);
  EXPECT_EQ(centre.displacement_m.x, 0.0);
  EXPECT_EQ(centre.displacement_m.y, 0.0);
  EXPECT_NEAR(centre.gradient.xx, -(1.0 - 2.0 * nu) * p0 / (4.0 * g), 1e-15 * gs);
  EXPECT_NEAR(centre.gradient.yy, -(1.0 - 2.0 * nu) * p0 / (4.0 * g), 1e-15 * gs);
  EXPECT_EQ(centre.gradient.xy, 0.0);

  // r = a itself is in the continuity test: p(r) has an infinite slope there, so one ulp of r moves the
  // divergence by ~1e-8 of its scale.
  for (double rho : {1e-9, 1e-4, 0.1, 0.5, 0.9, 0.999, 1.0 - 1e-9, 1.0 + 1e-9, 1.001, 2.0, 50.0, 1e6}) {
    for (double ang : {0.3, 2.0, -1.2}) {
      const double x = rho * a * std::cos(ang);
      const double y = rho * a * std::sin(ang);
      const double r = std::hypot(x, y);  // what the model sees: rho = 1 may land on either side of a
      const double t = (r / a) * (r / a);
      const FieldSample s = m.evaluate(x, y);
      // u_r from docs/model.md, with 1 − (1 − t)^(3/2) through expm1/log1p so the reference keeps its digits
      // near the centre (the model uses the (1 + s + s²)/(1 + s) form instead).
      const double ur = r < a
                            ? (1.0 - 2.0 * nu) * p0 * a * a / (6.0 * g * r) * std::expm1(1.5 * std::log1p(-t))
                            : -(1.0 - 2.0 * nu) * p.normal_N / (4.0 * kPi * g * r);
      const double tol_u = 1e-13 * std::abs(ur);
      EXPECT_NEAR(s.displacement_m.x, ur * x / r, tol_u) << rho;
      EXPECT_NEAR(s.displacement_m.y, ur * y / r, tol_u) << rho;
      // div u^N = −(1−2ν)p/(2G) (zero outside the contact).
      const double div = s.gradient.xx + s.gradient.yy;
      EXPECT_NEAR(div, -(1.0 - 2.0 * nu) * m.pressure_Pa(r) / (2.0 * g), 1e-13 * gs) << rho;
      // Irrotational: H symmetric. ε_θθ = u_r/r.
      EXPECT_NEAR(s.gradient.xy, s.gradient.yx, 1e-15 * gs);
      const double e_tt = s.gradient.xx * std::sin(ang) * std::sin(ang) -
                          (s.gradient.xy + s.gradient.yx) * std::sin(ang) * std::cos(ang) +
                          s.gradient.yy * std::cos(ang) * std::cos(ang);
      EXPECT_NEAR(e_tt, ur / r, 1e-13 * gs) << rho;
    }
  }
}

// Tangential part is unchanged by adding the radial one (they are superposed, not coupled).
TEST(CattaneoMindlin, RadialTermSuperposes) {
  auto p = base_params();
  p.direction_rad = 1.1;
  const CattaneoMindlin tangential(p);
  p.hertz_radial = true;
  const CattaneoMindlin both(p);
  p.tangential_N = 0.0;
  const CattaneoMindlin radial(p);
  const double a = both.hertz().contact_radius_m;
  for (double rho : {0.0, 0.4, 0.9, 1.3, 10.0}) {
    const double x = rho * a * 0.6;
    const double y = -rho * a * 0.8;
    const Vec2 ut = tangential.displacement_m(x, y);
    const Vec2 ur = radial.displacement_m(x, y);
    const Vec2 ub = both.displacement_m(x, y);
    EXPECT_LE(norm(diff(ub, {ut.x + ur.x, ut.y + ur.y})), 1e-15 * displacement_scale_m(both));
    const Gradient2 ht = tangential.gradient(x, y);
    const Gradient2 hr = radial.gradient(x, y);
    const Gradient2 hb = both.gradient(x, y);
    EXPECT_LE(norm(diff(hb, {ht.xx + hr.xx, ht.xy + hr.xy, ht.yx + hr.yx, ht.yy + hr.yy})),
              1e-15 * gradient_scale(both));
  }
}

// The analytic gradient against 4th-order central differences of displacement_m, away from the bands
// |r − c|, |r − a| < 0.02a where the second derivatives are singular.
TEST(CattaneoMindlin, GradientMatchesCentralDifferences) {
  for (bool radial : {false, true}) {
    auto p = base_params();
    p.direction_rad = 0.3;
    p.hertz_radial = radial;
    const CattaneoMindlin m(p);
    const double a = m.hertz().contact_radius_m;
    const double c = m.stick_radius_m();
    int checked = 0;
    for (double rho :
         {0.0, 0.1, 0.4, 0.7, 0.76, 0.82, 0.9, 0.96, 1.03, 1.5, 3.0, 3.99, 4.01, 12.0, 1e3, 1e6}) {
      const double r = rho * a;
      if (std::abs(r - c) < 0.02 * a || std::abs(r - a) < 0.02 * a) continue;
      for (int k = 0; k < 8; ++k) {
        const double ang = 2.0 * kPi * k / 8.0 + 0.2;
        const double x = r * std::cos(ang);
        const double y = r * std::sin(ang);
        // Truncation ~ step⁴·u⁽⁵⁾ stays ~1e-9 relative at 0.02a from an edge; rounding ~ eps·u/step ~ 1e-12.
        const double step = 2e-4 * std::max(r, a);
        const auto d = [&](double dx, double dy) {
          const Vec2 u2p = m.displacement_m(x + 2 * dx, y + 2 * dy);
          const Vec2 up = m.displacement_m(x + dx, y + dy);
          const Vec2 um = m.displacement_m(x - dx, y - dy);
          const Vec2 u2m = m.displacement_m(x - 2 * dx, y - 2 * dy);
          const double s = std::hypot(dx, dy);
          return Vec2{(-u2p.x + 8 * up.x - 8 * um.x + u2m.x) / (12 * s),
                      (-u2p.y + 8 * up.y - 8 * um.y + u2m.y) / (12 * s)};
        };
        const Vec2 dx = d(step, 0.0);
        const Vec2 dy = d(0.0, step);
        const Gradient2 fd{dx.x, dy.x, dx.y, dy.y};
        const Gradient2 an = m.gradient(x, y);
        const double tol = 1e-6 * (r <= c && !radial ? gradient_scale(m) : norm(an));
        EXPECT_LE(norm(diff(fd, an)), tol) << "rho " << rho << " angle " << ang << " radial " << radial;
        ++checked;
      }
    }
    EXPECT_GE(checked, 100);
  }
}

// The series used beyond ρ = 4 against the direct forms in long double (ρ²·1e-19 rounding there).
TEST(CattaneoMindlinKernels, OuterShapeSeriesMatchesDirectForms) {
  for (double rho = 1.0; rho < 300.0; rho *= 1.037) {
    const long double r = rho;
    const long double root = std::sqrt((r - 1) * (r + 1));
    const long double arc = std::asin(1 / r);
    const long double phi = (2 - r * r) * arc + root;
    const long double d = -r * r * arc + root * (1 - 2 / (r * r));
    const long double dphi = 2 * root / r - 2 * r * arc;
    const long double dd = -2 * r * arc + 2 * root / r + 4 * root / (r * r * r);
    const detail::OuterShape s = detail::outer_shape(rho);
    const double tol = 1e-13 + 1e-18 * rho * rho;
    EXPECT_NEAR(s.phi, static_cast<double>(phi), tol * std::abs(static_cast<double>(phi))) << rho;
    EXPECT_NEAR(s.d, static_cast<double>(d), tol * std::abs(static_cast<double>(d))) << rho;
    EXPECT_NEAR(s.dphi, static_cast<double>(dphi), tol * std::abs(static_cast<double>(dphi))) << rho;
    EXPECT_NEAR(s.dd, static_cast<double>(dd), tol * std::abs(static_cast<double>(dd))) << rho;
    EXPECT_NEAR(s.d_over_rho, static_cast<double>(d / r), tol * std::abs(static_cast<double>(d / r))) << rho;
  }
  // docs/model.md's two-term far-field forms.
  for (double rho : {1e4, 1e6, 1e12}) {
    const detail::OuterShape s = detail::outer_shape(rho);
    EXPECT_NEAR(s.phi, 4.0 / (3.0 * rho) + 2.0 / (15.0 * std::pow(rho, 3)), 1e-15 * s.phi);
    EXPECT_NEAR(s.d, -8.0 / (3.0 * rho) + 4.0 / (5.0 * std::pow(rho, 3)), 1e-15 * std::abs(s.d));
  }
  // Inner and outer forms meet at ρ = 1: φ = π/2, d = −π/2, φ' = d' = −π.
  const detail::OuterShape one = detail::outer_shape(1.0);
  EXPECT_DOUBLE_EQ(one.phi, kPi / 2);
  EXPECT_DOUBLE_EQ(one.d, -kPi / 2);
  EXPECT_DOUBLE_EQ(one.dphi, -kPi);
  EXPECT_DOUBLE_EQ(one.dd, -kPi);
}

// Far away the contact acts as a Cerruti point force Q: u = Q/(2πG r)·[(1−ν) t + ν (t·n) n].
TEST(CattaneoMindlin, FarFieldIsPointForce) {
  auto p = base_params();
  p.direction_rad = 0.9;
  const CattaneoMindlin m(p);
  const double a = m.hertz().contact_radius_m;
  const double g = m.shear_modulus_Pa();
  const double nu = p.poisson;
  for (double ang : {0.0, 0.5, 2.0, 4.0}) {
    const double r = 1e6 * a;
    const Vec2 n{std::cos(ang), std::sin(ang)};
    const Vec2 t{std::cos(p.direction_rad), std::sin(p.direction_rad)};
    const double tn = t.x * n.x + t.y * n.y;
    const double k = p.tangential_N / (2.0 * kPi * g * r);
    const Vec2 expected{k * ((1.0 - nu) * t.x + nu * tn * n.x), k * ((1.0 - nu) * t.y + nu * tn * n.y)};
    EXPECT_LE(norm(diff(m.displacement_m(r * n.x, r * n.y), expected)), 1e-10 * norm(expected)) << ang;
  }
}

// The places docs/model.md calls delicate: every output finite.
TEST(CattaneoMindlin, HardCasesStayFinite) {
  const double limit = base_params().friction * base_params().normal_N;
  for (double q : {0.0, 1e-12 * limit, 0.5 * limit, limit * (1.0 - 1e-15), limit}) {
    for (double dir : {0.0, 1.0, -kPi}) {
      for (bool radial : {false, true}) {
        auto p = base_params();
        p.tangential_N = q;
        p.direction_rad = dir;
        p.hertz_radial = radial;
        const CattaneoMindlin m(p);
        const double a = m.hertz().contact_radius_m;
        const double c = m.stick_radius_m();
        EXPECT_TRUE(std::isfinite(m.rigid_shift_m()));
        std::vector<std::array<double, 2>> points = {{0.0, 0.0},
                                                     {c, 0.0},
                                                     {0.0, -c},
                                                     {a, 0.0},
                                                     {0.0, a},
                                                     {a * std::cos(0.3), a * std::sin(0.3)},
                                                     {c * std::cos(0.3), c * std::sin(0.3)},
                                                     {std::nextafter(c, 0.0), 0.0},
                                                     {std::nextafter(c, 1.0), 0.0},
                                                     {std::nextafter(a, 0.0), 0.0},
                                                     {std::nextafter(a, 1.0), 0.0},
                                                     {0.5 * (a + c), 0.0},
                                                     {1e6 * a, 0.0},
                                                     {-7e5 * a, 7e5 * a},
                                                     {1e150, -1e150},
                                                     {1e-300, 0.0},
                                                     {std::numeric_limits<double>::denorm_min(), 0.0},
                                                     {4.0 * a, 0.0}};
        for (const auto& pt : points) {
          const FieldSample s = m.evaluate(pt[0], pt[1]);
          EXPECT_TRUE(all_finite(s)) << "Q " << q << " dir " << dir << " radial " << radial << " at ("
                                     << pt[0] << ", " << pt[1] << ")";
        }
        for (double r : {0.0, c, a, 2.0 * a, -a}) {
          EXPECT_TRUE(std::isfinite(m.traction_Pa(r)));
          EXPECT_TRUE(std::isfinite(m.pressure_Pa(r)));
        }
      }
    }
  }
}

// c → a (Q = 1e-12 μP): the annulus is a few 1e-13·a wide; the stick zone still shifts by exactly δ_x.
TEST(CattaneoMindlin, VanishingSlipAnnulus) {
  auto p = base_params();
  p.tangential_N = 1e-12 * p.friction * p.normal_N;
  const CattaneoMindlin m(p);
  const double a = m.hertz().contact_radius_m;
  EXPECT_LT(m.stick_radius_m(), a);
  EXPECT_GT(m.stick_radius_m(), a * (1.0 - 1e-12));
  const Vec2 u = m.displacement_m(0.5 * a, 0.2 * a);
  EXPECT_EQ(u.x, m.rigid_shift_m());
  EXPECT_EQ(u.y, 0.0);
  // Outside, the field is a difference of two nearly equal blocks: finite and no larger than the shift.
  const Vec2 out = m.displacement_m(1.5 * a, 0.3 * a);
  EXPECT_TRUE(std::isfinite(out.x) && std::isfinite(out.y));
  EXPECT_LT(norm(out), m.rigid_shift_m() + 1e-15 * displacement_scale_m(m));
}

TEST(CattaneoMindlin, EvaluateAgreesWithParts) {
  auto p = base_params();
  p.direction_rad = -0.4;
  p.hertz_radial = true;
  const CattaneoMindlin m(p);
  const double a = m.hertz().contact_radius_m;
  const FieldSample s = m.evaluate(0.87 * a, 0.1 * a);
  const Vec2 u = m.displacement_m(0.87 * a, 0.1 * a);
  const Gradient2 h = m.gradient(0.87 * a, 0.1 * a);
  EXPECT_EQ(s.displacement_m.x, u.x);
  EXPECT_EQ(s.displacement_m.y, u.y);
  EXPECT_EQ(s.gradient.xx, h.xx);
  EXPECT_EQ(s.gradient.yx, h.yx);
  const Strain2 e = green_lagrange(h);
  EXPECT_EQ(s.strain.xy, e.xy);
  EXPECT_EQ(s.energy_density_J_m3, plane_strain_energy_density_J_m3(e, p.young_Pa, p.poisson));
  EXPECT_GT(s.energy_density_J_m3, 0.0);
}

struct Refusal {
  std::string parameter;
  std::function<void(CattaneoMindlinParams&)> edit;
};

TEST(CattaneoMindlin, RefusesInputsOutsideTheModel) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<Refusal> cases = {
      {"normal_N", [](auto& p) { p.normal_N = 0.0; }},
      {"normal_N", [](auto& p) { p.normal_N = -1.0; }},
      {"normal_N", [=](auto& p) { p.normal_N = nan; }},
      {"normal_N", [=](auto& p) { p.normal_N = inf; }},
      {"radius_m", [](auto& p) { p.radius_m = 0.0; }},
      {"radius_m", [=](auto& p) { p.radius_m = -inf; }},
      {"young_Pa", [](auto& p) { p.young_Pa = -1e6; }},
      {"young_Pa", [=](auto& p) { p.young_Pa = nan; }},
      {"poisson", [](auto& p) { p.poisson = 0.5; }},
      {"poisson", [](auto& p) { p.poisson = -1.0; }},
      {"poisson", [](auto& p) { p.poisson = 0.7; }},
      {"poisson", [=](auto& p) { p.poisson = nan; }},
      {"friction", [](auto& p) { p.friction = 0.0; }},
      {"friction", [=](auto& p) { p.friction = inf; }},
      {"tangential_N", [](auto& p) { p.tangential_N = -1e-9; }},
      {"tangential_N", [](auto& p) { p.tangential_N = 1.5; }},
      {"tangential_N", [](auto& p) { p.tangential_N = std::nextafter(1.0, 2.0); }},
      {"tangential_N", [=](auto& p) { p.tangential_N = nan; }},
      {"tangential_N", [=](auto& p) { p.tangential_N = inf; }},
      {"direction_rad", [=](auto& p) { p.direction_rad = nan; }},
      {"direction_rad", [=](auto& p) { p.direction_rad = inf; }},
      {"friction",
       [](auto& p) {  // finite Hertz contact and μP, but the strain scale μp0/G overflows
         p.friction = 1e300;
         p.young_Pa = 1e-30;
       }},
      {"normal_N",
       [](auto& p) {  // each finite, together out of range
         p.normal_N = 1e300;
         p.radius_m = 1e300;
         p.young_Pa = 1e-300;
       }},
  };
  for (const auto& c : cases) {
    auto p = base_params();  // friction 1, P = 1 N
    c.edit(p);
    try {
      const CattaneoMindlin m(p);
      ADD_FAILURE() << "accepted, expected a refusal naming " << c.parameter;
    } catch (const InvalidParameter& e) {
      EXPECT_EQ(e.parameter(), c.parameter) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.parameter), std::string::npos) << e.what();
    }
  }
  // Q = μP exactly is the edge of the model, not outside it.
  auto p = base_params();
  p.tangential_N = 1.0;
  EXPECT_NO_THROW(CattaneoMindlin{p});
  p.tangential_N = 0.0;
  EXPECT_NO_THROW(CattaneoMindlin{p});

  EXPECT_THROW(hertz_contact(1.0, 0.01, 1e6, 0.5), InvalidParameter);
  try {
    hertz_contact(1.0, -0.01, 1e6, 0.4);
    ADD_FAILURE() << "accepted a negative radius";
  } catch (const InvalidParameter& e) {
    EXPECT_EQ(e.parameter(), "radius_m");
  }
}

TEST(AdaptiveQuadrature, ExactForPolynomialsAndConvergesOnEdges) {
  // K15 is exact to degree 22, G7 to degree 13: both sides of the error estimate.
  const auto k = quadrature::gauss_kronrod_15([](double x) { return std::pow(x, 22); }, -1.0, 1.0);
  EXPECT_NEAR(k.value, 2.0 / 23.0, 1e-15);
  const auto g7 = quadrature::gauss_kronrod_15([](double x) { return std::pow(x, 12); }, -1.0, 1.0);
  EXPECT_NEAR(g7.value, 2.0 / 13.0, 1e-15);
  EXPECT_LT(g7.error, 1e-14);
  const auto edge = integrate([](double x) { return std::sqrt(1.0 - x * x); }, -1.0, 1.0, 1e-12);
  EXPECT_NEAR(edge.value, kPi / 2, 1e-10);
  EXPECT_TRUE(edge.converged);
}

}  // namespace
}  // namespace tirstrain::model
