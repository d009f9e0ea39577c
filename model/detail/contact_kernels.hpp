#pragma once
// Building blocks of the Cattaneo–Mindlin surface field (docs/model.md): the shape functions
// φ(ρ), d(ρ) of a semi-ellipsoidal tangential traction outside its circle, and the Hertz radial term.
// Internal to model/; in a header so the tests can hold the far-field series against the direct forms.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace tirstrain::model::detail {

// φ, d and their ρ-derivatives for ρ = r/a >= 1. d/ρ is carried separately because the gradient needs
// d/r, and the series gives it without a division.
struct OuterShape {
  double phi = 0.0;
  double d = 0.0;
  double dphi = 0.0;
  double dd = 0.0;
  double d_over_rho = 0.0;
};

// The direct forms add O(ρ) and O(1) terms whose sum is O(1/ρ) (values) or O(1/ρ²) (derivatives), so they
// lose about ρ²·eps relative: 1e-8 at ρ = 1e4, 1e-4 for the derivatives there. Beyond kSeriesRho the series
// in w² = 1/ρ² is used instead; its terms shrink at least like 16^-k, so 16 terms are below rounding.
inline constexpr double kSeriesRho = 4.0;
inline constexpr std::size_t kSeriesTerms = 16;

struct SeriesCoefficients {
  // φ = Σ phi[k] w^(2k+1), d = Σ d[k] w^(2k+1); the *_deriv arrays hold (2k+1)·coefficient so that
  // φ' = −Σ phi_deriv[k] w^(2k+2).
  std::array<double, kSeriesTerms> phi{};
  std::array<double, kSeriesTerms> d{};
  std::array<double, kSeriesTerms> phi_deriv{};
  std::array<double, kSeriesTerms> d_deriv{};
};

// From asin(w) = Σ c_n w^(2n+1) and sqrt(1 − w²) = Σ b_n w^(2n):
// φ = 2 asin w − asin(w)/w² + sqrt(1 − w²)/w, d = −asin(w)/w² + sqrt(1 − w²)(1 − 2w²)/w.
constexpr SeriesCoefficients make_series_coefficients() {
  std::array<double, kSeriesTerms + 1> c{};
  std::array<double, kSeriesTerms + 1> b{};
  double central = 1.0;   // C(2n, n) / 4^n
  double binomial = 1.0;  // (−1)^n C(1/2, n)
  for (std::size_t n = 0; n <= kSeriesTerms; ++n) {
    const double nd = static_cast<double>(n);
    c[n] = central / (2.0 * nd + 1.0);
    b[n] = binomial;
    central *= (2.0 * nd + 1.0) / (2.0 * nd + 2.0);
    binomial *= (nd - 0.5) / (nd + 1.0);
  }
  SeriesCoefficients s;
  for (std::size_t k = 0; k < kSeriesTerms; ++k) {
    const double odd = 2.0 * static_cast<double>(k) + 1.0;
    s.phi[k] = 2.0 * c[k] - c[k + 1] + b[k + 1];
    s.d[k] = -c[k + 1] + b[k + 1] - 2.0 * b[k];
    s.phi_deriv[k] = odd * s.phi[k];
    s.d_deriv[k] = odd * s.d[k];
  }
  return s;
}

inline constexpr SeriesCoefficients kSeries = make_series_coefficients();

inline double horner(const std::array<double, kSeriesTerms>& coefficients, double w2) noexcept {
  double sum = 0.0;
  for (std::size_t k = kSeriesTerms; k-- > 0;) sum = sum * w2 + coefficients[k];
  return sum;
}

// Requires rho >= 1 (values below are treated as 1, the inner and outer forms agree there).
inline OuterShape outer_shape(double rho) noexcept {
  OuterShape s;
  if (rho >= kSeriesRho) {
    const double w = 1.0 / rho;
    const double w2 = w * w;
    const double d_sum = horner(kSeries.d, w2);
    s.phi = w * horner(kSeries.phi, w2);
    s.d = w * d_sum;
    s.d_over_rho = w2 * d_sum;
    s.dphi = -w2 * horner(kSeries.phi_deriv, w2);
    s.dd = -w2 * horner(kSeries.d_deriv, w2);
    return s;
  }
  rho = std::max(rho, 1.0);
  const double rho2 = rho * rho;
  const double w = 1.0 / rho;
  const double w2 = w * w;
  // (ρ−1)(ρ+1) rather than ρ²−1: exact near ρ = 1, where the root matters most.
  const double root = std::sqrt((rho - 1.0) * (rho + 1.0));
  const double arc = std::asin(std::min(w, 1.0));
  s.phi = (2.0 - rho2) * arc + root;
  s.d = -rho2 * arc + root * (1.0 - 2.0 * w2);
  s.dphi = 2.0 * root * w - 2.0 * rho * arc;
  s.dd = -2.0 * rho * arc + 2.0 * root * w + 4.0 * root * w2 * w;
  s.d_over_rho = s.d * w;
  return s;
}

// Hertz radial field u = ur_over_r·(x, y), gradient H = ur_over_r·I + aniso·n nᵀ (n the radial unit vector),
// i.e. aniso = du_r/dr − u_r/r. Both are finite and aniso = 0 at r = 0, so no division by r is needed.
struct RadialTerm {
  double ur_over_r = 0.0;
  double aniso = 0.0;
};

// coeff = (1 − 2ν)·p0 / (6G); far = (1 − 2ν)·P / (4πG) (equal to coeff·a², kept separate so the outside
// branch does not depend on the rounding of p0).
inline RadialTerm hertz_radial_term(double r_m, double a_m, double coeff, double far) noexcept {
  RadialTerm t;
  if (r_m < a_m) {
    const double rho = r_m / a_m;
    const double s = std::sqrt(std::max(0.0, (1.0 - rho) * (1.0 + rho)));
    // [1 − (1 − ρ²)^(3/2)] / ρ² written without the 0/0 at the centre.
    t.ur_over_r = -coeff * (1.0 + s + s * s) / (1.0 + s);
    // du_r/dr − u_r/r = coeff·ρ²(2 + s)/(1 + s)², the cancelling form of (2/3)f − s.
    t.aniso = coeff * rho * rho * (2.0 + s) / ((1.0 + s) * (1.0 + s));
  } else {
    const double inv_r = 1.0 / r_m;
    t.ur_over_r = -far * inv_r * inv_r;
    t.aniso = -2.0 * t.ur_over_r;
  }
  return t;
}

}  // namespace tirstrain::model::detail
