#pragma once
// Textures evaluated as smooth analytic functions at arbitrary (sub-pixel) coordinates, never interpolated
// from a raster: the renderer samples them exactly at the inverted reference position of every pixel, so
// the only difference between the truth and what a tracker can see is the field itself.
#include <cstdint>
#include <vector>

#include "core/tensor2.hpp"
#include "samples/synth_config.hpp"

namespace tirstrain::samples {

// Deterministic 64-bit mixing (splitmix64) for seeding per-cell and per-frame random streams.
std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b);

// Random dots printed on the glass: a jittered lattice of Gaussian dots, combined as 1 - exp(-sum) so
// overlapping dots saturate smoothly. Infinite in extent; evaluated at plate coordinates.
class PlatePattern {
 public:
  PlatePattern(const PatternConfig& config, double px_per_mm, std::uint64_t seed);
  double darkness(Vec2 p_px) const;  // in [0, 1)

 private:
  double spacing_px_ = 1.0;
  double inv_two_sigma2_ = 1.0;
  double fill_ = 0.7;
  std::uint64_t seed_ = 0;
};

// A synthetic fingerprint in reference coordinates: cos(phase) with
//   phase = 2 pi rho(p) / lambda + sum over minutia pairs of w(r) * angle(p - a, p - b),
// where rho is a smoothed distance to the loop's axis segment (the core sits at its end; an optional second
// centre makes a triradius (delta) at the saddle between them), p is warped by a few long-wavelength sines so
// the flow curves naturally, and each minutia pair (a, b) adds a ridge ending and a bifurcation. The pair
// term is windowed smoothly to zero a few periods away so each pixel sums only nearby pairs; the window is
// exactly 1 on the pair's branch cut, where the angle jumps by 2 pi, so cos(phase) stays continuous. Contrast
// falls to zero right at each minutia point, where the phase is singular.
// Sweat pores multiply the ridge level by 1 - pore_depth * dots(X) (Gaussian dots on a jittered lattice, 60 %
// of the sites): dots of lost contrast on the ridges, invisible in the valleys. They give a small patch 2-D
// texture, which ridges alone (locally 1-D) do not.
class Fingerprint {
 public:
  Fingerprint(const FingerprintConfig& config, double px_per_mm, double period_mm, Vec2 core_px,
              Vec2 extent_px, std::uint64_t seed);
  // Ridge indicator in [0, 1]; 1 on a ridge crest.
  double ridge(Vec2 X_px) const;
  // Gradient of the phase (rad/px) by central differences, h = 1e-3 px, each difference wrapped to
  // (-pi, pi] so the 2 pi jump on a minutia pair's branch cut does not enter (relative error << 1e-6).
  Vec2 phase_gradient(Vec2 X_px) const;
  // Ridge direction at X in reference coordinates: perpendicular to the phase gradient, from +x towards +y,
  // in [0, pi). Ridges run along it; it is undefined (0) where the gradient vanishes. Pores do not change it.
  double ridge_orientation_rad(Vec2 X_px) const;
  std::size_t minutia_pairs() const { return pairs_.size(); }

 private:
  // cos(phase) times amplitude (which falls to 0 at each minutia point) is the ridge pattern.
  double phase(Vec2 X_px, double& amplitude) const;
  struct Pair {
    Vec2 a, b, mid;
    double sign = 1.0;
    double inner_px = 0.0, outer_px = 0.0;
  };
  double wavenumber_ = 0.0;  // 2 pi / period, rad/px
  double period_px_ = 0.0;
  Vec2 core_px_;
  double axis_cos_ = 0.0, axis_sin_ = 1.0;
  double loop_length_px_ = 0.0;
  double core_smoothing_px_ = 0.0;
  bool has_delta_ = false;
  Vec2 second_centre_local_;  // in axis-aligned coordinates relative to the core
  double softmin_px_ = 0.0;
  double warp_amplitude_px_[4] = {};
  Vec2 warp_wavevector_[4];
  double warp_phase_[4] = {};
  double minutia_core_px_ = 0.0;
  double pore_depth_ = 0.0;
  PlatePattern pores_;
  std::vector<Pair> pairs_;
  // Spatial bins of pair indices so a lookup touches only the pairs whose support covers the pixel.
  Vec2 bin_origin_px_;
  double bin_size_px_ = 1.0;
  int bins_x_ = 0, bins_y_ = 0;
  std::vector<std::vector<int>> bins_;
};

// Sweat blobs attached to the skin: patches where ridges lose contrast.
class SweatBlobs {
 public:
  SweatBlobs(const SweatConfig& config, double px_per_mm, Vec2 centre_px, Vec2 semi_axes_px,
             std::uint64_t seed);
  double contrast_factor(Vec2 X_px) const;  // in [1 - depth, 1]

 private:
  struct Blob {
    Vec2 centre;
    double inv_two_sigma2 = 0.0;
    double radius_px = 0.0;
  };
  std::vector<Blob> blobs_;
  double depth_ = 0.0;
};

}  // namespace tirstrain::samples
