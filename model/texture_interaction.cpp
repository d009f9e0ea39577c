#include "model/texture_interaction.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <string>

namespace tirstrain::model {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kMaxPeriodsInContact = 1e4;  // periods of the shorter profile along the contact

void require_positive(double value, const char* field) {
  if (!(value > 0.0) || !std::isfinite(value))
    throw std::invalid_argument(std::string(field) + " must be positive and finite");
}

}  // namespace

double predicted_vibration_frequency_Hz(double speed_m_s, double wavelength_m) {
  require_positive(wavelength_m, "wavelength_m");
  return std::abs(speed_m_s) / wavelength_m;
}

TextureZone classify_texture(double surface_wavelength_m, double ridge_period_m, double tolerance) {
  require_positive(surface_wavelength_m, "surface_wavelength_m");
  require_positive(ridge_period_m, "ridge_period_m");
  if (surface_wavelength_m < (1.0 - tolerance) * ridge_period_m) return TextureZone::finer_than_ridges;
  if (surface_wavelength_m > (1.0 + tolerance) * ridge_period_m) return TextureZone::coarser_than_ridges;
  return TextureZone::comparable_to_ridges;
}

const char* to_string(TextureZone zone) {
  switch (zone) {
    case TextureZone::finer_than_ridges:
      return "finer_than_ridges";
    case TextureZone::comparable_to_ridges:
      return "comparable_to_ridges";
    case TextureZone::coarser_than_ridges:
      return "coarser_than_ridges";
  }
  return "unknown";
}

OverlapSeries overlap_area(const TextureInteractionParams& p) {
  require_positive(p.ridge_period_m, "ridge_period_m");
  require_positive(p.surface_wavelength_m, "surface_wavelength_m");
  require_positive(p.ridge_amplitude_m, "ridge_amplitude_m");
  require_positive(p.surface_amplitude_m, "surface_amplitude_m");
  require_positive(p.contact_length_m, "contact_length_m");
  require_positive(p.speed_m_s, "speed_m_s");
  if (!(p.interpenetration > 0.0 && p.interpenetration <= 1.0))
    throw std::invalid_argument("interpenetration must lie in (0, 1]");
  if (p.samples_per_period < 4) throw std::invalid_argument("samples_per_period must be at least 4");
  if (p.points_per_wavelength < 8) throw std::invalid_argument("points_per_wavelength must be at least 8");
  const double shortest = std::min(p.ridge_period_m, p.surface_wavelength_m);
  // The profiles are sampled along the whole contact at points_per_wavelength of the shorter period: a
  // period far below the contact's length would take memory and time without end.
  if (p.contact_length_m / shortest > kMaxPeriodsInContact)
    throw std::invalid_argument(
        std::string(shortest == p.surface_wavelength_m ? "surface_wavelength_m" : "ridge_period_m") +
        " is below 1/" + std::to_string(static_cast<long>(kMaxPeriodsInContact)) + " of the contact length");
  const auto points = static_cast<std::size_t>(
      std::ceil(p.contact_length_m / shortest * static_cast<double>(p.points_per_wavelength)));
  const double dx = p.contact_length_m / static_cast<double>(points);
  const double depth = (1.0 - p.interpenetration) * (p.ridge_amplitude_m + p.surface_amplitude_m);
  const double period_s = p.surface_wavelength_m / p.speed_m_s;
  // The ridge profile does not move with time: evaluate it once.
  std::vector<double> ridge(points);
  for (std::size_t k = 0; k < points; ++k) {
    const double x = (static_cast<double>(k) + 0.5) * dx;  // midpoint rule
    ridge[k] = 0.5 * p.ridge_amplitude_m * (1.0 + std::cos(kTwoPi * x / p.ridge_period_m));
  }
  OverlapSeries out;
  out.time_s.resize(p.samples_per_period);
  out.area_m2.resize(p.samples_per_period);
  for (std::size_t j = 0; j < p.samples_per_period; ++j) {
    const double t = period_s * static_cast<double>(j) / static_cast<double>(p.samples_per_period);
    const double shift = p.speed_m_s * t;
    double area = 0.0;
    for (std::size_t k = 0; k < points; ++k) {
      const double x = (static_cast<double>(k) + 0.5) * dx;
      const double surface =
          0.5 * p.surface_amplitude_m * (1.0 + std::cos(kTwoPi * (x + shift) / p.surface_wavelength_m));
      area += std::max(0.0, ridge[k] + surface - depth);
    }
    out.time_s[j] = t;
    out.area_m2[j] = area * dx;
  }
  return out;
}

InteractionPrediction predict_interaction(const TextureInteractionParams& p, double zone_tolerance) {
  const OverlapSeries s = overlap_area(p);
  const std::size_t n = s.area_m2.size();
  InteractionPrediction out;
  out.surface_frequency_Hz = predicted_vibration_frequency_Hz(p.speed_m_s, p.surface_wavelength_m);
  out.ridge_frequency_Hz = predicted_vibration_frequency_Hz(p.speed_m_s, p.ridge_period_m);
  out.zone = classify_texture(p.surface_wavelength_m, p.ridge_period_m, zone_tolerance);
  for (double a : s.area_m2) out.mean_area_m2 += a;
  out.mean_area_m2 /= static_cast<double>(n);
  // One exact period is sampled, so the DFT bins are the harmonics m·v/λ_s with no leakage; n is small
  // (hundreds), so a direct sum is cheap and keeps model/ free of an FFT dependency.
  for (std::size_t m = 1; m <= n / 2; ++m) {
    std::complex<double> c(0.0, 0.0);
    for (std::size_t j = 0; j < n; ++j)
      c += s.area_m2[j] * std::polar(1.0, -kTwoPi * static_cast<double>(m * j) / static_cast<double>(n));
    const double amplitude = 2.0 * std::abs(c) / static_cast<double>(n);
    out.lines.push_back({m, static_cast<double>(m) * out.surface_frequency_Hz, amplitude});
    if (amplitude > out.modulation_m2) {
      out.modulation_m2 = amplitude;
      out.peak_harmonic = m;
    }
  }
  out.peak_frequency_Hz = static_cast<double>(out.peak_harmonic) * out.surface_frequency_Hz;
  return out;
}

std::vector<InteractionPrediction> sweep_surface_wavelength(const TextureInteractionParams& params,
                                                            const std::vector<double>& wavelengths_m,
                                                            double zone_tolerance) {
  std::vector<InteractionPrediction> out;
  out.reserve(wavelengths_m.size());
  for (double lambda : wavelengths_m) {
    TextureInteractionParams p = params;
    p.surface_wavelength_m = lambda;
    out.push_back(predict_interaction(p, zone_tolerance));
  }
  return out;
}

}  // namespace tirstrain::model
