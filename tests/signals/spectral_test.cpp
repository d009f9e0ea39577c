// Welch, cross-spectra, H1 and coherence against analytic truth: a hand-computed impulse spectrum that
// pins SciPy's conventions (periodic Hann, constant detrend, density scaling, one-sided doubling, 50 %
// overlap without padding), sinusoid amplitude and frequency, white-noise level, and the transfer function
// of a known FIR system.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "signals/spectral.hpp"

namespace ts = tirstrain::signals;

namespace {
constexpr double kPi = std::numbers::pi;
}

TEST(Welch, ImpulseSpectrumPinsScipyConventions) {
  // One 8-sample segment, x = δ[n−2], fs = 1. Mean removal leaves δ[n−2] − 1/8; with the periodic Hann
  // window (w[2] = 0.5, Σw = 4, Σw² = 3, W[±1] = −2) the DFT is X[k] = 0.5·e^{−jπk/2} − W[k]/8:
  // X[0] = 0, X[1] = 0.25 − 0.5j, |X[2..4]| = 0.5. Density scale 1/(fs·Σw²) = 1/3, doubled except DC and
  // Nyquist. (A symmetric Hann window would give w[2] = 0.188 and different numbers.)
  std::vector<double> x(8, 0.0);
  x[2] = 1.0;
  const auto p = ts::welch(x, 1.0, {.segment = 8});
  ASSERT_EQ(p.psd.size(), 5u);
  EXPECT_EQ(p.segments, 1u);
  EXPECT_NEAR(p.psd[0], 0.0, 1e-15);
  EXPECT_NEAR(p.psd[1], 2.0 * 0.3125 / 3.0, 1e-14);
  EXPECT_NEAR(p.psd[2], 2.0 * 0.25 / 3.0, 1e-14);
  EXPECT_NEAR(p.psd[3], 2.0 * 0.25 / 3.0, 1e-14);
  EXPECT_NEAR(p.psd[4], 0.25 / 3.0, 1e-14);
  EXPECT_NEAR(p.freq_Hz[4], 0.5, 0.0);
  // 12 samples, segment 8, overlap 4: floor((12 − 4)/4) = 2 segments; the second one (samples 4..11) sees
  // the impulse nowhere, and its mean is zero, so the average halves the first segment's spectrum.
  std::vector<double> y(12, 0.0);
  y[2] = 1.0;
  const auto q = ts::welch(y, 1.0, {.segment = 8});
  EXPECT_EQ(q.segments, 2u);
  EXPECT_NEAR(q.psd[2], 0.5 * 2.0 * 0.25 / 3.0, 1e-14);
}

TEST(Welch, OddSegmentDoublesUpToTheLastBin) {
  std::vector<double> x(7, 0.0);
  x[3] = 1.0;
  const auto p = ts::welch(x, 1.0, {.segment = 7, .overlap = 0, .detrend = ts::Detrend::none});
  // No Nyquist bin for odd nfft: Σ P·Δf over the one-sided spectrum still equals the windowed energy/(Σw²).
  const auto w = ts::hann_periodic(7);
  double w2 = 0.0;
  for (double v : w) w2 += v * v;
  const double df = 1.0 / 7.0;
  double total = p.psd[0] * df;
  for (std::size_t k = 1; k < p.psd.size(); ++k) total += p.psd[k] * df;
  // Parseval for the one-sided density: Σ_full |X|²/N = Σ (w x)²; with doubling, Σ_onesided = full sum.
  EXPECT_NEAR(total, w[3] * w[3] / w2, 1e-14);
}

TEST(Welch, SinusoidAmplitudeAndFrequency) {
  const double fs = 1000.0, amp = 2.0;
  const std::size_t seg = 1000, n = 20000;
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = amp * std::sin(2 * kPi * 50.0 * i / fs + 0.3);
  const auto p = ts::welch(x, fs, {.segment = seg});
  const auto peak = std::max_element(p.psd.begin(), p.psd.end()) - p.psd.begin();
  EXPECT_NEAR(p.freq_Hz[static_cast<std::size_t>(peak)], 50.0, 1e-12);
  // On-bin sinusoid through a periodic Hann window: peak density A²·N/(3·fs), total power A²/2.
  EXPECT_NEAR(p.psd[static_cast<std::size_t>(peak)], amp * amp * seg / (3.0 * fs), 1e-9);
  double power = 0.0;
  for (std::size_t k = 45; k <= 55; ++k) power += p.psd[k] * (fs / seg);
  EXPECT_NEAR(power, amp * amp / 2.0, 1e-9);

  // Off-bin (50.37 Hz): parabolic interpolation of the peak finds the frequency within 0.05 bin widths·fs,
  // and the power summed over the main lobe stays within 0.5 %.
  for (std::size_t i = 0; i < n; ++i) x[i] = amp * std::sin(2 * kPi * 50.37 * i / fs);
  const auto q = ts::welch(x, fs, {.segment = seg});
  const auto qpeak = static_cast<std::size_t>(std::max_element(q.psd.begin(), q.psd.end()) - q.psd.begin());
  // Parabola through the log-density (Gaussian interpolation): nearly unbiased for the Hann main lobe.
  std::vector<double> log_psd(q.psd.size());
  for (std::size_t k = 0; k < q.psd.size(); ++k) log_psd[k] = std::log(q.psd[k] + 1e-300);
  const double f_est = ts::parabolic_peak_index(log_psd, qpeak) * fs / seg;
  EXPECT_NEAR(f_est, 50.37, 0.05);
  double qpower = 0.0;
  for (std::size_t k = 40; k <= 60; ++k) qpower += q.psd[k] * (fs / seg);
  EXPECT_NEAR(qpower, amp * amp / 2.0, 0.005 * amp * amp / 2.0);
}

TEST(Welch, WhiteNoiseLevel) {
  // One-sided density of white noise of variance σ² is 2σ²/fs. 2^18 samples, 256-sample segments: the
  // band average has a statistical error of a few tenths of a percent; tolerance 2 %.
  const double fs = 2000.0, sigma = 0.5;
  std::mt19937_64 rng(12345);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<double> x(1 << 18);
  for (double& v : x) v = noise(rng);
  const auto p = ts::welch(x, fs, {.segment = 256});
  double mean = 0.0;
  for (std::size_t k = 1; k < 128; ++k) mean += p.psd[k];
  mean /= 127.0;
  EXPECT_NEAR(mean, 2.0 * sigma * sigma / fs, 0.02 * 2.0 * sigma * sigma / fs);
  // Constant detrend removes each segment's mean: the DC bin keeps only main-lobe leakage from bins ±1
  // and is not doubled, so it sits well below the level.
  EXPECT_LT(p.psd[0], 0.5 * mean);
}

TEST(TransferEstimate, RecoversFirSystemAndCoherence) {
  // y = h * x with h = [0.5, 0.3, −0.2] (H(f) known in closed form), white input.
  const double fs = 1000.0;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> unit(0.0, 1.0);
  const std::size_t n = 1 << 16;
  std::vector<double> x(n), y(n), y_noisy(n);
  for (double& v : x) v = unit(rng);
  for (std::size_t i = 0; i < n; ++i) {
    y[i] = 0.5 * x[i] + (i >= 1 ? 0.3 * x[i - 1] : 0.0) - (i >= 2 ? 0.2 * x[i - 2] : 0.0);
    y_noisy[i] = y[i] + 0.05 * unit(rng);
  }
  auto h_true = [&](double f) {
    const std::complex<double> z = std::polar(1.0, -2 * kPi * f / fs);
    return 0.5 + 0.3 * z - 0.2 * z * z;
  };
  const auto clean = ts::transfer_estimate(x, y, fs, {.segment = 512});
  const auto noisy = ts::transfer_estimate(x, y_noisy, fs, {.segment = 512});
  for (std::size_t k = 1; k + 1 < clean.freq_Hz.size(); ++k) {
    const auto ht = h_true(clean.freq_Hz[k]);
    // Noiseless linear system: H1 within 1 % and coherence ≥ 0.99 (the 2-sample delay costs a little
    // coherence through the window, ~(delay/segment)); H has a zero at Nyquist, where leakage from
    // neighbouring bins dominates, so coherence is checked where |H| > 0.2.
    EXPECT_NEAR(std::abs(clean.h1[k] - ht), 0.0, 0.01 * std::abs(ht) + 1e-3);
    if (std::abs(ht) > 0.2) {
      EXPECT_GT(clean.coherence[k], 0.99);
    }
    // With output noise (SNR set by |H|²·σx² / σn²): H1 unbiased, within 5 %; coherence matches the
    // theoretical |H|²/(|H|² + σn²) within 0.03.
    if (std::abs(ht) > 0.2) {
      EXPECT_NEAR(std::abs(noisy.h1[k] - ht), 0.0, 0.05 * std::abs(ht));
      const double g = std::norm(ht);
      EXPECT_NEAR(noisy.coherence[k], g / (g + 0.0025), 0.03);
    }
  }
  // csd is the same Pxy.
  const auto c = ts::csd(x, y, fs, {.segment = 512});
  EXPECT_NEAR(std::abs(c.csd[10] - clean.pxy[10]), 0.0, 1e-15);
}

// A sample whose square overflows a double would give an infinite spectrum that looks like power: refused.
TEST(Welch, SamplesTooLargeForTheirPowerAreRefused) {
  std::vector<double> x(256, 0.0);
  x[10] = 1e308;
  try {
    ts::welch(x, 1000.0, {.segment = 64});
    FAIL() << "no error";
  } catch (const tirstrain::Error& e) {
    EXPECT_NE(std::string(e.what()).find("reaches 1e+308"), std::string::npos) << e.what();
  }
  x[10] = 1e100;  // large, but its power is finite
  for (const double p : ts::welch(x, 1000.0, {.segment = 64}).psd) EXPECT_TRUE(std::isfinite(p));
}

TEST(Welch, SegmentErrorsNameTheParameter) {
  try {
    ts::welch(std::vector<double>(100, 1.0), 1.0, {.segment = 200});
    FAIL();
  } catch (const tirstrain::Error& e) {
    EXPECT_EQ(e.context().key, "segment");
  }
  EXPECT_THROW(ts::welch(std::vector<double>(100, 1.0), 1.0, {.segment = 64, .overlap = 64}),
               tirstrain::Error);
}

TEST(FindPeaks, HandComputedPeaksAndProminences) {
  const std::vector<double> x{0, 1, 0, 2, 2, 2, 0, 3, 1, 1.5, 0};
  const auto peaks = ts::find_peaks(x);
  ASSERT_EQ(peaks.size(), 4u);
  EXPECT_EQ(peaks[0].index, 1u);
  EXPECT_EQ(peaks[1].index, 4u);  // middle of the flat top 3..5
  EXPECT_EQ(peaks[2].index, 7u);
  EXPECT_EQ(peaks[3].index, 9u);
  EXPECT_DOUBLE_EQ(peaks[0].prominence, 1.0);
  EXPECT_DOUBLE_EQ(peaks[1].prominence, 2.0);
  EXPECT_DOUBLE_EQ(peaks[2].prominence, 3.0);
  EXPECT_DOUBLE_EQ(peaks[3].prominence, 0.5);
  EXPECT_EQ(peaks[3].left_base, 8u);
  EXPECT_EQ(peaks[3].right_base, 10u);
  const auto distant = ts::find_peaks(x, {.min_distance = 3});
  ASSERT_EQ(distant.size(), 3u);
  EXPECT_EQ(distant[2].index, 7u);
  const auto prominent = ts::find_peaks(x, {.min_prominence = 1.5});
  ASSERT_EQ(prominent.size(), 2u);
  EXPECT_EQ(prominent[0].index, 4u);
  const auto high = ts::find_peaks(x, {.min_height = 1.2});
  EXPECT_EQ(high.size(), 3u);
}
