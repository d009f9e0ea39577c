// Butterworth design and zero-phase filtering against closed-form truth: published/analytic coefficients,
// the bilinear-transform Butterworth magnitude |H|² = 1/(1 + r^{2N}), and signals whose filtered form is
// known exactly (sinusoids scaled by |H|² with no phase shift, constants, ramps).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/error.hpp"
#include "signals/filter.hpp"

namespace ts = tirstrain::signals;
using ts::ButterworthSpec;
using ts::FilterType;

namespace {
constexpr double kPi = std::numbers::pi;
std::vector<double> sine(std::size_t n, double fs, double f, double amp = 1.0) {
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = amp * std::sin(2 * kPi * f * static_cast<double>(i) / fs);
  return x;
}
}  // namespace

TEST(Butterworth, SecondOrderQuarterNyquistMatchesAnalyticCoefficients) {
  // Ω = tan(π/4) = 1: H(s) = 1/(s² + √2 s + 1) through the bilinear transform gives b = [1,2,1]/(2+√2),
  // a = [1, 0, (2−√2)/(2+√2)] (scipy.signal.butter(2, 0.5) prints the same numbers).
  const auto tf = ts::butterworth_ba({FilterType::lowpass, 2, 250.0, 0.0, 1000.0});
  const double s2 = std::sqrt(2.0);
  ASSERT_EQ(tf.b.size(), 3u);
  EXPECT_NEAR(tf.b[0], 1.0 / (2.0 + s2), 1e-14);
  EXPECT_NEAR(tf.b[1], 2.0 / (2.0 + s2), 1e-14);
  EXPECT_NEAR(tf.b[2], 1.0 / (2.0 + s2), 1e-14);
  EXPECT_NEAR(tf.a[0], 1.0, 0.0);
  EXPECT_NEAR(tf.a[1], 0.0, 1e-14);
  EXPECT_NEAR(tf.a[2], (2.0 - s2) / (2.0 + s2), 1e-14);
}

TEST(Butterworth, FirstOrderLowAndHighPassCoefficients) {
  const double fs = 1000.0, fc = 80.0;
  const double k = std::tan(kPi * fc / fs);
  const auto lp = ts::butterworth_ba({FilterType::lowpass, 1, fc, 0.0, fs});
  EXPECT_NEAR(lp.b[0], k / (1 + k), 1e-14);
  EXPECT_NEAR(lp.b[1], k / (1 + k), 1e-14);
  EXPECT_NEAR(lp.a[1], (k - 1) / (k + 1), 1e-14);
  const auto hp = ts::butterworth_ba({FilterType::highpass, 1, fc, 0.0, fs});
  EXPECT_NEAR(hp.b[0], 1 / (1 + k), 1e-14);
  EXPECT_NEAR(hp.b[1], -1 / (1 + k), 1e-14);
  EXPECT_NEAR(hp.a[1], (k - 1) / (k + 1), 1e-14);
}

TEST(Butterworth, MagnitudeMatchesClosedFormForAllTypesAndOrders) {
  const std::vector<ButterworthSpec> specs = {
      {FilterType::lowpass, 4, 80.0, 0.0, 1000.0},   // the paper's force filter
      {FilterType::lowpass, 7, 300.0, 0.0, 1000.0},  // odd order
      {FilterType::highpass, 3, 20.0, 0.0, 1000.0},
      {FilterType::bandpass, 4, 15.0, 500.0, 5000.0},   // accelerometer band
      {FilterType::bandpass, 3, 100.0, 120.0, 2000.0},  // narrow, odd
      {FilterType::lowpass, 12, 1.0, 0.0, 1000.0},      // high order far below Nyquist: needs SOS
  };
  for (const auto& spec : specs) {
    const auto sos = ts::butterworth_sos(spec);
    EXPECT_EQ(sos.order, spec.type == FilterType::bandpass ? 2 * spec.order : spec.order);
    for (double f = 0.0; f < 0.5 * spec.sample_rate_Hz; f += spec.sample_rate_Hz / 997.0) {
      const double expected = ts::butterworth_power_response(spec, f);
      const double got = std::norm(ts::frequency_response(sos, f, spec.sample_rate_Hz));
      EXPECT_NEAR(got, expected, 1e-9 + 1e-7 * expected) << "order " << spec.order << " f " << f;
    }
    // -3 dB exactly at the cutoff(s) thanks to pre-warping.
    EXPECT_NEAR(std::norm(ts::frequency_response(sos, spec.cutoff_Hz, spec.sample_rate_Hz)), 0.5, 1e-10);
    if (spec.type == FilterType::bandpass) {
      EXPECT_NEAR(std::norm(ts::frequency_response(sos, spec.cutoff2_Hz, spec.sample_rate_Hz)), 0.5, 1e-10);
    }
  }
}

TEST(Butterworth, SosAndPolynomialFormsAgree) {
  const ButterworthSpec spec{FilterType::bandpass, 2, 15.0, 200.0, 1000.0};
  const auto sos = ts::butterworth_sos(spec);
  const auto tf = ts::butterworth_ba(spec);
  for (double f = 1.0; f < 500.0; f += 7.0) {
    const auto a = ts::frequency_response(sos, f, 1000.0);
    const auto b = ts::frequency_response(tf, f, 1000.0);
    EXPECT_NEAR(std::abs(a - b), 0.0, 1e-11);
  }
}

TEST(Butterworth, RejectsBadSpecsWithTheParameterNamed) {
  try {
    ts::butterworth_sos({FilterType::lowpass, 4, 600.0, 0.0, 1000.0});
    FAIL();
  } catch (const tirstrain::Error& e) {
    EXPECT_EQ(e.context().key, "cutoff_Hz");
    EXPECT_NE(std::string(e.what()).find("Nyquist"), std::string::npos);
  }
  EXPECT_THROW(ts::butterworth_sos({FilterType::lowpass, 0, 10.0, 0.0, 1000.0}), tirstrain::Error);
  EXPECT_THROW(ts::butterworth_sos({FilterType::bandpass, 2, 50.0, 20.0, 1000.0}), tirstrain::Error);
}

TEST(Filtfilt, SinusoidsScaledByPowerResponseWithZeroPhase) {
  // The paper's 4th-order 80 Hz low-pass at 1 kHz. filtfilt's response is |H|², real and positive: a
  // sinusoid keeps its phase exactly and is scaled by |H(f)|². Compared away from the edges (0.3 s, ≫ the
  // filter's ~5 ms time constant), where the padding transient has died out.
  const double fs = 1000.0;
  const ButterworthSpec spec{FilterType::lowpass, 4, 80.0, 0.0, fs};
  const std::size_t n = 3000;
  const auto a = sine(n, fs, 10.0, 1.0), b = sine(n, fs, 75.0, 0.7), c = sine(n, fs, 200.0, 0.5);
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = a[i] + b[i] + c[i];
  const auto y = ts::butterworth_filtfilt(x, spec);
  const double g10 = ts::butterworth_power_response(spec, 10.0),
               g75 = ts::butterworth_power_response(spec, 75.0),
               g200 = ts::butterworth_power_response(spec, 200.0);
  double max_err = 0.0;
  for (std::size_t i = 300; i < n - 300; ++i)
    max_err = std::max(max_err, std::abs(y[i] - (g10 * a[i] + g75 * b[i] + g200 * c[i])));
  EXPECT_LT(max_err, 1e-8);
}

TEST(Filtfilt, BandPassPreservesPhaseAtCentre) {
  const double fs = 5000.0;
  const ButterworthSpec spec{FilterType::bandpass, 4, 15.0, 500.0, fs};
  const auto x = sine(20000, fs, 120.0);
  const auto y = ts::butterworth_filtfilt(x, spec);
  const double g = ts::butterworth_power_response(spec, 120.0);
  for (std::size_t i = 5000; i < 15000; ++i) ASSERT_NEAR(y[i], g * x[i], 1e-8);
}

TEST(Filtfilt, ConstantsAndRampsPassExactly) {
  // Odd extension + steady-state initial conditions: a constant passes a unit-DC-gain low-pass untouched
  // everywhere (edges included), a high-pass removes it; a ramp's interior is unchanged (the forward and
  // backward group delays cancel).
  const double fs = 1000.0;
  const std::vector<double> constant(500, 3.25);
  const auto lp = ts::butterworth_filtfilt(constant, {FilterType::lowpass, 4, 80.0, 0.0, fs});
  for (double v : lp) ASSERT_NEAR(v, 3.25, 1e-12);
  const auto hp = ts::butterworth_filtfilt(constant, {FilterType::highpass, 2, 5.0, 0.0, fs});
  for (double v : hp) ASSERT_NEAR(v, 0.0, 1e-12);
  std::vector<double> ramp(2000);
  for (std::size_t i = 0; i < ramp.size(); ++i) ramp[i] = 0.01 * static_cast<double>(i) - 4.0;
  const auto yr = ts::butterworth_filtfilt(ramp, {FilterType::lowpass, 4, 80.0, 0.0, fs});
  for (std::size_t i = 200; i < 1800; ++i) ASSERT_NEAR(yr[i], ramp[i], 1e-9);
}

TEST(Filtfilt, PaddingFollowsScipyDefault) {
  // padlen = 3·max(len(a), len(b)) = 3·(order + 1) for filtfilt, and the same for sosfiltfilt.
  const double fs = 1000.0;
  const auto lp4 = ts::butterworth_sos({FilterType::lowpass, 4, 80.0, 0.0, fs});
  const auto lp3 = ts::butterworth_sos({FilterType::lowpass, 3, 80.0, 0.0, fs});
  const auto bp4 = ts::butterworth_sos({FilterType::bandpass, 4, 15.0, 300.0, fs});
  EXPECT_EQ(ts::default_padlen(lp4), 15u);
  EXPECT_EQ(ts::default_padlen(lp3), 12u);
  EXPECT_EQ(ts::default_padlen(bp4), 27u);
  EXPECT_EQ(ts::default_padlen(ts::butterworth_ba({FilterType::lowpass, 4, 80.0, 0.0, fs})), 15u);
  EXPECT_THROW(ts::filtfilt(lp4, std::vector<double>(15, 1.0)), tirstrain::Error);
  EXPECT_NO_THROW(ts::filtfilt(lp4, std::vector<double>(16, 1.0)));
}

TEST(Filtfilt, SosAndPolynomialPathsGiveTheSameSignal) {
  const double fs = 1000.0;
  const ButterworthSpec spec{FilterType::lowpass, 4, 80.0, 0.0, fs};
  std::vector<double> x(700);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::sin(0.05 * i) + 0.3 * std::cos(0.9 * i) + 0.001 * i;
  const auto a = ts::filtfilt(ts::butterworth_sos(spec), x);
  const auto b = ts::filtfilt(ts::butterworth_ba(spec), x);
  for (std::size_t i = 0; i < x.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-10);
}

TEST(Filtfilt, ZiGivesSteadyStateForAStep) {
  const auto sos = ts::butterworth_sos({FilterType::lowpass, 5, 50.0, 0.0, 1000.0});
  const auto zi = ts::sosfilt_zi(sos);
  const auto y = ts::sosfilt(sos, std::vector<double>(100, 1.0), &zi);
  for (double v : y) ASSERT_NEAR(v, 1.0, 1e-12);
  const auto tf = ts::butterworth_ba({FilterType::lowpass, 3, 50.0, 0.0, 1000.0});
  const auto zi2 = ts::lfilter_zi(tf);
  const auto y2 = ts::lfilter(tf, std::vector<double>(100, 1.0), &zi2);
  for (double v : y2) ASSERT_NEAR(v, 1.0, 1e-12);
}
