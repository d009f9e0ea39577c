#pragma once
// Butterworth design and zero-phase filtering with SciPy/MATLAB semantics.
//
// Design follows scipy.signal.butter: analog prototype poles on the unit circle, frequency pre-warping
// (Ω = 2·fs·tan(π·f/fs)), low/high/band-pass transformation, bilinear transform. Filters are kept as
// second-order sections (SOS) because the polynomial form loses all precision for high orders or cutoffs
// far below Nyquist; the (b, a) form is offered for small orders and for comparison with published
// coefficients.
//
// filtfilt follows scipy.signal.filtfilt / sosfiltfilt defaults: odd extension of the signal by
// padlen = 3·(filter order + 1) samples at each end (the same value both SciPy functions use for a
// Butterworth filter), steady-state initial conditions scaled by the first sample (lfilter_zi /
// sosfilt_zi), a forward pass, a backward pass, and the padding removed. The input must be longer than
// padlen, as SciPy requires.
#include <complex>
#include <cstddef>
#include <vector>

namespace tirstrain::signals {

enum class FilterType { lowpass, highpass, bandpass };

// One biquad: H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²); a first-order section has b2 = a2 = 0.
struct Biquad {
  double b0 = 1.0, b1 = 0.0, b2 = 0.0;
  double a1 = 0.0, a2 = 0.0;
};

struct SosFilter {
  std::vector<Biquad> sections;
  int order = 0;  // number of digital poles (2·N for a band-pass of prototype order N)
};

// Polynomial form, a[0] = 1.
struct TransferFunction {
  std::vector<double> b;
  std::vector<double> a;
};

struct ButterworthSpec {
  FilterType type = FilterType::lowpass;
  int order = 4;            // prototype order N (a band-pass has 2·N poles, as in SciPy)
  double cutoff_Hz = 0.0;   // -3 dB frequency for low/high-pass; lower edge for band-pass
  double cutoff2_Hz = 0.0;  // upper -3 dB edge for band-pass
  double sample_rate_Hz = 0.0;
};

// Throws tirstrain::Error (key naming the parameter) for order < 1, cutoffs outside (0, fs/2), or a
// band-pass with f1 >= f2.
SosFilter butterworth_sos(const ButterworthSpec& spec);
TransferFunction butterworth_ba(const ButterworthSpec& spec);

// Complex response at f_Hz (H(e^{jω}), ω = 2π f / fs).
std::complex<double> frequency_response(const SosFilter& filter, double f_Hz, double sample_rate_Hz);
std::complex<double> frequency_response(const TransferFunction& filter, double f_Hz, double sample_rate_Hz);

// |H|² of the ideal digital Butterworth filter obtained by the bilinear transform, in closed form; used by
// tests and documentation as the reference response.
double butterworth_power_response(const ButterworthSpec& spec, double f_Hz);

// Causal filtering (scipy.signal.sosfilt / lfilter), zero initial state unless `initial` is given.
// For SOS, `initial` holds 2 values per section (transposed direct form II states).
std::vector<double> sosfilt(const SosFilter& filter, const std::vector<double>& x,
                            const std::vector<double>* initial = nullptr);
std::vector<double> lfilter(const TransferFunction& filter, const std::vector<double>& x,
                            const std::vector<double>* initial = nullptr);

// Steady-state states for a unit step input (scipy.signal.sosfilt_zi / lfilter_zi).
std::vector<double> sosfilt_zi(const SosFilter& filter);
std::vector<double> lfilter_zi(const TransferFunction& filter);

// The default odd padding length used by filtfilt for this filter.
std::size_t default_padlen(const SosFilter& filter);
std::size_t default_padlen(const TransferFunction& filter);

// Zero-phase filtering; throws Error if x.size() <= padlen.
std::vector<double> filtfilt(const SosFilter& filter, const std::vector<double>& x);
std::vector<double> filtfilt(const TransferFunction& filter, const std::vector<double>& x);

// Convenience: design + filtfilt in one call, e.g. the paper's 4th-order 80 Hz low-pass.
std::vector<double> butterworth_filtfilt(const std::vector<double>& x, const ButterworthSpec& spec);

}  // namespace tirstrain::signals
