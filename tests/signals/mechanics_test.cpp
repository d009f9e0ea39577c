// Impedance, spring–mass–damper fit and pad deformation from simulated records whose truth is known:
// a finger modelled as m = 0.029 kg, c = 2.1 N·s/m, k = 830 N/m driven by a repeated logarithmic sweep.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "signals/filter.hpp"
#include "signals/mechanics.hpp"

namespace ts = tirstrain::signals;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kM = 0.029, kC = 2.1, kK = 830.0;

// Logarithmic sweep f0→f1 over `period` seconds, repeated.
double sweep(double t, double f0, double f1, double period) {
  const double tau = std::fmod(t, period);
  const double rate = std::log(f1 / f0) / period;
  return std::sin(2 * kPi * f0 * (std::exp(rate * tau) - 1.0) / rate);
}

struct Response {
  std::vector<double> force, disp, vel, accel;
};

// RK4 on m x'' + c x' + k x = F(t), F evaluated exactly at the sub-steps; acceleration from the equation
// of motion at each sample.
template <typename Force>
Response simulate(Force force, double fs, std::size_t n, double m, double c, double k) {
  Response r;
  const double dt = 1.0 / fs;
  double x = 0.0, v = 0.0;
  auto acc = [&](double t, double xx, double vv) { return (force(t) - c * vv - k * xx) / m; };
  for (std::size_t i = 0; i < n; ++i) {
    const double t = i * dt;
    r.force.push_back(force(t));
    r.disp.push_back(x);
    r.vel.push_back(v);
    r.accel.push_back(acc(t, x, v));
    const double k1x = v, k1v = acc(t, x, v);
    const double k2x = v + 0.5 * dt * k1v, k2v = acc(t + 0.5 * dt, x + 0.5 * dt * k1x, v + 0.5 * dt * k1v);
    const double k3x = v + 0.5 * dt * k2v, k3v = acc(t + 0.5 * dt, x + 0.5 * dt * k2x, v + 0.5 * dt * k2v);
    const double k4x = v + dt * k3v, k4v = acc(t + dt, x + dt * k3x, v + dt * k3v);
    x += dt / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
    v += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
  }
  return r;
}

// The simulated finger's impedance Z = F/V = c + j(ωm − k/ω), N·s/m.
std::complex<double> finger_truth(double omega) {
  return {kC, omega * kM - kK / omega};
}

void add_noise(std::vector<double>& v, double fraction, std::mt19937_64& rng) {
  double rms = 0.0;
  for (double x : v) rms += x * x;
  rms = std::sqrt(rms / static_cast<double>(v.size()));
  std::normal_distribution<double> g(0.0, fraction * rms);
  for (double& x : v) x += g(rng);
}

}  // namespace

TEST(Mechanics, MckFitFromNoisySweepWithinTwoPercent) {
  const double fs = 5000.0;
  auto r = simulate([](double t) { return 0.5 * sweep(t, 5.0, 300.0, 2.0); }, fs, 100000, kM, kC, kK);
  std::mt19937_64 rng(42);
  add_noise(r.force, 0.01, rng);
  add_noise(r.accel, 0.01, rng);
  const auto fit =
      ts::fit_mass_spring_damper(r.force, r.accel, fs, {.segment = 4096},
                                 {.band_low_Hz = 5.0, .band_high_Hz = 250.0, .min_coherence = 0.9});
  EXPECT_NEAR(fit.mck.k_N_m, kK, 0.02 * kK);
  EXPECT_NEAR(fit.mck.c_Ns_m, kC, 0.02 * kC);
  EXPECT_NEAR(fit.mck.m_kg, kM, 0.02 * kM);
  EXPECT_GT(fit.frequencies_used, 100u);
  EXPECT_NEAR(fit.mck.natural_frequency_Hz(), std::sqrt(kK / kM) / (2 * kPi), 0.02 * 27.0);
}

TEST(Mechanics, FingerImpedanceIsLoadedMinusUnloaded) {
  // A 10 g plate alone (Z = jω m_p) and with the finger attached (Z = jω m_p + c + j(ωm − k/ω)).
  const double fs = 5000.0, mp = 0.010;
  auto f = [](double t) { return sweep(t, 20.0, 400.0, 2.0); };
  const auto plate = simulate(f, fs, 60000, mp, 0.0, 0.0);
  const auto loaded = simulate(f, fs, 60000, mp + kM, kC, kK);
  const ts::WelchOptions w{.segment = 2048};
  const auto zu = ts::mechanical_impedance(plate.force, plate.accel, fs, w);
  const auto zl = ts::mechanical_impedance(loaded.force, loaded.accel, fs, w);
  const auto finger = ts::finger_impedance(zl, &zu);
  int checked = 0;
  for (std::size_t i = 0; i < finger.freq_Hz.size(); ++i) {
    const double fr = finger.freq_Hz[i];
    if (fr < 40.0 || fr > 350.0) continue;
    const double omega = 2 * kPi * fr;
    const std::complex<double> truth = finger_truth(omega);
    EXPECT_NEAR(std::abs(finger.z_Ns_m[i] - truth), 0.0, 0.02 * std::abs(truth)) << fr;
    EXPECT_NEAR(finger.mass_kg[i], kM - kK / (omega * omega), 0.02 * std::abs(truth) / omega);
    EXPECT_NEAR(finger.damping_Ns_m[i], kC, 0.02 * std::abs(truth));
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(Mechanics, VelocityChannelGivesTheSameImpedanceAsAcceleration) {
  const double fs = 5000.0;
  const auto r = simulate([](double t) { return sweep(t, 20.0, 400.0, 2.0); }, fs, 60000, kM, kC, kK);
  const ts::WelchOptions w{.segment = 2048};
  const auto from_accel = ts::mechanical_impedance(r.force, r.accel, fs, w);
  const auto from_velocity = ts::mechanical_impedance(r.force, r.vel, fs, w, ts::MotionKind::velocity_m_s);
  int checked = 0;
  for (std::size_t i = 0; i < from_accel.freq_Hz.size(); ++i) {
    const double fr = from_accel.freq_Hz[i];
    if (fr < 40.0 || fr > 350.0) continue;
    const double omega = 2 * kPi * fr;
    const std::complex<double> truth = finger_truth(omega);
    EXPECT_NEAR(std::abs(from_velocity.z_Ns_m[i] - truth), 0.0, 0.02 * std::abs(truth)) << fr;
    EXPECT_NEAR(std::abs(from_velocity.z_Ns_m[i] - from_accel.z_Ns_m[i]), 0.0, 0.02 * std::abs(truth)) << fr;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(Mechanics, NarrowBandTradesStiffnessForMassAndSaysSoAFixedStiffnessResolvesIt) {
  const double fs = 5000.0;
  auto r = simulate([](double t) { return 0.5 * sweep(t, 5.0, 300.0, 2.0); }, fs, 100000, kM, kC, kK);
  std::mt19937_64 rng(7);
  add_noise(r.force, 0.01, rng);
  add_noise(r.accel, 0.01, rng);
  const ts::WelchOptions w{.segment = 4096};
  const auto wide =
      ts::fit_mass_spring_damper(r.force, r.accel, fs, w, {.band_low_Hz = 5.0, .band_high_Hz = 250.0});
  EXPECT_LT(std::abs(wide.m_k_correlation), ts::kMassStiffnessCorrelationLimit);
  EXPECT_LT(wide.m_sd_kg, 0.02 * kM);
  // 150-200 Hz, well above the 27 Hz resonance: k − mω² changes little, the estimates move together.
  const auto narrow =
      ts::fit_mass_spring_damper(r.force, r.accel, fs, w, {.band_low_Hz = 150.0, .band_high_Hz = 200.0});
  EXPECT_GT(std::abs(narrow.m_k_correlation), ts::kMassStiffnessCorrelationLimit);
  EXPECT_GT(narrow.k_sd_N_m, 5 * wide.k_sd_N_m);
  // The true error of m is of the order of its reported standard deviation.
  EXPECT_LT(std::abs(narrow.mck.m_kg - kM), 4 * narrow.m_sd_kg + 0.01 * kM);
  ts::MckFitOptions fixed{.band_low_Hz = 150.0, .band_high_Hz = 200.0};
  fixed.fixed_stiffness_N_m = kK;
  const auto held = ts::fit_mass_spring_damper(r.force, r.accel, fs, w, fixed);
  EXPECT_TRUE(held.stiffness_fixed);
  EXPECT_EQ(held.mck.k_N_m, kK);
  EXPECT_NEAR(held.mck.m_kg, kM, 0.02 * kM);
  EXPECT_NEAR(held.mck.c_Ns_m, kC, 0.05 * kC);
  EXPECT_EQ(held.m_k_correlation, 0.0);
}

TEST(Mechanics, MassAndDamperAloneWithStiffnessFixedAtZero) {
  // The vibrating-plate finger model without a spring: F = m a + c v.
  const double fs = 5000.0, m = 0.012, c = 3.5;
  const auto r = simulate([](double t) { return sweep(t, 50.0, 500.0, 2.0); }, fs, 60000, m, c, 0.0);
  ts::MckFitOptions o{.band_low_Hz = 60.0, .band_high_Hz = 450.0};
  o.fixed_stiffness_N_m = 0.0;
  const auto fit = ts::fit_mass_spring_damper(r.force, r.accel, fs, {.segment = 2048}, o);
  EXPECT_NEAR(fit.mck.m_kg, m, 0.01 * m);
  EXPECT_NEAR(fit.mck.c_Ns_m, c, 0.02 * c);
  EXPECT_EQ(fit.mck.k_N_m, 0.0);
}

TEST(Mechanics, PadTransferCalibrationAndBothDisplacementEstimatesAgree) {
  const double fs = 5000.0;
  const std::size_t n = 100000;
  // Calibration sweep: the side accelerometer sees the pad through a known 2nd-order low-pass (G1).
  const auto g1 = ts::butterworth_sos({ts::FilterType::lowpass, 2, 300.0, 0.0, fs});
  std::vector<double> pad(n);
  for (std::size_t i = 0; i < n; ++i) pad[i] = sweep(i / fs, 10.0, 800.0, 2.0);
  const auto side = ts::sosfilt(g1, pad);
  const auto cal = ts::calibrate_pad_transfer(pad, side, fs, {.segment = 2048}, 0.95);
  EXPECT_LE(cal.band_low_Hz, 15.0);
  EXPECT_GE(cal.band_high_Hz, 700.0);
  for (std::size_t i = 0; i < cal.freq_Hz.size(); ++i) {
    // Outside the swept 10–800 Hz the noiseless record is still coherent but carries no energy.
    if (!cal.valid[i] || cal.freq_Hz[i] < 15.0 || cal.freq_Hz[i] > 750.0) continue;
    const auto truth = ts::frequency_response(g1, cal.freq_Hz[i], fs);
    EXPECT_NEAR(std::abs(cal.g1[i] - truth), 0.0, 0.02 * std::abs(truth)) << cal.freq_Hz[i];
  }
  // Trial: force drives the pad through G2; the side accelerometer records G1 · pad acceleration.
  const ts::MassSpringDamper mck{kM, kC, kK};
  const auto r = simulate([](double t) { return 0.3 * sweep(t, 10.0, 600.0, 2.0); }, fs, n, kM, kC, kK);
  const auto side_trial = ts::sosfilt(g1, r.accel);
  const ts::WelchOptions w{.segment = 2048};
  const auto side_psd = ts::welch(side_trial, fs, w);
  const auto force_psd = ts::welch(r.force, fs, w);
  const auto xp_side = ts::pad_displacement_psd_from_side(cal, side_psd.psd);
  const auto xp_force = ts::pad_displacement_psd_from_force(force_psd.freq_Hz, force_psd.psd, mck);
  const auto xp_true = ts::welch(r.disp, fs, w);
  for (const auto& [lo, hi] :
       std::vector<std::pair<double, double>>{{20, 50}, {50, 100}, {100, 200}, {200, 400}}) {
    const double rs = ts::band_rms(side_psd.freq_Hz, xp_side, lo, hi);
    const double rf = ts::band_rms(force_psd.freq_Hz, xp_force, lo, hi);
    const double rt = ts::band_rms(xp_true.freq_Hz, xp_true.psd, lo, hi);
    EXPECT_NEAR(rs, rt, 0.05 * rt) << lo;
    EXPECT_NEAR(rf, rt, 0.05 * rt) << lo;
  }
}

TEST(Mechanics, FitNeedsCoherentBins) {
  std::vector<double> f(4096, 0.0), a(4096, 0.0);
  EXPECT_THROW(ts::fit_mass_spring_damper(f, a, 1000.0, {.segment = 512}, {}), tirstrain::Error);
}
