#include "core/circular_statistics.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>

#include "core/error.hpp"

namespace tirstrain {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// The doubled angle φ = 2θ wrapped into [0, 2π).
std::vector<double> doubled(const std::vector<double>& angles_rad, const char* what) {
  if (angles_rad.empty()) throw Error(std::string("no ") + what + " angles to analyse");
  std::vector<double> phi(angles_rad.size());
  for (std::size_t i = 0; i < angles_rad.size(); ++i) {
    if (!std::isfinite(angles_rad[i]))
      throw Error(std::string(what) + " angle " + std::to_string(i) + " is not a finite number");
    phi[i] = std::fmod(2.0 * angles_rad[i], kTwoPi);
    if (phi[i] < 0.0) phi[i] += kTwoPi;
  }
  return phi;
}

std::complex<double> trigonometric_moment(const std::vector<double>& phi, double order) {
  std::complex<double> sum(0.0, 0.0);
  for (double p : phi) sum += std::polar(1.0, order * p);
  return sum / static_cast<double>(phi.size());
}

double kuiper_p_value(double lambda) {
  if (lambda < 0.4) return 1.0;  // the series converges slowly there and the sum is 1 to many digits
  double sum = 0.0;
  for (int j = 1; j <= 100; ++j) {
    const double j2l2 = static_cast<double>(j * j) * lambda * lambda;
    const double term = (4.0 * j2l2 - 1.0) * std::exp(-2.0 * j2l2);
    sum += term;
    if (std::abs(term) < 1e-12 * std::abs(sum)) break;
  }
  return std::clamp(2.0 * sum, 0.0, 1.0);
}

}  // namespace

AxialSummary axial_summary(const std::vector<double>& angles_rad) {
  const auto phi = doubled(angles_rad, "axial");
  const auto m1 = trigonometric_moment(phi, 1.0), m2 = trigonometric_moment(phi, 2.0);
  AxialSummary s;
  s.count = phi.size();
  s.resultant_length = std::abs(m1);
  s.circular_variance = 1.0 - s.resultant_length;
  double mean_phi = std::arg(m1);
  if (mean_phi < 0.0) mean_phi += kTwoPi;
  s.mean_direction_rad = 0.5 * mean_phi;
  const double spread = 1.0 - s.resultant_length;
  if (spread > 1e-12) {
    const double r4 = std::pow(s.resultant_length, 4);
    s.kurtosis = (std::abs(m2) * std::cos(std::arg(m2) - 2.0 * std::arg(m1)) - r4) / (spread * spread);
  }
  return s;
}

KuiperResult kuiper_two_sample_axial(const std::vector<double>& a_rad, const std::vector<double>& b_rad) {
  auto a = doubled(a_rad, "first group's"), b = doubled(b_rad, "second group's");
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  const double na = static_cast<double>(a.size()), nb = static_cast<double>(b.size());
  double d_plus = 0.0, d_minus = 0.0;
  std::size_t i = 0, j = 0;
  // Walk both sorted samples; after each distinct value both empirical distribution functions are exact.
  while (i < a.size() || j < b.size()) {
    const double x = (j >= b.size() || (i < a.size() && a[i] <= b[j])) ? a[i] : b[j];
    while (i < a.size() && a[i] == x) ++i;
    while (j < b.size() && b[j] == x) ++j;
    const double diff = static_cast<double>(i) / na - static_cast<double>(j) / nb;
    d_plus = std::max(d_plus, diff);
    d_minus = std::max(d_minus, -diff);
  }
  KuiperResult r;
  r.statistic = d_plus + d_minus;
  r.count_a = a.size();
  r.count_b = b.size();
  const double ne = na * nb / (na + nb), root = std::sqrt(ne);
  r.p_value = kuiper_p_value((root + 0.155 + 0.24 / root) * r.statistic);
  return r;
}

std::vector<std::size_t> axial_histogram(const std::vector<double>& angles_rad, std::size_t bins) {
  if (bins == 0) throw Error("a histogram needs at least one bin");
  std::vector<std::size_t> counts(bins, 0);
  for (double phi : doubled(angles_rad, "axial")) {
    const auto k = static_cast<std::size_t>(phi / kTwoPi * static_cast<double>(bins));
    ++counts[std::min(k, bins - 1)];
  }
  return counts;
}

}  // namespace tirstrain
