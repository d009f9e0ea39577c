#pragma once
// The `synthesis:` section of a scene file: everything `tirstrain synth` needs to render a trial, parsed
// strictly (unknown keys, wrong types and out-of-range values are errors naming the file and key path).
// The schema is documented in docs/formats.md; every default below is the value a key takes when absent.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "core/tensor2.hpp"

namespace tirstrain::samples {

enum class FieldKind { kCattaneoMindlin, kRigid, kAffine, kNone };
enum class ContactShape { kHertz, kEllipse };

struct ImageConfig {
  int width_px = 0;
  int height_px = 0;
  int bit_depth = 8;  // 8 or 16
};

struct TimingConfig {
  int frames = 0;
  double frame_rate_hz = 0.0;
  double jitter_s = 0.0;  // standard deviation of frame timestamps around index / rate (frame 0 exact)
};

struct ContactConfig {
  ContactShape shape = ContactShape::kHertz;
  double normal_N = 2.0;
  double radius_m = 0.02;               // sphere radius R for Hertz (and the ellipse's equivalent field)
  double semi_axes_mm[2] = {4.0, 3.0};  // ellipse only, along its own axes
  double angle_deg = 0.0;               // ellipse only: first semi-axis from +x towards +y
  std::optional<Vec2> centre_px;        // default: image centre of the part below the pattern band
  double border_irregularity = 0.03;    // relative amplitude of the border's radius modulation
  double border_softness_px = 2.0;      // width of the soft contact edge
  double fade_mm = 0.4;                 // ridge contrast rises over this distance inside the border
  double fade_floor = 0.35;             // relative ridge contrast right at the border
};

struct LoadingConfig {
  FieldKind field = FieldKind::kCattaneoMindlin;
  double friction = 1.0;
  double direction_deg = 0.0;     // plate motion = traction on the skin, from +x towards +y (image axes)
  double plate_speed_mm_s = 5.0;  // cattaneo_mindlin only
  double shear_start_s = 0.0;     // plate starts moving (all fields start ramping) at this time
  Vec2 translation_px;            // rigid/affine: value reached at the last frame
  double rotation_deg = 0.0;      // rigid: rotation about the contact centre reached at the last frame
  Gradient2 gradient;             // affine: H = du/dX reached at the last frame
};

struct FingerprintConfig {
  Vec2 core_offset_mm{0.0, -0.6};       // core relative to the contact centre
  double axis_deg = 90.0;               // finger axis (distal -> proximal) from +x towards +y
  double loop_length_mm = 0.8;          // straight part of the loop below the core
  std::optional<Vec2> delta_offset_mm;  // triradius relative to the core; absent: no delta
  double minutiae_per_mm2 = 0.4;        // ridge endings + bifurcations
  double flow_warp = 0.5;               // amplitude of the smooth ridge-flow warp, in ridge periods
  double background = -1.0;             // optics background level (0..1); <0: 0.8 dark / 0.15 bright
  double ridge_contrast = 0.55;         // ridge crest change of level in full contact (0..1)
  double pore_depth = 0.7;              // relative loss of ridge level at a sweat pore's centre
  double pore_spacing_mm = 0.2;         // lattice of candidate pore sites (60 % hold a pore)
  double pore_sigma_mm = 0.06;          // Gaussian pore profile (FWHM ~0.14 mm)
  double vignetting = 0.08;             // relative fall-off at the image corners
};

struct PatternConfig {
  double dot_spacing_mm = 0.22;
  double dot_sigma_mm = 0.04;
  double opacity = 0.6;
  double fill = 0.7;  // fraction of lattice cells holding a dot
};

struct SweatConfig {
  int blobs = 0;
  double radius_mm_min = 0.3;
  double radius_mm_max = 0.8;
  double depth = 0.85;  // fraction of ridge contrast lost at a blob's centre
};

struct SensorConfig {
  double full_well_electrons = 0.0;  // shot noise from this many electrons at full scale; 0 = no shot noise
  double read_noise = 0.0;           // standard deviation, fraction of full scale
  double blur_sigma_px = 0.0;
  double drift = 0.0;  // relative illumination change over the trial
  double gain = 1.0;   // > 1 saturates the brightest parts
  std::vector<int> motion_blur_frames;
  double motion_blur_exposure_s = 0.01;
};

struct AccelerometerConfig {
  double mass_kg = 0.029;
  double damping_N_s_m = 2.1;
  double stiffness_N_m = 830.0;
  double noise_m_s2 = 0.0;
};

struct ChannelsConfig {
  double rate_hz = 1000.0;
  double normal_noise_N = 0.0;      // servo noise on the normal force
  double tangential_noise_N = 0.0;  // sensor noise on the tangential force
  double slip_fluctuation_N = 0.0;  // broadband friction force fluctuation during full slip (drives the pad)
  AccelerometerConfig accelerometer;
};

struct TruthConfig {
  double grid_step_px = 8.0;
  int orientation_block_px = 32;  // blocks of the ridge orientation truth (contact/'s default block size)
};

struct SynthConfig {
  Scene scene;  // the whole scene (calibration, tissue, reference pattern ROI)
  std::uint64_t seed = 1;
  ImageConfig image;
  TimingConfig timing;
  ContactConfig contact;
  LoadingConfig loading;
  FingerprintConfig fingerprint;
  PatternConfig pattern;
  SweatConfig sweat;
  SensorConfig sensor;
  ChannelsConfig channels;
  TruthConfig truth;
  double ridge_period_mm =
      0.45;                 // calibration.ridge_period_mm, or 0.45 when the scene leaves it to measurement
  bool ridges_dark = true;  // calibration.ridge_polarity ("auto" renders dark ridges)
};

// Reads the scene's `synthesis:` section (required) and checks it against the rest of the scene.
// Throws tirstrain::Error naming the file and the key path.
SynthConfig parse_synth_config(const Scene& scene);

// load_scene + parse_synth_config.
SynthConfig load_synth_config(const std::string& path);

}  // namespace tirstrain::samples
