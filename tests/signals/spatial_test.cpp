// Spatial resampling: a texture of wavelength λ scanned at a changing speed gives one spatial peak at 1/λ.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.hpp"
#include "signals/spatial.hpp"

namespace ts = tirstrain::signals;

TEST(Spatial, AcceleratingStrokeGivesPeakAtInverseWavelength) {
  const double fs = 10000.0, lambda = 0.5e-3;
  std::vector<double> t, x, f;
  for (int i = 0; i < 40000; ++i) {
    const double ti = i / fs;
    const double xi = 0.02 * ti + 0.01 * ti * ti;  // 20 → 100 mm/s
    t.push_back(ti);
    x.push_back(xi);
    f.push_back(0.2 + 0.05 * std::sin(2 * std::numbers::pi * xi / lambda));
  }
  const auto s = ts::to_spatial_domain(t, x, f);
  EXPECT_NEAR(s.mean_speed_m_s, (x.back() - x.front()) / (t.back() - t.front()), 1e-12);
  // Peak speed over the last 20 ms window: v(t) = 0.02 + 0.02 t at its middle, t ≈ 3.99 s (to a sample or
  // two of the window's placement, 2e-6 m/s each); the mean speed is 0.06 m/s.
  EXPECT_NEAR(s.peak_speed_m_s, 0.02 + 0.02 * 3.99, 1e-5);
  const auto spec = ts::spatial_spectrum(s, {.segment = 8192});
  const auto k =
      static_cast<std::size_t>(std::max_element(spec.psd.begin() + 1, spec.psd.end()) - spec.psd.begin());
  std::vector<double> log_psd(spec.psd.size());
  for (std::size_t i = 0; i < log_psd.size(); ++i) log_psd[i] = std::log(spec.psd[i] + 1e-300);
  const double nu =
      ts::parabolic_peak_index(log_psd, k) * (spec.spatial_freq_per_m[1] - spec.spatial_freq_per_m[0]);
  EXPECT_NEAR(nu, 1.0 / lambda, 0.01 / lambda);
  // The resampled force is the texture itself, sample for sample (linear interpolation error only).
  for (std::size_t j = 0; j < s.x_m.size(); j += 97)
    ASSERT_NEAR(s.values[j], 0.2 + 0.05 * std::sin(2 * std::numbers::pi * s.x_m[j] / lambda), 2e-4);
}

TEST(Spatial, ReversalIsReportedWithTheSample) {
  const std::vector<double> t{0, 1, 2, 3, 4}, x{0, 1, 2, 1.5, 3}, f{0, 0, 0, 0, 0};
  try {
    ts::to_spatial_domain(t, x, f);
    FAIL();
  } catch (const tirstrain::Error& e) {
    EXPECT_NE(e.message().find("reverses at sample 3"), std::string::npos);
  }
}
