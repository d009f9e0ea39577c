#pragma once
// Welch spectral estimates with the conventions of scipy.signal.welch / csd / coherence (and MATLAB's
// pwelch / cpsd / tfestimate / mscohere with a Hann window):
//   - periodic ("DFT-even") Hann window of `segment` samples, nfft = segment;
//   - overlap segment/2 (floor), no padding of the last partial segment (it is dropped);
//   - each segment has its mean removed (detrend = 'constant') before windowing;
//   - density scaling 1/(fs·Σw²), segments averaged by the mean;
//   - one-sided spectra for real input: every bin except DC and (for even nfft) Nyquist doubled.
// Cross-spectra follow SciPy's order: Pxy = conj(X)·Y, so H1 = Pxy/Pxx is the transfer function from x to y
// and coherence = |Pxy|²/(Pxx·Pyy).
#include <complex>
#include <cstddef>
#include <optional>
#include <vector>

namespace tirstrain::signals {

enum class Detrend { none, constant, linear };

struct WelchOptions {
  std::size_t segment = 256;           // nperseg, samples
  std::optional<std::size_t> overlap;  // noverlap; default segment / 2
  Detrend detrend = Detrend::constant;
};

struct PowerSpectrum {
  std::vector<double> freq_Hz;
  std::vector<double> psd;  // units² / Hz
  std::size_t segments = 0;
};

struct CrossSpectrum {
  std::vector<double> freq_Hz;
  std::vector<std::complex<double>> csd;  // units_x·units_y / Hz, Pxy = conj(X)·Y
  std::size_t segments = 0;
};

// Everything needed for a transfer-function estimate, from one pass over the segments.
struct TransferEstimate {
  std::vector<double> freq_Hz;
  std::vector<double> pxx, pyy;
  std::vector<std::complex<double>> pxy;
  std::vector<std::complex<double>> h1;  // Pxy / Pxx (0 where Pxx = 0)
  std::vector<double> coherence;         // |Pxy|² / (Pxx·Pyy), in [0, 1] (0 where undefined)
  std::size_t segments = 0;
};

// Throws tirstrain::Error (key "segment" / "overlap") when the segment is shorter than 2 samples, longer
// than the signal, or the overlap is not smaller than the segment.
PowerSpectrum welch(const std::vector<double>& x, double sample_rate_Hz, const WelchOptions& options);
CrossSpectrum csd(const std::vector<double>& x, const std::vector<double>& y, double sample_rate_Hz,
                  const WelchOptions& options);
TransferEstimate transfer_estimate(const std::vector<double>& x, const std::vector<double>& y,
                                   double sample_rate_Hz, const WelchOptions& options);

// Periodic Hann window w[n] = 0.5 − 0.5·cos(2πn/N).
std::vector<double> hann_periodic(std::size_t n);

// One-sided frequency axis k·fs/nfft for k = 0..nfft/2.
std::vector<double> rfft_frequencies(std::size_t nfft, double sample_rate_Hz);

// Full forward DFT of real input, bins 0..n/2 (mixed-radix FFT, any length).
std::vector<std::complex<double>> rfft(const std::vector<double>& x);

// Peaks as scipy.signal.find_peaks: strict local maxima (a flat top counts once, at its middle sample,
// rounded down), never the first or last sample; filters applied in SciPy's order (height, distance,
// prominence). Prominence: height above the higher of the two lowest points reached on each side before
// meeting a higher sample or the signal end.
struct Peak {
  std::size_t index = 0;
  double value = 0.0;
  double prominence = 0.0;
  std::size_t left_base = 0;
  std::size_t right_base = 0;
};

struct PeakOptions {
  std::optional<double> min_height;
  double min_prominence = 0.0;
  std::size_t min_distance = 1;  // samples; peaks closer than this are thinned, highest kept
};

std::vector<Peak> find_peaks(const std::vector<double>& x, const PeakOptions& options = {});

// Refines a peak's position by fitting a parabola through it and its two neighbours; returns the
// fractional index (the index itself at the signal ends).
double parabolic_peak_index(const std::vector<double>& x, std::size_t index);

}  // namespace tirstrain::signals
