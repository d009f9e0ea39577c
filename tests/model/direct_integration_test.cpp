// Independent check of the closed forms: surface displacements by direct numerical integration of the
// Cerruti (tangential point force) and Boussinesq (normal point force) kernels over the Cattaneo–Mindlin
// traction and the Hertz pressure. Shares no code with model/ beyond the public results it checks; the
// contact size and tractions are recomputed here from docs/model.md.
//
// Kernels, for a point force at x' and a surface point x, d = x − x', s = |d|:
//   Cerruti (tangential force F):  u = 1/(2πG s)·[(1 − ν) F + ν (F·d) d / s²]
//   Boussinesq (normal force P):   u = −(1 − 2ν) P / (4πG s) · d / s      (towards the load)
// In polar coordinates (s, α) centred on the field point, with e = (cos α, sin α) and x' = x + s e,
// dA = s ds dα cancels the 1/s, and d/s = −e:
//   u_tan(x) = 1/(2πG) ∫ [(1 − ν) t + ν (t·e) e] (∫ q(x + s e) ds) dα
//   u_rad(x) = (1 − 2ν)/(4πG) ∫ e (∫ p(x + s e) ds) dα
// The traction is q = μp0·sqrt(1 − r²/a²) − μp0 (c/a)·sqrt(1 − r²/c²)[r < c], so each ray integral splits
// at the circles r = c and r = a, where the traction has square-root edges; the substitution
// s = m + h·sin τ over each chord of each circle turns those edges into smooth integrands.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "model/cattaneo_mindlin.hpp"
#include "tests/model/adaptive_quadrature.hpp"

namespace tirstrain::model {
namespace {

using quadrature::integrate;
constexpr double kPi = std::numbers::pi;
constexpr double kRayTol = 1e-13;
constexpr double kAngleTol = 1e-12;

// ∫₀^∞ sqrt(1 − |p + s e|²/R²)₊ ds: the ray from p along e through the disc of radius R.
double ray_integral(double px, double py, double ex, double ey, double radius) {
  const double pe = px * ex + py * ey;
  const double disc = pe * pe - (px * px + py * py - radius * radius);
  if (disc <= 0.0) return 0.0;
  const double half = std::sqrt(disc);  // half chord
  const double mid = -pe;
  if (mid + half <= 0.0) return 0.0;
  const double start = std::max(0.0, mid - half);
  const double tau_lo = std::asin(std::clamp((start - mid) / half, -1.0, 1.0));
  const auto f = [&](double tau) {
    const double s = mid + half * std::sin(tau);
    const double x = px + s * ex;
    const double y = py + s * ey;
    const double v = 1.0 - (x * x + y * y) / (radius * radius);
    return std::sqrt(std::max(v, 0.0)) * half * std::cos(tau);
  };
  return integrate(f, tau_lo, kPi / 2, kRayTol, 1e-15 * radius).value;
}

// The angular range of rays that meet the disc: all of them from inside, a cone from outside (the
// integrand drops to zero with a kink at the cone's edges, so the range stops there).
void angular_range(double px, double py, double radius, double& lo, double& hi) {
  const double r0 = std::hypot(px, py);
  if (r0 < radius) {
    lo = 0.0;
    hi = 2.0 * kPi;
    return;
  }
  const double centre = std::atan2(-py, -px);
  const double half = std::asin(std::min(1.0, radius / r0));
  lo = centre - half;
  hi = centre + half;
}

// ∫ w(α)·J(α) dα for the two components of a vector weight w.
template <class Weight>
Vec2 angular_integral(double px, double py, double radius, const Weight& weight) {
  double lo = 0.0;
  double hi = 0.0;
  angular_range(px, py, radius, lo, hi);
  const auto component = [&](int i) {
    const auto f = [&](double alpha) {
      const double ex = std::cos(alpha);
      const double ey = std::sin(alpha);
      const Vec2 w = weight(ex, ey);
      return (i == 0 ? w.x : w.y) * ray_integral(px, py, ex, ey, radius);
    };
    return integrate(f, lo, hi, kAngleTol, 1e-13 * radius).value;
  };
  return {component(0), component(1)};
}

struct Contact {
  double normal_N = 1.0, tangential_N = 0.5, radius_m = 0.01, young_Pa = 1.0e6, poisson = 0.4, friction = 1.0;
  double direction_rad = 0.6;

  double g() const { return young_Pa / (2.0 * (1.0 + poisson)); }
  double a() const {
    return std::cbrt(3.0 * normal_N * radius_m * (1.0 - poisson * poisson) / (4.0 * young_Pa));
  }
  double p0() const { return 3.0 * normal_N / (2.0 * kPi * a() * a()); }
  double c() const { return a() * std::cbrt(1.0 - tangential_N / (friction * normal_N)); }

  CattaneoMindlinParams params(bool radial) const {
    CattaneoMindlinParams p;
    p.normal_N = normal_N;
    p.tangential_N = tangential_N;
    p.radius_m = radius_m;
    p.young_Pa = young_Pa;
    p.poisson = poisson;
    p.friction = friction;
    p.direction_rad = direction_rad;
    p.hertz_radial = radial;
    return p;
  }

  Vec2 cerruti(double x, double y) const {
    const double nu = poisson;
    const double tx = std::cos(direction_rad);
    const double ty = std::sin(direction_rad);
    const auto weight = [&](double ex, double ey) {
      const double te = tx * ex + ty * ey;
      return Vec2{(1.0 - nu) * tx + nu * te * ex, (1.0 - nu) * ty + nu * te * ey};
    };
    const double q0 = friction * p0();
    const Vec2 ua = angular_integral(x, y, a(), weight);
    Vec2 u{q0 * ua.x, q0 * ua.y};
    if (c() > 0.0) {
      const Vec2 uc = angular_integral(x, y, c(), weight);
      u.x -= q0 * (c() / a()) * uc.x;
      u.y -= q0 * (c() / a()) * uc.y;
    }
    const double k = 1.0 / (2.0 * kPi * g());
    return {k * u.x, k * u.y};
  }

  Vec2 boussinesq(double x, double y) const {
    const Vec2 v = angular_integral(x, y, a(), [](double ex, double ey) { return Vec2{ex, ey}; });
    const double k = (1.0 - 2.0 * poisson) * p0() / (4.0 * kPi * g());
    return {k * v.x, k * v.y};
  }
};

double rel_error(const Vec2& got, const Vec2& want) {
  return std::hypot(got.x - want.x, got.y - want.y) / std::hypot(want.x, want.y);
}

struct Point {
  const char* region;
  double rho;  // r / a
  double angle_rad;
};

// 36 points: 12 in the stick zone (c/a = 0.794), 12 in the slip annulus, 12 outside the contact; angles
// advance by the golden angle so no two share a symmetry line.
std::vector<Point> field_points() {
  const double stick[] = {0.0, 0.05, 0.15, 0.3, 0.4, 0.5, 0.6, 0.65, 0.7, 0.75, 0.77, 0.785};
  const double slip[] = {0.80, 0.81, 0.83, 0.85, 0.87, 0.89, 0.91, 0.93, 0.95, 0.97, 0.985, 0.995};
  const double out[] = {1.005, 1.02, 1.05, 1.1, 1.25, 1.5, 2.0, 3.0, 4.5, 10.0, 40.0, 300.0};
  std::vector<Point> pts;
  double angle = 0.3;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (double rho : stick) pts.push_back({"stick", rho, angle += golden});
  for (double rho : slip) pts.push_back({"slip", rho, angle += golden});
  for (double rho : out) pts.push_back({"outside", rho, angle += golden});
  return pts;
}

// One semi-ellipsoidal block at its centre: π q0 (2 − ν) a / (8G), which fixes the Cerruti normalisation
// (every ray sees ∫ sqrt(1 − s²/a²) ds = πa/4).
TEST(DirectIntegration, CentreOfOneBlock) {
  const Contact k;
  const double a = k.a();
  const double nu = k.poisson;
  const auto weight = [&](double ex, double ey) { return Vec2{(1.0 - nu) + nu * ex * ex, nu * ex * ey}; };
  const Vec2 v = angular_integral(0.0, 0.0, a, weight);
  const double q0 = 1000.0;
  const double ux = q0 * v.x / (2.0 * kPi * k.g());
  EXPECT_NEAR(ux, kPi * q0 * (2.0 - nu) * a / (8.0 * k.g()), 1e-12 * ux);
  EXPECT_NEAR(v.y, 0.0, 1e-12 * v.x);
}

TEST(DirectIntegration, TangentialFieldMatchesClosedForm) {
  const Contact k;
  ASSERT_NEAR(k.c() / k.a(), std::cbrt(0.5), 1e-15);
  const CattaneoMindlin m(k.params(false));
  ASSERT_NEAR(m.stick_radius_m(), k.c(), 1e-15 * k.a());
  double worst = 0.0;
  int count = 0;
  for (const Point& pt : field_points()) {
    const double x = pt.rho * k.a() * std::cos(pt.angle_rad);
    const double y = pt.rho * k.a() * std::sin(pt.angle_rad);
    const Vec2 direct = k.cerruti(x, y);
    const Vec2 closed = m.displacement_m(x, y);
    const double err = rel_error(closed, direct);
    EXPECT_LE(err, 1e-6) << pt.region << " rho " << pt.rho << " angle " << pt.angle_rad << ": closed ("
                         << closed.x << ", " << closed.y << ") direct (" << direct.x << ", " << direct.y
                         << ")";
    worst = std::max(worst, err);
    ++count;
  }
  EXPECT_GE(count, 30);
  std::printf("tangential: %d points, worst relative error %.3g\n", count, worst);
}

// The Hertz radial term alone (Q = 0) against Boussinesq, then both together against the sum.
TEST(DirectIntegration, RadialAndCombinedFieldsMatchClosedForm) {
  Contact radial_only;
  radial_only.tangential_N = 0.0;
  const CattaneoMindlin mr(radial_only.params(true));
  const Contact k;
  const CattaneoMindlin mb(k.params(true));
  double worst_radial = 0.0;
  double worst_both = 0.0;
  int count = 0;
  for (const Point& pt : field_points()) {
    const double x = pt.rho * k.a() * std::cos(pt.angle_rad);
    const double y = pt.rho * k.a() * std::sin(pt.angle_rad);
    const Vec2 bous = k.boussinesq(x, y);
    if (pt.rho > 0.0) {  // the radial field vanishes at the centre: no relative error there
      const double err = rel_error(mr.displacement_m(x, y), bous);
      EXPECT_LE(err, 1e-6) << pt.region << " rho " << pt.rho;
      worst_radial = std::max(worst_radial, err);
      ++count;
    } else {
      EXPECT_LE(std::hypot(bous.x, bous.y), 1e-12 * k.p0() * k.a() / k.g());
      EXPECT_EQ(mr.displacement_m(x, y).x, 0.0);
    }
    const Vec2 cerr = k.cerruti(x, y);
    const double err = rel_error(mb.displacement_m(x, y), {cerr.x + bous.x, cerr.y + bous.y});
    EXPECT_LE(err, 1e-6) << pt.region << " rho " << pt.rho;
    worst_both = std::max(worst_both, err);
  }
  EXPECT_GE(count, 30);
  std::printf("radial: %d points, worst relative error %.3g; combined: worst %.3g\n", count, worst_radial,
              worst_both);
}

}  // namespace
}  // namespace tirstrain::model
