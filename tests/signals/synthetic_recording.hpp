#pragma once
// A synthetic force recording of a finger on a tribometer with known phase times and μ: approach (no
// contact), press (W rises linearly), strokes (F_t follows the Cattaneo–Mindlin loading curve to μW, slides
// at a μ that wanders along the slide, then falls back linearly as the plate stops, directions
// alternating), release (W falls linearly), no contact to the end. The DAQ adds an offset and a linear drift
// to each channel, Gaussian noise and quantisation to its least significant bit.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace tirstrain::signals::testing {

struct SynthRecording {
  double fs_Hz = 2000.0, duration_s = 8.5;
  double contact_s = 2.5, loaded_s = 3.0, release_s = 7.41, contact_end_s = 7.61;
  double load_N = 1.5;
  int strokes = 1;
  double first_stroke_s = 3.4;      // first tangential loading starts here
  double loading_s = 0.1;           // Cattaneo–Mindlin rise to full slip
  double unload_s = 0.08;           // F_t falls back when the plate stops
  double gap_s = 0.05;              // between one stroke's unload and the next loading
  bool slide_into_release = false;  // the last slide runs until the finger lifts
  std::vector<double> mu{0.31, 0.36, 0.28, 0.40, 0.33};
  double mu_wander = 0.04;          // relative amplitude of μ's slow change along a slide
  double mu_wander_period_s = 0.0;  // its period; 0: one period over each slide
  double offset_normal_N = 0.21, offset_tangential_N = -0.13;
  double drift_normal_N_s = 0.004, drift_tangential_N_s = 0.02;
  double noise_N = 0.004, lsb_N = 0.002;
  int normal_sign = 1;  // −1: the DAQ's normal channel goes negative on pressing
  double speed_m_s = 0.01;
  unsigned seed = 7;
};

struct StrokeTruth {
  double slide_start_s, slide_end_s, mu_mean;
  int direction;
};

struct SynthOutput {
  std::vector<double> t_s, normal_N, tangential_N, position_m;  // as recorded
  std::vector<double> true_normal_N, true_tangential_N;
  std::vector<StrokeTruth> strokes;
};

inline SynthOutput synthesise(const SynthRecording& c) {
  // Stroke k: loading from a_k, full slip at s_k = a_k + loading_s, slide to e_k, unloaded at e_k + unload_s.
  const double region = c.release_s - c.first_stroke_s;
  const double slot = region / c.strokes;
  std::vector<double> a, e;
  for (int k = 0; k < c.strokes; ++k) {
    a.push_back(c.first_stroke_s + k * slot);
    const bool last = k + 1 == c.strokes;
    e.push_back(last && c.slide_into_release ? c.release_s
                                             : a.back() + slot - c.unload_s - c.gap_s - (last ? 0.1 : 0.0));
  }
  const auto w_of = [&](double t) {
    if (t < c.contact_s) return 0.0;
    if (t < c.loaded_s) return c.load_N * (t - c.contact_s) / (c.loaded_s - c.contact_s);
    if (t < c.release_s) return c.load_N;
    if (t < c.contact_end_s) return c.load_N * (c.contact_end_s - t) / (c.contact_end_s - c.release_s);
    return 0.0;
  };
  const auto mu_of = [&](int k, double t) {
    const double s = a[k] + c.loading_s;
    return c.mu[static_cast<std::size_t>(k) % c.mu.size()] *
           (1.0 + c.mu_wander * std::sin(2.0 * std::numbers::pi * (t - s) /
                                         (c.mu_wander_period_s > 0.0 ? c.mu_wander_period_s : e[k] - s)));
  };
  const auto ft_of = [&](double t) {
    for (int k = c.strokes - 1; k >= 0; --k) {
      if (t < a[k]) continue;
      const double dir = k % 2 == 0 ? 1.0 : -1.0;
      const double s = a[k] + c.loading_s;
      if (t < s) {
        const double u = (t - a[k]) / c.loading_s;
        return dir * mu_of(k, s) * w_of(t) * (1.0 - std::pow(1.0 - u, 1.5));
      }
      if (t <= e[k] || (k + 1 == c.strokes && c.slide_into_release))
        return dir * mu_of(k, std::min(t, e[k])) * w_of(t);
      if (t < e[k] + c.unload_s) return dir * mu_of(k, e[k]) * w_of(t) * (1.0 - (t - e[k]) / c.unload_s);
      return 0.0;
    }
    return 0.0;
  };
  SynthOutput out;
  std::mt19937_64 rng(c.seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const auto daq = [&](double v) { return std::round((v + c.noise_N * g(rng)) / c.lsb_N) * c.lsb_N; };
  double x = 0.0;
  const auto n = static_cast<std::size_t>(std::lround(c.duration_s * c.fs_Hz)) + 1;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / c.fs_Hz;
    const double w = w_of(t), ft = ft_of(t);
    out.t_s.push_back(t);
    out.true_normal_N.push_back(w);
    out.true_tangential_N.push_back(ft);
    out.normal_N.push_back(daq(c.normal_sign * w + c.offset_normal_N + c.drift_normal_N_s * t));
    out.tangential_N.push_back(daq(ft + c.offset_tangential_N + c.drift_tangential_N_s * t));
    for (int k = 0; k < c.strokes; ++k)
      if (t > a[k] && t <= e[k]) x += (k % 2 == 0 ? 1.0 : -1.0) * c.speed_m_s / c.fs_Hz;
    out.position_m.push_back(x);
  }
  for (int k = 0; k < c.strokes; ++k) {
    const double s = a[k] + c.loading_s, end = std::min(e[k], c.release_s);
    double sum = 0.0;
    int count = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (out.t_s[i] >= s && out.t_s[i] <= end) {
        sum += out.true_tangential_N[i] / out.true_normal_N[i];
        ++count;
      }
    out.strokes.push_back({s, end, sum / count, k % 2 == 0 ? 1 : -1});
  }
  return out;
}

}  // namespace tirstrain::signals::testing
