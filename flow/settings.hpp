#pragma once
// Tracking options: the two presets (`auto`, sized from the scene, and `delhaye2016`, the paper's fixed
// settings) and the scene file's `tracking:` section, parsed strictly.
//
// In C++ the options are grouped by the tracker's steps (docs/flow.md names them): seeding and births,
// the contact border, the prediction, the main match, the rounds, the neighbour check, the fusion, the
// local fit, re-anchoring, rest handling, smoothing in time, the plate and the texture adaptation. In the
// scene file the keys stay flat; each field's comment gives its key, its unit and the struct's default
// (the presets change several; `preset_options` says which and why).
//
//   tracking:
//     preset: auto                  # or delhaye2016
//     max_displacement_px: 12       # largest expected skin motion between two frames (sizes the pyramid)
//     grid_step_px: 8               # any key below overrides the preset's value
//     refine: quadratic             # none | translation | affine | quadratic (subset vs. anchor frame)
//     fusion_sigma_px: 8
//     ...
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "flow/subset.hpp"

namespace tirstrain::flow {

struct TrackerOptions {
  std::string preset = "auto";  // `preset`: which preset the other values started from
  // `refine`: match every track against its anchor frame (false: the paper's plain frame-to-frame chaining)
  bool refine = true;
  double ridge_period_px = 0.0;  // what the preset was sized from, px (0: unknown, the LK window is used)

  // Where tracks start (frame 0's lattice) and where new ones are born.
  struct Seeding {
    double grid_step_px = 8.0;        // `grid_step_px`: lattice spacing of seeds and births, px; default 8
    int max_features = 3000;          // `max_features`: most tracks created, default 3000
    double min_eigen_quality = 0.01;  // `min_eigen_quality`: Shi–Tomasi λ_min kept ≥ this × the best; 0.01
    int eigen_block_px = 7;           // Shi–Tomasi block side, px; default 7
    double border_margin_px = 3.0;  // `border_margin_px`: seeds and births this far inside the contact, px; 3
    void check() const;
  } seeding;

  // Births where coverage thins. A newborn whose skin frame 0 saw is matched in frame 0 (its X is then a
  // matched pixel); skin frame 0 did not see gets X by extrapolating the neighbours' map, and says so.
  struct Births {
    bool enabled = true;      // `births`: create tracks where the contact has none; default true
    int interval_frames = 5;  // `birth_interval_frames`: look for thin coverage every this many frames; 5
    // `extrapolate_all_births`: also extrapolate skin that slid into frame 0's contact; default false
    bool extrapolate_all = false;
    void check() const;
  } births;

  // The contact's border. The ridge contrast fades there (partial contact), a pattern fixed in the image
  // that the skin slides through and that pulls a match towards zero motion (docs/flow.md, "Why the border
  // exclusion"). The measured outline lies on the outer flank of the last crest, ~1 px outside where skin
  // fully touches, hence the inset.
  struct Border {
    double exclusion_px = 0.0;  // `border_exclusion_px`: subset pixels this close to the border unused, px; 0
    double contact_inset_px = 1.0;  // `contact_inset_px`: the pipeline erodes the contact by this, px; 1
    void check() const;
  } border;

  // Frame-to-frame pyramidal Lucas–Kanade: the prediction the main match starts from.
  struct Prediction {
    double max_displacement_px = 12.0;  // `max_displacement_px`: largest motion between frames, px; 12
    int window_px = 21;                 // `window_px`: LK window side (odd), px; default 21
    int pyramid_levels = 2;             // `pyramid_levels`: LK pyramid levels above the frame; default 2
    int max_iterations = 30;            // `lk_max_iterations`: LK iterations per level; default 30
    double epsilon_px = 0.01;           // `lk_epsilon`: LK stops at steps below this, px; default 0.01
    double forward_backward_px = 1.0;  // `forward_backward_px`: largest forward–backward disagreement, px; 1
    // `global_prediction`: phase correlation of the contact between frames catches jumps LK cannot; true
    bool global_jump = true;
    void check() const;
  } prediction;

  // The main match: each track's subset against its anchor frame (IC-GN, flow/subset.hpp).
  struct MainMatch {
    // `prefilter_sigma_px`: anchor and current frame smoothed by this Gaussian σ before any subset match,
    // px; 0 = off. Ridges a period P apart keep exp(−2π²σ²/P²) of their contrast (0.92 at σ = P/16) while
    // the pixel noise falls to about 1/(2√π σ) of its level, so noisy references are mostly ridge.
    double prefilter_sigma_px = 0.0;
    ShapeFunction shape = ShapeFunction::kQuadratic;  // `refine`'s shape function; default quadratic
    int subset_radius_px = 13;                        // `subset_radius_px`: subset half-side, px; default 13
    int subset_stride = 1;  // `subset_stride`: every this many pixels each way are matched; default 1
    // The solver (`max_iterations`, `convergence_px`, `interpolation`); also used by the rounds.
    MatchOptions solver;
    double min_zncc = 0.6;  // `min_zncc`: matches with less zero-normalised correlation fail; default 0.6
    // `main_match_period_frames`: an interior frame-0 track takes the main match every this many frames
    // (1, 2 or 4, sharing the work on the seeding lattice) and otherwise starts the rounds where its
    // matched neighbours put it (docs/flow.md, step 7); default 1
    int period_frames = 1;
    // `max_correction_px`: a match further than this from its prediction is checked against the
    // neighbours, px; default 3
    double max_correction_px = 3.0;
    void check() const;
  } main_match;

  // The fixed-shape rounds: each track matched again for its translation only, its shape fixed at a
  // weighted quadratic fit of its neighbours' displacements. A second-order subset's shape terms trade off
  // against its along-ridge translation; fixing them halves that noise.
  struct Rounds {
    bool enabled = true;  // `fixed_shape_pass`: run the rounds; default true
    // `fixed_shape_radius_px`: the rounds' subset half-side if larger than the main match's, px; default 0
    int subset_radius_px = 0;
    // `fixed_shape_stride`: every this many pixels of that subset are matched (a translation needs far
    // fewer samples than the subset's reach gives); default 1
    int subset_stride = 1;
    double sigma_grid = 1.5;  // `fixed_shape_sigma_grid`: the shape fit's Gaussian σ, in grid steps; 1.5
    int iterations = 2;       // `fixed_shape_iterations`: fit and match again this many times; default 2
    // `fixed_shape_convergence_px`: every round but the last stops its translation at steps below this
    // (the last converges to the solver's convergence_px), px; default 0.1
    double convergence_px = 0.1;
    // `fixed_shape_resampled`: frame-0 tracks' rounds run on the current frame resampled once per round
    // through the neighbours' fitted field (flow/shape_field.hpp) instead of subset by subset; false
    bool resampled = false;
    int resampled_rounds = 3;  // `fixed_shape_resampled_rounds`: those rounds (fewer once nothing moves); 3
    int node_grid = 1;         // `fixed_shape_node_grid`: the field's node spacing, in grid steps; default 1
    bool smoothed_gradient = true;  // `smoothed_gradient`: report the fitted gradient, not the subset's; true
    void check() const;
  } rounds;

  // The neighbour check: each match against what its neighbours imply through their deformation gradients.
  struct Neighbours {
    bool enabled = true;        // `neighbour_check`: needs `refine`; default true
    double radius_px = 24.0;    // neighbours within this radius, px; default 24
    double tolerance_px = 0.6;  // `neighbour_tolerance_px`: largest disagreement, px; default 0.6
    int min_count = 3;          // fewer neighbours than this: the track is unchecked; default 3
    void check() const;
  } neighbours;

  // The fusion: each refined position replaced by the information-weighted mean of what it and its
  // neighbours within ~2σ imply for it. A subset about one ridge period wide pins the motion across its
  // ridges but hardly along them; neighbours whose ridges run another way supply that direction.
  struct Fusion {
    double sigma_px = 8.0;  // `fusion_sigma_px`: the neighbours' Gaussian weight σ, reference px; 0 = off; 8
    double weight = 0.02;   // `fusion_weight`: smoothness weight, a fraction of the track's information; 0.02
    int sweeps = 8;         // `fusion_sweeps`: Jacobi sweeps; default 8
    void check() const;
  } fusion;

  // Spatially adaptive averaging (flow/local_fit.hpp): a track reports the local polynomial fit of its
  // neighbours' matches over the widest window that agrees, within their predicted noise, with every
  // smaller window and with its own match; where none does it keeps its own match. On in the automatic
  // preset, off by default and in `delhaye2016`.
  struct LocalFit {
    bool enabled = false;          // `local_fit`: default false (the automatic preset: true)
    double max_radius_px = 0.0;    // `local_fit_max_radius_px`: widest window, px; 0 = 8 grid steps
    double agreement_chi2 = 9.21;  // `local_fit_agreement_chi2`: χ²(2) bound of every comparison; 9.21 (99 %)
    // `local_fit_order`: 2 (default) fits the second-order terms as well, so a smoothly bending field (a
    // Hertz load, a chirp) is followed over wide windows without the bias an affine fit has there; 1 affine
    int order = 2;
    // `local_fit_per_component`: true (default) tries each displacement component alone against the
    // frame's affine fit of it where the joint windows stop (a field that bends in one component only)
    bool per_component = true;
    void check() const;
  } local_fit;

  // The frame's affine fit (flow/tracker_affine_fit.cpp): where one affine motion describes the frame-0
  // tracks' matches of this frame within their predicted noise and without spatial structure (the test of
  // flow/model_check.hpp), each such track whose own match lies within its noise of the fit reports the fit.
  // A rigid shift, a uniform stretch or a rotation is then measured by every match at once; any motion the
  // affine model lacks (a load, a creep, a slip annulus) fails the test and the matches stand.
  struct AffineFit {
    bool enabled = true;             // `affine_fit`: default true (needs refinement)
    double max_chi2_per_dof = 1.5;   // `affine_fit_max_chi2_per_dof`: residuals against predicted noise; 1.5
    double max_correlation_z = 3.0;  // `affine_fit_max_correlation_z`: neighbours' residual correlation, z; 3
    // `affine_fit_max_hidden_px`: the test must see a non-affine motion of this RMS over the frame, px; 0.03.
    // Its χ² bound lets through motions up to the matches' typical noise times sqrt(bound − 1): where the
    // matches are noisier than that allows (a low-contrast or noisy texture), no fit stands in for them. A
    // normal load, a creep or a first partial slip moves the skin by 0.05 px and more.
    double max_hidden_px = 0.03;
    void check() const;
  } affine_fit;

  // Drift control for unrefined (frame-to-frame) tracking: track again from the anchor frame and adopt
  // that result where it agrees. Refined tracking is anchored every frame and needs none.
  struct Reanchor {
    int interval_frames = 0;    // `reanchor_interval_frames`: every this many frames; 0 = never
    double tolerance_px = 2.0;  // largest disagreement adopted, px; default 2
    void check() const;
  } reanchor;

  // Rest: while the skin has not moved since frame 0, frame 0's anchor becomes the mean of up to
  // `average_frames` frames, so its pixel noise stops entering every frame. "Not moved" is a test on the
  // frame's own evidence (flow/model_check.hpp): an affine fit must describe the frame-0 tracks' matches
  // within their predicted noise and without spatial structure, and the fitted motion must be nil. A
  // creep, a load or a first partial slip fails it, and the first failing frame ends the averaging.
  struct Rest {
    int average_frames = 1;          // `rest_average_frames`: frames averaged into the anchor; 1 = off
    double max_chi2_per_dof = 1.5;   // `rest_max_chi2_per_dof`: residuals against predicted noise; 1.5
    double max_correlation_z = 3.0;  // `rest_max_correlation_z`: neighbours' residual correlation, z; 3
    double tolerance_px = 0.01;      // `rest_tolerance_px`: RMS fitted motion counted as nil, px; 0.01
    double max_motion_chi2 = 22.5;  // `rest_max_motion_chi2`: or the fit's parameters nil within χ²(6); 22.5
    void check() const;
  } rest;

  // Positions smoothed in time once the whole trial is tracked (flow/temporal_smoothing.hpp); `process`
  // applies it and computes the strain from the smoothed tracks.
  struct Smoothing {
    // `smooth_in_time`: "auto" (only on noisy texture, where each match is at its bound and its error is
    // white in time), "on" or "off"; default off
    std::string mode = "off";
    double gamma = 1.5;  // `smooth_in_time_gamma`: TemporalSmoothing::gamma; default 1.5
    void check() const;
  } smoothing;

  // The plate's motion from the pattern printed on the glass (flow/plate.hpp).
  struct Plate {
    int subset_radius_px = 0;         // `plate_subset_radius_px`: 0 = the largest up to 22 px the band fits
    double grid_step_px = 0.0;        // `plate_grid_step_px`: subset spacing, px; 0 = side by side
    double prefilter_sigma_px = 0.7;  // `plate_prefilter_sigma_px`: Gaussian σ before matching, px; 0.7
    void check() const;
  } plate;

  // Model only what the texture supports: frame 0's ridge contrast over its pixel noise (TextureQuality).
  // Below `min_unfiltered_snr` the frames are smoothed by P/24 before matching; below `min_quadratic_snr`
  // the subsets drop their second-order terms, are smoothed by P/12, grow to 0.75 P and the fusion reaches
  // twice as far (docs/flow.md, "Frame 0"). What a scene sets itself is kept (`pinned`).
  struct Texture {
    bool adapt = false;                // `adapt_to_texture`: default false (the automatic preset: true)
    double min_unfiltered_snr = 30.0;  // `min_unfiltered_snr`: default 30
    double min_quadratic_snr = 4.0;    // `min_quadratic_snr`: default 4
    void check() const;
  } texture;

  // Which values the scene gave itself, so that the texture adaptation keeps them.
  struct Pinned {
    bool shape = false, prefilter = false, subset_radius = false, fusion = false, subset_stride = false,
         fixed_shape_stride = false, main_match_period = false;
  } pinned;

  // Throws Error naming the scene key of the first value out of range (every group's check()).
  void check() const;
};

// What the presets are sized from.
struct SceneHints {
  double px_per_mm = 52.0;
  double ridge_period_px = 0.45 * 52.0;
  double max_displacement_px = 12.0;
};

SceneHints hints_from_scene(const Scene& scene);

// The preset's options for a scene. Names: "auto", "delhaye2016". Throws Error for an unknown name.
TrackerOptions preset_options(const std::string& name, const SceneHints& hints);
const std::vector<std::string>& preset_names();

// The scene's `tracking:` section on top of its preset (`preset_override`, if not empty, replaces the
// section's `preset`, e.g. from `--preset`). Unknown keys and out-of-range values throw Error naming the
// file and key.
TrackerOptions parse_tracking_options(const Scene& scene, const std::string& preset_override = "");

std::string to_string(ShapeFunction shape);

}  // namespace tirstrain::flow
