#pragma once
// Tracking settings: the two presets (`auto`, sized from the scene, and `delhaye2016`, the paper's fixed
// settings) and the scene file's `tracking:` section, parsed strictly.
//
//   tracking:
//     preset: auto                  # or delhaye2016
//     max_displacement_px: 12       # largest expected skin motion between two frames (sizes the pyramid)
//     grid_step_px: 8               # any key below overrides the preset's value
//     max_features: 3000
//     window_px: 21                 # LK window side (odd)
//     pyramid_levels: 2
//     refine: quadratic             # none | translation | affine | quadratic (subset vs. anchor frame)
//     subset_radius_px: 13
//     subset_stride: 1
//     ...
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "flow/subset.hpp"

namespace tirstrain::flow {

struct TrackerSettings {
  std::string preset = "auto";

  // Seeding and births.
  double grid_step_px = 8.0;
  int max_features = 3000;
  double min_eigen_quality = 0.01;  // Shi–Tomasi: kept if λ_min ≥ quality × the largest λ_min in the contact
  int eigen_block_px = 7;           // Shi–Tomasi block side
  bool births = true;
  int birth_interval_frames = 5;  // look for thin coverage every this many frames
  // Refined tracking gives a newborn whose skin frame 0 saw a frame-0 anchor (its X then is a matched frame-0
  // pixel). Skin frame 0 did not see gets X by extrapolating the neighbours' map; by default only where the
  // contact grew beyond frame 0's (true: also skin that slid into an unchanged contact).
  bool extrapolate_all_births = false;
  double border_margin_px = 3.0;  // seeds and births at least this far inside the contact
  // Subset pixels closer than this to the contact border are not matched: there the ridge contrast fades
  // with the partial contact, a pattern fixed in the image that the skin slides through, so it biases any
  // match towards zero motion. Tracks whose subsets lose most of their pixels this way are retired.
  double border_exclusion_px = 0.0;
  // The pipeline's tracking stage insets the measured contact by this much before it is the tracker's contact
  // mask (above). The measured outline lies on the outer flank of the last crest (contact/segmenter.hpp:
  // crest_edge_level < 1/2), on average ~1 px outside where skin fully touches and 2-3 px where a crest is
  // cut; a subset pixel on background pulls the match towards zero motion, a lost skin pixel only costs a
  // little information. End to end, 1 px: default scene 0.054 -> 0.048 px (BENCHMARKS.md, flow section).
  double contact_inset_px = 1.0;

  // Frame-to-frame pyramidal Lucas–Kanade (the prediction).
  int window_px = 21;
  int pyramid_levels = 2;
  int lk_max_iterations = 30;
  double lk_epsilon = 0.01;
  double forward_backward_px = 1.0;  // largest forward–backward disagreement
  bool global_prediction = true;     // phase correlation of the contact between frames catches large jumps

  // Refinement against the anchor frame (none: the paper's plain frame-to-frame chaining).
  bool refine = true;
  // Both the anchor and the current frame are smoothed by a Gaussian of this σ before subset matching
  // (0 = off). Ridges a period P apart keep exp(−2π²σ²/P²) of their contrast (0.92 at σ = P/16), while
  // pixel noise drops to about 1/(2√π σ) of its level: on noisy frames the reference gradients are then
  // mostly ridge, not noise, and IC-GN converges instead of creeping.
  double prefilter_sigma_px = 0.0;
  ShapeFunction shape = ShapeFunction::kQuadratic;
  int subset_radius_px = 13;
  int subset_stride = 1;
  MatchOptions match;
  double min_zncc = 0.6;
  // Second pass: each refined track is matched again for its translation only, its subset's shape (gradient
  // and curvature) fixed at the neighbours' smoothed shape. Halves the along-ridge noise of a second-order
  // subset (its shape terms trade off against the along-ridge translation).
  bool fixed_shape_pass = true;
  int fixed_shape_radius_px = 0;  // that pass's subset radius, if larger than subset_radius_px
  // Every this many pixels of that subset are matched: a translation needs far fewer samples than the
  // second-order solve, and the wide subset's reach (the ridges' curvature) matters more than its density.
  int fixed_shape_stride = 1;
  // With the resampled rounds, an interior frame-0 track takes the main match (LK and the subset match)
  // every this many frames (1, 2 or 4), the tracks sharing the work on the seeding lattice (a checkerboard
  // at 2, one grid point in four at 4); in between, it starts the rounds at the median of where its matched
  // neighbours put it. Border tracks, newborns in their first frame and tracks with too few matched
  // neighbours match every frame, and a track the rounds do not carry is matched after all (docs/flow.md,
  // step 7). The automatic preset: 4, and 1 on small contacts and low-SNR texture.
  int main_match_period_frames = 1;
  // The shape is a weighted quadratic fit of the neighbours' displacements (Gaussian weights of this σ, in
  // grid steps, out to 2σ).
  double fixed_shape_sigma_grid = 1.5;
  int fixed_shape_iterations = 2;  // fit and match again from the improved positions
  // Every round but the last stops its translation-only match once the step is below this (the last one
  // converges to match.convergence_px). The rounds are themselves iterations (each starts where the last
  // ended, with a refitted shape), and near the answer one Gauss-Newton step of a translation with the
  // template's exact Hessian lands almost on it. A loose criterion in every round gave identical errors on
  // the shipped scenes but left one track of the 50 % stretch 1.007 px off.
  double fixed_shape_convergence_px = 0.1;
  // The fixed-shape rounds of the tracks anchored in frame 0 itself run on the current frame resampled
  // through the neighbours' fitted field (flow/shape_field.hpp), once per round for all of them, instead of
  // interpolating every overlapping subset on its own; each round refits the field and takes one
  // translation step per track, this many rounds (fewer only once no track moves by 0.001 px: run to their
  // fixed point the rounds amplify noise, docs/flow.md step 7). Other tracks (anchored later) keep the
  // subset-by-subset rounds.
  bool fixed_shape_resampled = false;
  int fixed_shape_resampled_rounds = 3;
  // The resampled rounds' field has its nodes this many grid steps apart, on the seeding lattice. The
  // node polynomials are fits over 2σ (fixed_shape_sigma_grid) and are blended bilinearly between nodes: a
  // spacing well under σ adds nodes, not detail.
  int fixed_shape_node_grid = 1;
  bool smoothed_gradient = true;  // report (and use) the fitted gradient instead of the subset's own
  // A refined match further than this from its prediction is re-checked against the neighbours.
  double max_correction_px = 3.0;

  // Neighbour consistency (needs refinement: it uses each track's deformation gradient).
  bool neighbour_check = true;
  double neighbour_radius_px = 24.0;
  double neighbour_tolerance_px = 0.6;
  int min_neighbours = 3;

  // Fusion: each refined position is replaced by the information-weighted mean of what it and its
  // neighbours within ~2σ imply for it (carried over by their deformation gradients). A subset of about one
  // ridge period pins the motion across its ridges but hardly along them; neighbours whose ridges run
  // another way supply that direction. σ in reference pixels; 0 = off.
  double fusion_sigma_px = 8.0;
  double fusion_weight = 0.02;  // smoothness weight, as a fraction of each track's own information
  int fusion_sweeps = 8;

  // Spatially adaptive averaging (flow/local_fit.hpp): each refined track reports the local affine fit of
  // its neighbours' own matches over the widest window, up to `local_fit_max_radius_px` (0: 8 grid steps),
  // that agrees with every smaller window and with the track's own match within their predicted noise
  // (χ²(2) at most `local_fit_agreement_chi2`, 9.21: 99 %; every comparison of every window must pass, so a
  // stricter quantile stops most tracks early on a field that is affine throughout) and whose residuals are
  // the matches' noise; where none does, the track keeps its own
  // match. Needs refinement (the matches' predicted covariances). Off unless a scene turns it on: on the
  // Cattaneo–Mindlin trials it smooths the slip annulus' kink that the model fit reads c from.
  bool local_fit = false;
  double local_fit_max_radius_px = 0.0;
  double local_fit_agreement_chi2 = 9.21;

  // Drift control for unrefined (frame-to-frame) tracking: every this many frames, track again from the
  // anchor frame to the current one and adopt that result where it agrees; 0 = never. Refined tracking is
  // anchored every frame and needs none.
  int reanchor_interval_frames = 0;
  double reanchor_tolerance_px = 2.0;

  // Refined tracking matches every frame against its anchor, so the anchor's pixel noise is in every
  // frame's error, frame after frame. While the skin has not moved since frame 0 (the hold before the
  // plate moves), frame 0's anchor becomes the mean of up to `rest_average_frames` such frames; 1 = off.
  // "Not moved" is a test on the frame's own evidence (flow/model_check.hpp): an affine fit of the frame-0
  // tracks' own matches must describe them, its residuals consistent with each match's predicted noise (χ²
  // per degree of freedom at most `rest_max_chi2_per_dof`) and without spatial structure (the correlation
  // of independent neighbours' residuals at most `rest_max_correlation_z` as a z-score); and the fitted
  // motion itself must be nil: its RMS over the tracks within `rest_tolerance_px`, or its parameters zero
  // within their uncertainty predicted from the matches' noise (χ²(6) at most `rest_max_motion_chi2`). An
  // averaged anchor holds the mean of its frames' positions, so any motion let in here would bias every
  // later frame by its share. A creep, a load or
  // a first partial slip fails it, and the first frame that fails ends the averaging for good. While the
  // test accepts, each frame-0 track reports the fit where it lies within its own match's noise. The
  // automatic preset averages up to 16 frames, and only noisy texture (SNR below min_unfiltered_snr),
  // where the anchor's noise matters.
  int rest_average_frames = 1;
  double rest_max_chi2_per_dof = 1.5;
  double rest_max_correlation_z = 3.0;
  double rest_tolerance_px = 0.01;
  double rest_max_motion_chi2 = 22.5;

  // Positions smoothed in time once the whole trial is tracked (flow/temporal_smoothing.hpp; `process`
  // applies it, the strain is then computed from the smoothed tracks): "auto" only where the texture is
  // noisy (the low-SNR subsets, SNR below min_quadratic_snr; there each frame's match is at its bound and
  // its error is white in time), "on", "off". The automatic preset: auto; delhaye2016: off.
  std::string smooth_in_time = "off";
  double smooth_in_time_gamma = 1.5;  // TemporalSmoothing::gamma

  // Plate motion from the pattern on the glass.
  // 0: automatic, the largest radius up to 22 px that fits the band (measured on the shipped scenes, 15 /
  // 18 / 20 / 22 / 25 px: default 0.0053 / 0.0053 / 0.0049 / 0.0043 / 0.0044 px RMS, hard_heavy_noise
  // 0.034 / 0.038 / 0.023 / 0.021 / 0.022 px).
  int plate_subset_radius_px = 0;
  double plate_grid_step_px = 0.0;        // PlateSettings::grid_step_px (0: subsets side by side)
  double plate_prefilter_sigma_px = 0.7;  // PlateSettings::prefilter_sigma_px

  // Largest expected skin displacement between consecutive frames (sizes the pyramid).
  double max_displacement_px = 12.0;

  // Model only what the texture supports: frame 0's ridge contrast against its pixel noise is measured
  // (TextureQuality). Below `min_unfiltered_snr` the frames are
  // smoothed by P/24 before matching (noise-free frames are matched best unsmoothed); below
  // `min_quadratic_snr` the subsets also drop the second-order terms (their six curvature parameters then
  // follow the noise and IC-GN wanders), are smoothed by P/12 and grow to 0.75 P, and the fusion reaches
  // twice as far, at full weight; once smoothed by 1.5 px or more, they sample every 2nd pixel each way. The
  // curvature still enters through the fixed-shape pass, from the neighbours. With the resampled rounds
  // (fixed_shape_resampled), a contact of fewer than 300 grid points (mostly border tracks, whose main match
  // counts on its own) keeps a second-order main match on every pixel, and its rounds' steps every pixel
  // (fixed_shape_stride 1). Set by the automatic preset;
  // what a scene sets itself (refine, prefilter_sigma_px, subset_radius_px, subset_stride,
  // fixed_shape_stride, the fusion keys) is kept.
  bool adapt_to_texture = false;
  struct Pinned {
    bool shape = false, prefilter = false, subset_radius = false, fusion = false, subset_stride = false,
         fixed_shape_stride = false, main_match_period = false;
  } pinned;
  double min_unfiltered_snr = 30.0;
  double min_quadratic_snr = 4.0;
  double ridge_period_px = 0.0;  // what the preset was sized from (0: unknown, the LK window is used)
};

// What the presets are sized from.
struct SceneHints {
  double px_per_mm = 52.0;
  double ridge_period_px = 0.45 * 52.0;
  double max_displacement_px = 12.0;
};

SceneHints hints_from_scene(const Scene& scene);

// The preset's settings for a scene. Names: "auto", "delhaye2016". Throws Error for an unknown name.
TrackerSettings preset_settings(const std::string& name, const SceneHints& hints);
const std::vector<std::string>& preset_names();

// The scene's `tracking:` section on top of its preset (`preset_override`, if not empty, replaces the
// section's `preset`, e.g. from `--preset`). Unknown keys and out-of-range values throw Error naming the
// file and key.
TrackerSettings parse_tracking_settings(const Scene& scene, const std::string& preset_override = "");

// Checks a settings object built in code; throws Error naming the offending field.
void validate(const TrackerSettings& settings);

std::string to_string(ShapeFunction shape);

}  // namespace tirstrain::flow
