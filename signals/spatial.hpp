#pragma once
// Texture vibration in the spatial domain: a force recorded while the plate slides is a function of the
// plate position, so resampling it uniformly in x (through the position channel) turns speed changes
// into nothing and a texture of wavelength λ into a spatial-spectrum peak at 1/λ, whatever the speed.
// The temporal frequency it produces at speed v is v/λ (model/texture_interaction.hpp predicts it).
#include <cstddef>
#include <vector>

#include "signals/spectral.hpp"

namespace tirstrain::signals {

struct SpatialSeries {
  std::vector<double> x_m;      // uniform grid, increasing or decreasing with the stroke
  std::vector<double> values;   // the channel linearly interpolated at x_m
  double dx_m = 0.0;            // grid step (positive)
  double mean_speed_m_s = 0.0;  // |Δx| / Δt over the stroke
  double peak_speed_m_s = 0.0;  // largest |Δx| / Δt over any window of speed_window_s within the stroke
};

// Position must move strictly one way over [begin, end) (samples); a stall or reversal is an Error naming
// the sample. dx_m <= 0 picks the median |Δx| of the stroke. The peak speed is taken over windows of
// speed_window_s (at least one sample interval) so that position noise does not make it.
SpatialSeries to_spatial_domain(const std::vector<double>& time_s, const std::vector<double>& position_m,
                                const std::vector<double>& values, double dx_m = 0.0, std::size_t begin = 0,
                                std::size_t end = static_cast<std::size_t>(-1), double speed_window_s = 0.02);

struct SpatialSpectrum {
  std::vector<double> spatial_freq_per_m;  // cycles per metre
  std::vector<double> psd;                 // units² · m (density per cycle/m)
  double mean_speed_m_s = 0.0;
  double peak_speed_m_s = 0.0;
};

// Welch (SciPy conventions, see spectral.hpp) with "sample rate" 1/dx.
SpatialSpectrum spatial_spectrum(const SpatialSeries& series, const WelchOptions& options);

}  // namespace tirstrain::signals
