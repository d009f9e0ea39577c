#include "flow/settings.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::flow {
namespace {

int odd(double v) {
  const int i = std::max(3, static_cast<int>(std::lround(v)));
  return i % 2 == 0 ? i + 1 : i;
}

}  // namespace

std::string to_string(ShapeFunction shape) {
  switch (shape) {
    case ShapeFunction::kTranslation:
      return "translation";
    case ShapeFunction::kAffine:
      return "affine";
    case ShapeFunction::kQuadratic:
      return "quadratic";
  }
  return "?";
}

const std::vector<std::string>& preset_names() {
  static const std::vector<std::string> names = {"auto", "delhaye2016"};
  return names;
}

SceneHints hints_from_scene(const Scene& scene) {
  SceneHints h;
  h.px_per_mm = scene.px_per_mm;
  h.ridge_period_px = scene.ridge_period_mm.value_or(0.45) * scene.px_per_mm;
  h.max_displacement_px = 0.5 * h.ridge_period_px;
  return h;
}

TrackerSettings preset_settings(const std::string& name, const SceneHints& hints) {
  TrackerSettings s;
  s.preset = name;
  s.max_displacement_px = hints.max_displacement_px;
  const double period = hints.ridge_period_px;
  if (name == "delhaye2016") {
    // Delhaye et al. 2016: features on a 9 px grid, 101×101 px KLT window, up to 3000 features, tracked
    // frame to frame with a three-level pyramid (levels 0..2) and no refinement against the first frame.
    s.grid_step_px = 9.0;
    s.max_features = 3000;
    s.window_px = 101;
    s.pyramid_levels = 2;
    s.refine = false;
    s.neighbour_check = false;
    s.fixed_shape_pass = false;
    s.fusion_sigma_px = 0.0;
    s.global_prediction = false;
    s.reanchor_interval_frames = 0;
    s.births = true;
    return s;
  }
  if (name != "auto")
    throw Error("unknown tracking preset '" + name + "' (known: auto, delhaye2016)",
                {.key = "tracking.preset"});
  // Sized from the ridge period P: the LK window spans most of a period (enough texture to be well posed,
  // small enough that the field is nearly uniform inside it); the refinement subset has a radius of about
  // 0.55 P, where a second-order subset's curvature bias is negligible and its noise is still low; seeds on a
  // grid of P/3 (three samples per ridge period, the finest spacing at which neighbouring subsets still
  // differ). The pyramid is as deep as the largest expected displacement needs, but never so deep that the
  // ridges (P / 2^L px at level L) fall below 4 px and vanish in the pyramid's smoothing.
  s.grid_step_px = std::max(3.0, std::round(period / 3.0));
  // The LK window is 0.7 P (17 px at P = 23.4 px): LK only seeds the subset match, and a window a full
  // period wide costs half again as much for the same answers.
  s.window_px = odd(0.7 * period);
  s.lk_epsilon = 0.1;  // LK stops at 0.1 px steps: the match converges to 0.01 px from there
  s.subset_radius_px = std::max(5, static_cast<int>(std::lround(0.55 * period)));
  s.neighbour_radius_px = 3.0 * s.grid_step_px;
  s.fusion_sigma_px = s.grid_step_px;
  s.border_exclusion_px = std::round(0.6 * period);
  s.fixed_shape_radius_px = static_cast<int>(std::lround(0.85 * period));
  s.fixed_shape_sigma_grid = 2.5;
  // Three fit-and-match rounds and a fusion weight of 0.1: each round lowers the displacement and strain
  // noise for a few per cent more time; the smoother field rounds the slip front only a little.
  s.fixed_shape_iterations = 3;
  // The frame-0 tracks' rounds run on the frame resampled once per round through the neighbours' fitted
  // field (flow/shape_field.hpp), three rounds as above. The rounds then set the final positions, and the
  // main match only has to seed them: an affine subset on every 3rd pixel does, at a third of the cost of a
  // second-order subset on every pixel and the same accuracy.
  s.fixed_shape_resampled = true;
  s.fixed_shape_resampled_rounds = 3;
  // Field nodes two grid steps apart (16 px at P = 23.4 px, 0.8 σ): a quarter of the nodes of a one-step
  // lattice to build and fit, with the same accuracy within a few per cent on every shipped scene.
  s.fixed_shape_node_grid = 2;
  s.shape = ShapeFunction::kAffine;
  // The main match reads every 3rd pixel: it only seeds the rounds, and the displacement error end to end
  // stays within a few per cent of every pixel's. Noisy texture keeps every 2nd pixel and small contacts
  // every pixel (FeatureTracker, adapt_to_texture).
  s.subset_stride = 3;
  // The rounds' translation steps read every 2nd pixel each way (and only those pixels are resampled): a
  // translation needs far fewer samples than the 41×41 window's reach gives it, and the frames are smoothed
  // by ≥ P/24 ≈ 1 px on every shipped scene but the noise-free one. Small contacts keep every pixel
  // (FeatureTracker, adapt_to_texture).
  s.fixed_shape_stride = 2;
  // Each interior frame-0 track takes LK and the main match every 4th frame, a quarter of them per frame on
  // a 2×2 pattern of the seeding lattice; the others start the rounds where their matched neighbours put
  // them. The rounds, not the main match, set the final positions: the displacement error end to end stays
  // within a few per cent of matching every track every frame, for about a third more frames/s. Border
  // tracks, small contacts and low-SNR texture match every frame (FeatureTracker).
  s.main_match_period_frames = 4;
  s.fusion_weight = 0.1;
  s.border_margin_px = s.border_exclusion_px;
  const double reach_px = 0.25 * s.window_px;  // what one level of LK follows reliably
  const int needed = hints.max_displacement_px > reach_px
                         ? static_cast<int>(std::ceil(std::log2(hints.max_displacement_px / reach_px)))
                         : 0;
  const int allowed = std::max(0, static_cast<int>(std::floor(std::log2(period / 4.0))));
  s.pyramid_levels = std::clamp(needed, 0, allowed);
  s.plate_subset_radius_px = 0;
  s.ridge_period_px = period;
  // The fixed-shape pass and the fusion decide the final position; the full-shape solve only has to land
  // within a hundredth of a pixel of it.
  s.match.convergence_px = 0.01;
  // Keys' kernel reads a sub-pixel shift of a fine texture up to 5 % short (0.010 px at 0.2 px on speckle);
  // the cubic B-spline of the frame's coefficients reads it within 0.3 %.
  s.match.interpolation = Interpolation::kCubicBSpline;
  // A track whose subset has less than 60 % of its pixels left inside the contact (after the border
  // exclusion) is retired as having left it: its position is then mostly an extrapolation of the warp
  // across the border band, where the fixed contrast fade pulls it back. At 0.5, a 50 % stretch carried
  // four track-frames 1.0-1.4 px off before they were retired; at 0.6 none is > 1 px (max 0.95 px), and the
  // default scene gains slightly (0.0553 → 0.0534 px, U 3.10 → 3.02 %) for 0.5 % fewer track-frames.
  s.match.min_valid_fraction = 0.6;
  s.adapt_to_texture = true;
  s.rest_average_frames = 16;
  s.smooth_in_time = "auto";
  return s;
}

TrackerSettings parse_tracking_settings(const Scene& scene, const std::string& preset_override) {
  YamlSection t(scene.tracking, scene.file, "tracking");
  std::string preset = t.choice("preset", "auto", preset_names());
  if (!preset_override.empty()) {
    if (std::find(preset_names().begin(), preset_names().end(), preset_override) == preset_names().end())
      throw Error("unknown tracking preset '" + preset_override + "' (known: auto, delhaye2016)",
                  {.key = "--preset"});
    preset = preset_override;
  }
  SceneHints hints = hints_from_scene(scene);
  hints.max_displacement_px = t.number("max_displacement_px", hints.max_displacement_px, 0.0, 1000.0);
  TrackerSettings s = preset_settings(preset, hints);
  s.grid_step_px = t.number("grid_step_px", s.grid_step_px, 1.0, 1000.0);
  s.max_features = static_cast<int>(t.integer("max_features", s.max_features, 1, 1000000));
  s.min_eigen_quality = t.number("min_eigen_quality", s.min_eigen_quality, 0.0, 1.0);
  s.births = t.boolean("births", s.births);
  s.extrapolate_all_births = t.boolean("extrapolate_all_births", s.extrapolate_all_births);
  s.birth_interval_frames =
      static_cast<int>(t.integer("birth_interval_frames", s.birth_interval_frames, 1, 100000));
  s.window_px = static_cast<int>(t.integer("window_px", s.window_px, 3, 401));
  if (s.window_px % 2 == 0)
    throw Error("the LK window side must be odd", {.file = scene.file, .key = t.path_of("window_px")});
  s.pyramid_levels = static_cast<int>(t.integer("pyramid_levels", s.pyramid_levels, 0, 8));
  s.forward_backward_px = t.number("forward_backward_px", s.forward_backward_px, 0.0, 1000.0);
  s.lk_max_iterations = static_cast<int>(t.integer("lk_max_iterations", s.lk_max_iterations, 1, 1000));
  s.lk_epsilon = t.number("lk_epsilon", s.lk_epsilon, 1e-6, 10.0);
  s.global_prediction = t.boolean("global_prediction", s.global_prediction);
  const std::string refine = t.choice("refine", s.refine ? to_string(s.shape) : "none",
                                      {"none", "translation", "affine", "quadratic"});
  s.refine = refine != "none";
  if (refine == "translation") s.shape = ShapeFunction::kTranslation;
  if (refine == "affine") s.shape = ShapeFunction::kAffine;
  if (refine == "quadratic") s.shape = ShapeFunction::kQuadratic;
  s.pinned = {t.has("refine"),
              t.has("prefilter_sigma_px"),
              t.has("subset_radius_px"),
              t.has("fusion_sigma_px") || t.has("fusion_weight") || t.has("fusion_sweeps"),
              t.has("subset_stride"),
              t.has("fixed_shape_stride"),
              t.has("main_match_period_frames")};
  s.adapt_to_texture = t.boolean("adapt_to_texture", s.adapt_to_texture);
  s.min_quadratic_snr = t.number("min_quadratic_snr", s.min_quadratic_snr, 0.0, 1e6);
  s.min_unfiltered_snr = t.number("min_unfiltered_snr", s.min_unfiltered_snr, 0.0, 1e6);
  s.subset_radius_px = static_cast<int>(t.integer("subset_radius_px", s.subset_radius_px, 3, 200));
  s.prefilter_sigma_px = t.number("prefilter_sigma_px", s.prefilter_sigma_px, 0.0, 20.0);
  s.subset_stride = static_cast<int>(t.integer("subset_stride", s.subset_stride, 1, 8));
  s.match.max_iterations = static_cast<int>(t.integer("max_iterations", s.match.max_iterations, 1, 1000));
  s.match.convergence_px = t.number("convergence_px", s.match.convergence_px, 1e-6, 1.0);
  s.match.interpolation =
      t.choice("interpolation",
               s.match.interpolation == Interpolation::kCubicBSpline ? "cubic_bspline" : "keys",
               {"keys", "cubic_bspline"}) == "cubic_bspline"
          ? Interpolation::kCubicBSpline
          : Interpolation::kKeys;
  s.max_correction_px = t.number("max_correction_px", s.max_correction_px, 0.01, 1000.0);
  s.min_zncc = t.number("min_zncc", s.min_zncc, -1.0, 1.0);
  s.neighbour_check = t.boolean("neighbour_check", s.neighbour_check);
  s.fixed_shape_pass = t.boolean("fixed_shape_pass", s.fixed_shape_pass);
  s.fixed_shape_sigma_grid = t.number("fixed_shape_sigma_grid", s.fixed_shape_sigma_grid, 0.5, 20.0);
  s.fixed_shape_iterations =
      static_cast<int>(t.integer("fixed_shape_iterations", s.fixed_shape_iterations, 1, 10));
  s.fixed_shape_convergence_px =
      t.number("fixed_shape_convergence_px", s.fixed_shape_convergence_px, 1e-6, 10.0);
  s.fixed_shape_resampled = t.boolean("fixed_shape_resampled", s.fixed_shape_resampled);
  s.fixed_shape_resampled_rounds =
      static_cast<int>(t.integer("fixed_shape_resampled_rounds", s.fixed_shape_resampled_rounds, 1, 100));
  s.fixed_shape_node_grid =
      static_cast<int>(t.integer("fixed_shape_node_grid", s.fixed_shape_node_grid, 1, 8));
  s.smoothed_gradient = t.boolean("smoothed_gradient", s.smoothed_gradient);
  s.fixed_shape_radius_px =
      static_cast<int>(t.integer("fixed_shape_radius_px", s.fixed_shape_radius_px, 0, 200));
  s.fixed_shape_stride = static_cast<int>(t.integer("fixed_shape_stride", s.fixed_shape_stride, 1, 8));
  s.main_match_period_frames =
      static_cast<int>(t.integer("main_match_period_frames", s.main_match_period_frames, 1, 4));
  if (s.main_match_period_frames == 3)
    throw Error("main_match_period_frames must be 1, 2 or 4 (the tracks share the work on the lattice)",
                {.file = scene.file, .key = t.path_of("main_match_period_frames")});
  s.neighbour_tolerance_px = t.number("neighbour_tolerance_px", s.neighbour_tolerance_px, 0.01, 100.0);
  s.border_exclusion_px = t.number("border_exclusion_px", s.border_exclusion_px, 0.0, 1000.0);
  s.border_margin_px = t.number("border_margin_px", s.border_margin_px, 0.0, 1000.0);
  s.contact_inset_px = t.number("contact_inset_px", s.contact_inset_px, 0.0, 100.0);
  s.fusion_sigma_px = t.number("fusion_sigma_px", s.fusion_sigma_px, 0.0, 1000.0);
  s.fusion_weight = t.number("fusion_weight", s.fusion_weight, 0.0, 1000.0);
  s.fusion_sweeps = static_cast<int>(t.integer("fusion_sweeps", s.fusion_sweeps, 0, 1000));
  s.reanchor_interval_frames =
      static_cast<int>(t.integer("reanchor_interval_frames", s.reanchor_interval_frames, 0, 100000));
  s.rest_average_frames = static_cast<int>(t.integer("rest_average_frames", s.rest_average_frames, 1, 10000));
  s.rest_max_chi2_per_dof = t.number("rest_max_chi2_per_dof", s.rest_max_chi2_per_dof, 0.0, 100.0);
  s.rest_max_correlation_z = t.number("rest_max_correlation_z", s.rest_max_correlation_z, 0.0, 100.0);
  s.rest_tolerance_px = t.number("rest_tolerance_px", s.rest_tolerance_px, 0.0, 10.0);
  s.rest_max_motion_chi2 = t.number("rest_max_motion_chi2", s.rest_max_motion_chi2, 0.0, 1e6);
  s.local_fit = t.boolean("local_fit", s.local_fit);
  s.local_fit_max_radius_px = t.number("local_fit_max_radius_px", s.local_fit_max_radius_px, 0.0, 10000.0);
  s.local_fit_agreement_chi2 = t.number("local_fit_agreement_chi2", s.local_fit_agreement_chi2, 0.1, 1e6);
  s.smooth_in_time = t.choice("smooth_in_time", s.smooth_in_time, {"auto", "on", "off"});
  s.smooth_in_time_gamma = t.number("smooth_in_time_gamma", s.smooth_in_time_gamma, 0.1, 100.0);
  s.plate_subset_radius_px =
      static_cast<int>(t.integer("plate_subset_radius_px", s.plate_subset_radius_px, 0, 200));
  s.plate_prefilter_sigma_px = t.number("plate_prefilter_sigma_px", s.plate_prefilter_sigma_px, 0.0, 10.0);
  s.plate_grid_step_px = t.number("plate_grid_step_px", s.plate_grid_step_px, 0.0, 1000.0);
  if (s.plate_grid_step_px > 0.0 && s.plate_grid_step_px < 4.0)
    throw Error("plate_grid_step_px must be 0 (automatic) or at least 4 px",
                {.file = scene.file, .key = t.path_of("plate_grid_step_px")});
  t.finish();
  if (s.neighbour_check && !s.refine)
    throw Error(
        "the neighbour check needs refinement (it compares deformation gradients): set refine or "
        "neighbour_check: false",
        {.file = scene.file, .key = t.path_of("neighbour_check")});
  validate(s);
  return s;
}

void validate(const TrackerSettings& s) {
  const auto fail = [](const std::string& key, const std::string& message) {
    throw Error(message, {.key = "tracking." + key});
  };
  if (!(s.grid_step_px >= 1.0)) fail("grid_step_px", "must be at least 1 px");
  if (s.max_features < 1) fail("max_features", "must be at least 1");
  if (s.window_px < 3 || s.window_px % 2 == 0) fail("window_px", "must be odd and at least 3");
  if (s.pyramid_levels < 0 || s.pyramid_levels > 8) fail("pyramid_levels", "must lie in [0, 8]");
  if (s.subset_radius_px < 3) fail("subset_radius_px", "must be at least 3 px");
  if (s.subset_stride < 1 || s.subset_stride > s.subset_radius_px)
    fail("subset_stride", "must lie in [1, radius]");
  if (s.neighbour_check && !s.refine) fail("neighbour_check", "needs refinement");
  if (s.birth_interval_frames < 1) fail("birth_interval_frames", "must be at least 1");
  if (!(s.forward_backward_px > 0.0)) fail("forward_backward_px", "must be positive");
  if (s.rest_average_frames < 1) fail("rest_average_frames", "must be at least 1");
  if (!(s.rest_max_chi2_per_dof >= 0.0)) fail("rest_max_chi2_per_dof", "must not be negative");
  if (!(s.rest_max_correlation_z >= 0.0)) fail("rest_max_correlation_z", "must not be negative");
  if (!(s.rest_tolerance_px >= 0.0)) fail("rest_tolerance_px", "must not be negative");
  if (!(s.rest_max_motion_chi2 >= 0.0)) fail("rest_max_motion_chi2", "must not be negative");
  if (s.fixed_shape_node_grid < 1 || s.fixed_shape_node_grid > 8)
    fail("fixed_shape_node_grid", "must lie in [1, 8] grid steps");
  if (s.plate_subset_radius_px != 0 && s.plate_subset_radius_px < 3)
    fail("plate_subset_radius_px", "must be 0 (automatic) or at least 3 px");
}

}  // namespace tirstrain::flow
