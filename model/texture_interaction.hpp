#pragma once
// Fingerprint–texture interaction: the temporal vibration a sliding finger receives from a periodic surface.
//
// Model (1-D, along the sliding direction): the fingerprint is a sinusoidal ridge profile of period λ_f
// fixed in the contact window [0, L]; the surface is a sinusoid of wavelength λ_s sliding past at speed v.
// Heights h_f(x) = a_f·(1 + cos 2πx/λ_f)/2 and h_s(x, t) = a_s·(1 + cos 2π(x + vt)/λ_s)/2; the two
// interpenetrate where h_f + h_s exceeds d = (1 − interpenetration)·(a_f + a_s), and the overlap area per
// unit width is A(t) = ∫_0^L max(0, h_f + h_s − d) dx. A(t) is exactly periodic with period λ_s/v (shifting
// the surface by one wavelength changes nothing), so its spectrum holds only harmonics m·v/λ_s; which
// harmonic dominates depends on λ_s relative to λ_f. The zones are named relative to the ridge period:
// finer (λ_s < (1 − tol)·λ_f), comparable (|λ_s − λ_f| <= tol·λ_f), coarser (λ_s > (1 + tol)·λ_f).
// Depends on nothing of ours.
#include <cstddef>
#include <vector>

namespace tirstrain::model {

// v/λ: the temporal frequency of a spatial period λ passing at speed v. Throws std::invalid_argument for
// λ <= 0.
double predicted_vibration_frequency_Hz(double speed_m_s, double wavelength_m);

enum class TextureZone { finer_than_ridges, comparable_to_ridges, coarser_than_ridges };

TextureZone classify_texture(double surface_wavelength_m, double ridge_period_m, double tolerance = 0.25);
const char* to_string(TextureZone zone);

struct TextureInteractionParams {
  double ridge_period_m = 0.45e-3;         // λ_f, typical fingertip ridge spacing
  double ridge_amplitude_m = 50e-6;        // a_f
  double surface_wavelength_m = 1.0e-3;    // λ_s
  double surface_amplitude_m = 50e-6;      // a_s
  double contact_length_m = 10e-3;         // L
  double speed_m_s = 0.05;                 // v
  double interpenetration = 0.5;           // fraction of a_f + a_s that overlaps, in (0, 1]
  std::size_t samples_per_period = 256;    // time samples over one period λ_s/v
  std::size_t points_per_wavelength = 64;  // spatial quadrature density on the shorter wavelength
};

struct OverlapSeries {
  std::vector<double> time_s;   // one period λ_s/v, uniformly sampled (endpoint excluded)
  std::vector<double> area_m2;  // overlap area per unit width
};

// One spectral line of the overlap area: the harmonic m·v/λ_s and its amplitude.
struct SpectralLine {
  std::size_t harmonic = 0;
  double frequency_Hz = 0.0;
  double amplitude_m2 = 0.0;
};

struct InteractionPrediction {
  double surface_frequency_Hz = 0.0;  // v/λ_s
  double ridge_frequency_Hz = 0.0;    // v/λ_f
  double peak_frequency_Hz = 0.0;     // strongest harmonic of A(t)
  std::size_t peak_harmonic = 0;      // m in m·v/λ_s
  double modulation_m2 = 0.0;         // amplitude of that harmonic
  double mean_area_m2 = 0.0;
  TextureZone zone = TextureZone::comparable_to_ridges;
  std::vector<SpectralLine> lines;  // every harmonic m = 1 … samples_per_period/2, in order
};

// Throws std::invalid_argument naming the field for non-positive lengths, speed or sample counts.
OverlapSeries overlap_area(const TextureInteractionParams& params);
InteractionPrediction predict_interaction(const TextureInteractionParams& params,
                                          double zone_tolerance = 0.25);
// Peak frequency versus surface wavelength (all other parameters fixed).
std::vector<InteractionPrediction> sweep_surface_wavelength(const TextureInteractionParams& params,
                                                            const std::vector<double>& wavelengths_m,
                                                            double zone_tolerance = 0.25);

}  // namespace tirstrain::model
