#pragma once
// Exact-truth image sequences for the tracking generalisation benchmark: textures and fields that were not
// designed for the fingerprint case. Each frame is rendered by inverting the analytic map x = X + u(X, frame)
// at every pixel centre (Newton on the exact gradient) and sampling the analytic texture at X, so the truth
// is the field itself, with no raster interpolation between it and the images.
//
// Cases (frame 0 always at rest):
//   subpixel_shift  rigid shifts of 0.05, 0.1, 0.2, 0.3, 0.5 px in mixed directions (6 frames)
//   integer_shift   rigid shifts (7,-4), (15,3), (4,8), (-3,1) px: frame-to-frame jumps up to 12 px (5
//   frames) chirp           u = A sin(phi(X)), v = 0, A = 0.1 px, local wavelength falling geometrically
//   along x
//                   from chirp_max_wavelength_px at x = 0 to chirp_min_wavelength_px at the right edge
//   step            u = (a/2) tanh((Y - H/2) / w(X)), v = 0: a shear step whose width w falls geometrically
//                   along x from 200 to 20 px, a growing to 10 px at the last frame (6 frames)
//   stretch         uniaxial stretch along x about the frame centre, growing to 45 % (11 frames)
//   rotation        rotation about the frame centre, growing to 10 deg (11 frames)
//   creep           a hold: a Gaussian bump (sigma H/4) along (cos 30 deg, sin 30 deg) whose amplitude grows
//                   by 0.02 px in the first frame up to 0.1 px in the last (11 frames, 0.6 px in all)
// Textures: `speckle` (Gaussian dots on a jittered lattice, levels in [0.1, 0.9]) and `fingerprint`
// (samples::Fingerprint over the whole frame, period 0.45 mm at 52 px/mm, levels in [0.2, 0.8]).
// Output: 16-bit frames (full scale 65535) with Gaussian noise of `noise_fraction` of full scale, drawn
// independently per frame (frame 0 too) from the case's seed; 16 bits keep the quantisation (1.5e-5 of full
// scale) far below the noise.
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/tensor2.hpp"
#include "samples/field.hpp"
#include "samples/texture.hpp"

namespace tirstrain::samples {

enum class GeneralisationField { kSubpixelShift, kIntegerShift, kChirp, kStep, kStretch, kRotation, kCreep };
enum class GeneralisationTexture { kSpeckle, kFingerprint };

const std::vector<GeneralisationField>& generalisation_fields();
std::string to_string(GeneralisationField field);
std::string to_string(GeneralisationTexture texture);
// Throws Error naming the known values for an unknown name.
GeneralisationField generalisation_field_from_string(const std::string& name);
GeneralisationTexture generalisation_texture_from_string(const std::string& name);

// Random speckle as in digital image correlation: dark Gaussian dots exp(-|X - p|^2 / r^2) with random
// amplitudes on a jittered square lattice, combined as 1 - exp(-gain * sum) so overlapping dots saturate
// smoothly, mapped to [0.1, 0.9] (0.9 paper white, 0.1 full ink). Infinite in extent; the same for the same
// seed.
class Speckle {
 public:
  Speckle(double spacing_px, double dot_radius_px, std::uint64_t seed);
  double level(Vec2 X_px) const;

 private:
  double spacing_px_ = 5.0;
  double inv_radius2_ = 1.0;
  std::uint64_t seed_ = 0;
};

struct GeneralisationConfig {
  GeneralisationField field = GeneralisationField::kSubpixelShift;
  GeneralisationTexture texture = GeneralisationTexture::kSpeckle;
  int width_px = 512;
  int height_px = 256;
  int frames = 0;  // 0: the case's own count (above); the schedules scale so the last frame is the same
  double noise_fraction = 0.005;
  double chirp_max_wavelength_px = 1000.0;
  double chirp_min_wavelength_px = 20.0;
  double chirp_amplitude_px = 0.1;
  std::uint64_t seed = 37;
};

// The bench's sizes: 512 x 256 (the chirp 2048 x 160, wavelengths 1000 -> 20 px); `small`: 192 x 128 (the
// chirp 512 x 96, wavelengths 200 -> 10 px) and at most 6 frames, for tests.
GeneralisationConfig generalisation_config(GeneralisationField field, GeneralisationTexture texture,
                                           double noise_fraction, bool small);

class GeneralisationCase {
 public:
  // Throws Error for a size or frame count the case cannot use.
  explicit GeneralisationCase(GeneralisationConfig config);
  ~GeneralisationCase();
  GeneralisationCase(GeneralisationCase&&) noexcept;
  GeneralisationCase& operator=(GeneralisationCase&&) noexcept;

  const GeneralisationConfig& config() const { return config_; }
  int frames() const { return frames_; }
  int width() const { return config_.width_px; }
  int height() const { return config_.height_px; }
  std::string name() const;  // e.g. "chirp/speckle/0.5%"

  // u(X) at a frame and its exact gradient du/dX.
  FieldValue field(Vec2 X_px, int frame) const;
  // Solves X + u(X, frame) = x by Newton's method from `guess_px`, to 1e-10 px or 50 steps.
  FrameField::Inverse invert(Vec2 x_px, int frame, Vec2 guess_px) const;
  // The texture's level at a reference point, in [0, 1].
  double texture_level(Vec2 X_px) const;

  // Noise-free frame, full scale 1 (CV_32F); `max_residual_px`, if given, receives the largest
  // |X + u(X) - x| over the frame's pixels.
  cv::Mat render_clean(int frame, double* max_residual_px = nullptr) const;
  // The clean frame with the case's noise, quantised to 16 bits (CV_16U).
  cv::Mat add_noise(const cv::Mat& clean, int frame) const;

  // The chirp's phase phi(X) (rad) and local wavelength 2 pi / phi'(X) (px); defined for every case,
  // meaningful for the chirp.
  double chirp_phase_rad(double X_px) const;
  double chirp_wavelength_px(double X_px) const;

 private:
  struct Texture;
  GeneralisationConfig config_;
  int frames_ = 0;
  std::unique_ptr<Texture> texture_;
};

}  // namespace tirstrain::samples
