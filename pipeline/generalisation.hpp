#pragma once
// The tracking generalisation benchmark: flow::FeatureTracker on the exact-truth sequences of
// samples/generalisation.hpp (textures and fields the tracker was not tuned on), measured against the
// analytic field. Settings are what `tirstrain track` uses without a scene (the preset sized from the
// default hints, births off), on a grid of points over the whole frame (empty mask).
//
// Per frame, at every live track: e = (x_t - X) - u(X), X = the track's reference position. The chirp's
// spatial resolution: in windows one local wavelength wide along x, the measured u is fitted by
// a sin(phi) + b cos(phi) + c; the in-phase gain a / A is the fraction of the amplitude reproduced. Going
// from long to short wavelengths, the resolution is where that gain first falls below `min_gain` (linear in
// the gain between the two windows either side).
#include <opencv2/core.hpp>

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "core/tensor2.hpp"
#include "flow/settings.hpp"
#include "samples/generalisation.hpp"

namespace tirstrain::pipeline {

struct GeneralisationOptions {
  double grid_step_px = 10.0;
  double min_gain = 0.9;          // the chirp's resolution: shortest wavelength with at least this gain
  double long_wave_radii = 10.0;  // the chirp's RMS over wavelengths of at least this many radii
};

struct GeneralisationFrame {
  int frame = 0;
  int alive = 0;
  double rms_px = std::numeric_limits<double>::quiet_NaN();
  Vec2 bias_px;  // mean error vector
  double max_px = std::numeric_limits<double>::quiet_NaN();
  double track_ms = 0.0;
  bool at_rest = false;     // the tracker declared the frame at rest (FrameStats::at_rest)
  bool affine_fit = false;  // the frame's affine fit stood in for its matches (FrameStats::affine_fit)
  double affine_hidden_px = std::numeric_limits<double>::quiet_NaN();  // FrameStats::affine_hidden_px
};

struct ChirpWindow {
  double centre_px = 0.0;
  double wavelength_px = 0.0;
  double gain = 0.0;        // in-phase amplitude over the applied one
  double quadrature = 0.0;  // out-of-phase amplitude over the applied one
  int tracks = 0;
};

struct ChirpResolution {
  std::vector<ChirpWindow> windows;  // from the longest wavelength to the shortest
  double resolved_wavelength_px = std::numeric_limits<double>::quiet_NaN();
};

struct GeneralisationResult {
  std::string field, texture, preset;
  double noise_fraction = 0.0;
  int width_px = 0, height_px = 0, frames = 0, seeded = 0;
  // The scale the resolution is expressed in: the refinement subset's radius, or half the LK window for
  // a preset that does not refine (delhaye2016), whose matches are the LK windows.
  double radius_px = 0.0;
  double alive_mean = 0.0;                                    // over frames 1..N-1
  double rms_px = std::numeric_limits<double>::quiet_NaN();   // over every track-frame after frame 0
  double bias_px = std::numeric_limits<double>::quiet_NaN();  // largest per-frame |mean error|
  double max_px = std::numeric_limits<double>::quiet_NaN();
  int over_1px = 0;  // track-frames more than 1 px off: lost or mismatched tracks
  // Over the track-frames of the grid's two outermost rows and columns (reference position within
  // edge_band_px of the frame's edge), and over the others: where a subset meets the frame's edge.
  double edge_rms_px = std::numeric_limits<double>::quiet_NaN();
  double interior_rms_px = std::numeric_limits<double>::quiet_NaN();
  double edge_band_px = 0.0;
  double resolution_px = std::numeric_limits<double>::quiet_NaN();  // chirp only
  double resolution_radii = std::numeric_limits<double>::quiet_NaN();
  double long_wave_rms_px = std::numeric_limits<double>::quiet_NaN();    // chirp only: |error vector|
  double long_wave_u_rms_px = std::numeric_limits<double>::quiet_NaN();  // chirp only: its component u
  // The chirp's longest window (the first of chirp.windows) and its gain: where the resolution is nan
  // (no window reaches the threshold), how much of the longest wavelength the frame holds is reproduced.
  double longest_wavelength_px = std::numeric_limits<double>::quiet_NaN();
  double longest_gain = std::numeric_limits<double>::quiet_NaN();
  double ms_per_frame = 0.0;  // FeatureTracker::track, mean over frames 1..N-1
  int rest_frames = 0;        // frames after 0 the tracker declared at rest
  int affine_fit_frames = 0;  // frames whose affine fit stood in for the matches within their noise
  std::vector<GeneralisationFrame> per_frame;
  ChirpResolution chirp;
};

// What `tirstrain track` runs without a scene: the preset from the default hints, births off. Besides the
// presets, "auto_no_rest" is the automatic preset without its rest handling (rest_average_frames 1: no
// averaged anchor, no affine fit reported on frames found at rest), to show what that handling costs,
// "auto_no_affine_fit" the automatic preset without the moving frame's affine fit (affine_fit: false),
// "auto_no_local_fit" the automatic preset without its local fit (flow/local_fit.hpp), and
// "auto_own_matches" without either (no moving frame's affine fit, no local fit; the rest fit and the fusion
// stay). Throws Error for another name.
flow::TrackerOptions generalisation_settings(const std::string& preset);
const std::vector<std::string>& generalisation_presets();

// Tracks `frames` (16-bit, as GeneralisationCase::add_noise makes them) with the preset and measures them
// against the case's field.
GeneralisationResult run_generalisation(const samples::GeneralisationCase& sequence,
                                        const std::vector<cv::Mat>& frames, const std::string& preset,
                                        const GeneralisationOptions& options = {});

// The chirp's windowed amplitude fit of measured displacements u_x at reference points X.
ChirpResolution chirp_resolution(const samples::GeneralisationCase& sequence, const std::vector<Vec2>& X_px,
                                 const std::vector<double>& u_x_px, double min_gain);

struct GeneralisationSuite {
  bool small = false;  // the test sizes (samples::generalisation_config)
  std::vector<samples::GeneralisationField> fields = samples::generalisation_fields();
  std::vector<samples::GeneralisationTexture> textures = {samples::GeneralisationTexture::kSpeckle,
                                                          samples::GeneralisationTexture::kFingerprint};
  std::vector<double> noise_fractions = {0.005, 0.02};
  std::vector<std::string> presets = {"auto", "delhaye2016"};
  GeneralisationOptions options;
  // Sees each noisy sequence once, before the presets run on it (e.g. to write it out as a recording).
  std::function<void(const samples::GeneralisationCase&, const std::vector<cv::Mat>&)> on_sequence;
};

// Every field x texture x noise x preset; each clean sequence is rendered once. `on_result` sees each
// result as it is measured.
std::vector<GeneralisationResult> run_generalisation_suite(
    const GeneralisationSuite& suite, const std::function<void(const GeneralisationResult&)>& on_result = {});

}  // namespace tirstrain::pipeline
