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

namespace {

// Delhaye et al. 2016: features on a 9 px grid, 101×101 px KLT window, up to 3000 features, tracked frame to
// frame with a three-level pyramid (levels 0..2) and no refinement against the first frame.
void apply_delhaye2016(TrackerOptions& s) {
  s.seeding.grid_step_px = 9.0;
  s.seeding.max_features = 3000;
  s.prediction.window_px = 101;
  s.prediction.pyramid_levels = 2;
  s.refine = false;
  s.neighbours.enabled = false;
  s.rounds.enabled = false;
  s.fusion.sigma_px = 0.0;
  s.prediction.global_jump = false;
  s.reanchor.interval_frames = 0;
  s.births.enabled = true;
}

// Sized from the ridge period P: the LK window spans most of a period (enough texture to be well posed,
// small enough that the field is nearly uniform inside it); the main subset has a radius of about 0.55 P,
// where a second-order subset's curvature bias is negligible and its noise is still low; seeds on a grid of
// P/3 (three samples per ridge period, the finest spacing at which neighbouring subsets still differ).
void size_from_ridge_period(TrackerOptions& s, double period) {
  s.ridge_period_px = period;
  s.seeding.grid_step_px = std::max(3.0, std::round(period / 3.0));
  // LK only seeds the subset match, and a window a full period wide costs half again as much for the same
  // answers.
  s.prediction.window_px = odd(0.7 * period);
  s.prediction.epsilon_px = 0.1;  // LK stops at 0.1 px steps: the match converges to 0.01 px from there
  s.main_match.subset_radius_px = std::max(5, static_cast<int>(std::lround(0.55 * period)));
  s.neighbours.radius_px = 3.0 * s.seeding.grid_step_px;
  s.fusion.sigma_px = s.seeding.grid_step_px;
  s.border.exclusion_px = std::round(0.6 * period);
  s.seeding.border_margin_px = s.border.exclusion_px;
  s.rounds.subset_radius_px = static_cast<int>(std::lround(0.85 * period));
}

// The pyramid is as deep as the largest expected displacement needs, but never so deep that the ridges
// (P / 2^L px at level L) fall below 4 px and vanish in the pyramid's smoothing.
int pyramid_levels_for(double max_displacement_px, double period, int window_px) {
  const double reach_px = 0.25 * window_px;  // what one level of LK follows reliably
  const int needed = max_displacement_px > reach_px
                         ? static_cast<int>(std::ceil(std::log2(max_displacement_px / reach_px)))
                         : 0;
  const int allowed = std::max(0, static_cast<int>(std::floor(std::log2(period / 4.0))));
  return std::clamp(needed, 0, allowed);
}

// The rounds set the final positions: three fit-and-match rounds (each lowers the displacement and strain
// noise for a few per cent more time; the smoother field rounds the slip front only a little), on the frame
// resampled once per round through the neighbours' fitted field (flow/shape_field.hpp), with field nodes two
// grid steps apart (0.8 σ: a quarter of the nodes of a one-step lattice, the same accuracy within a few per
// cent). Their translation steps read every 2nd pixel each way: a translation needs far fewer samples than
// the wide subset's reach gives it, and the frames are smoothed by ≥ P/24 ≈ 1 px on noisy texture. Small
// contacts keep every pixel (FeatureTracker, adapt_to_texture).
void automatic_rounds(TrackerOptions::Rounds& r) {
  r.sigma_grid = 2.5;
  r.iterations = 3;
  r.resampled = true;
  r.resampled_rounds = 3;
  r.node_grid = 2;
  r.subset_stride = 2;
}

// The main match only seeds the rounds: an affine subset on every 3rd pixel does, at a third of the cost of
// a second-order subset on every pixel, and each interior frame-0 track takes it every 4th frame (a quarter
// of them per frame on a 2×2 pattern of the seeding lattice; the others start the rounds where their matched
// neighbours put them). Noisy texture, border tracks and small contacts match more (adapt_to_texture).
void automatic_main_match(TrackerOptions::MainMatch& m) {
  m.shape = ShapeFunction::kAffine;
  m.subset_stride = 3;
  m.period_frames = 4;
  // The rounds and the fusion decide the final position; the full-shape solve only has to land within a
  // hundredth of a pixel of it.
  m.solver.convergence_px = 0.01;
  // Keys' kernel reads a sub-pixel shift of a fine texture up to 5 % short (0.010 px at 0.2 px on speckle);
  // the cubic B-spline of the frame's coefficients reads it within 0.3 %.
  m.solver.interpolation = Interpolation::kCubicBSpline;
  // A subset with less than 60 % of its pixels left inside the contact (after the border exclusion) has left
  // it: its position would mostly be an extrapolation of the warp across the border band, where the fixed
  // contrast fade pulls it back.
  m.solver.min_valid_fraction = 0.6;
}

void apply_automatic(TrackerOptions& s, const SceneHints& hints) {
  const double period = hints.ridge_period_px;
  size_from_ridge_period(s, period);
  s.prediction.pyramid_levels = pyramid_levels_for(hints.max_displacement_px, period, s.prediction.window_px);
  automatic_rounds(s.rounds);
  automatic_main_match(s.main_match);
  s.fusion.weight = 0.1;
  s.plate.subset_radius_px = 0;
  s.texture.adapt = true;
  s.rest.average_frames = 16;
  s.smoothing.mode = "auto";
  s.local_fit.enabled = true;
}

}  // namespace

TrackerOptions preset_options(const std::string& name, const SceneHints& hints) {
  TrackerOptions s;
  s.preset = name;
  s.prediction.max_displacement_px = hints.max_displacement_px;
  if (name == "delhaye2016")
    apply_delhaye2016(s);
  else if (name == "auto")
    apply_automatic(s, hints);
  else
    throw Error("unknown tracking preset '" + name + "' (known: auto, delhaye2016)",
                {.key = "tracking.preset"});
  return s;
}

namespace {

int integer(YamlSection& t, const std::string& key, int fallback, long min, long max) {
  return static_cast<int>(t.integer(key, fallback, min, max));
}

void parse_seeding(YamlSection& t, TrackerOptions::Seeding& o) {
  o.grid_step_px = t.number("grid_step_px", o.grid_step_px, 1.0, 1000.0);
  o.max_features = integer(t, "max_features", o.max_features, 1, 1000000);
  o.min_eigen_quality = t.number("min_eigen_quality", o.min_eigen_quality, 0.0, 1.0);
  o.border_margin_px = t.number("border_margin_px", o.border_margin_px, 0.0, 1000.0);
}

void parse_births(YamlSection& t, TrackerOptions::Births& o) {
  o.enabled = t.boolean("births", o.enabled);
  o.extrapolate_all = t.boolean("extrapolate_all_births", o.extrapolate_all);
  o.interval_frames = integer(t, "birth_interval_frames", o.interval_frames, 1, 100000);
}

void parse_border(YamlSection& t, TrackerOptions::Border& o) {
  o.exclusion_px = t.number("border_exclusion_px", o.exclusion_px, 0.0, 1000.0);
  o.contact_inset_px = t.number("contact_inset_px", o.contact_inset_px, 0.0, 100.0);
}

void parse_prediction(YamlSection& t, TrackerOptions::Prediction& o) {
  o.window_px = integer(t, "window_px", o.window_px, 3, 401);
  if (o.window_px % 2 == 0)
    throw Error("the LK window side must be odd", {.file = t.file(), .key = t.path_of("window_px")});
  o.pyramid_levels = integer(t, "pyramid_levels", o.pyramid_levels, 0, 8);
  o.forward_backward_px = t.number("forward_backward_px", o.forward_backward_px, 0.0, 1000.0);
  o.max_iterations = integer(t, "lk_max_iterations", o.max_iterations, 1, 1000);
  o.epsilon_px = t.number("lk_epsilon", o.epsilon_px, 1e-6, 10.0);
  o.global_jump = t.boolean("global_prediction", o.global_jump);
}

// `refine` sets both whether tracks are refined and the main match's shape function.
void parse_refine(YamlSection& t, TrackerOptions& s) {
  const std::string refine = t.choice("refine", s.refine ? to_string(s.main_match.shape) : "none",
                                      {"none", "translation", "affine", "quadratic"});
  s.refine = refine != "none";
  if (refine == "translation") s.main_match.shape = ShapeFunction::kTranslation;
  if (refine == "affine") s.main_match.shape = ShapeFunction::kAffine;
  if (refine == "quadratic") s.main_match.shape = ShapeFunction::kQuadratic;
}

void parse_main_match(YamlSection& t, TrackerOptions::MainMatch& o) {
  o.subset_radius_px = integer(t, "subset_radius_px", o.subset_radius_px, 3, 200);
  o.prefilter_sigma_px = t.number("prefilter_sigma_px", o.prefilter_sigma_px, 0.0, 20.0);
  o.subset_stride = integer(t, "subset_stride", o.subset_stride, 1, 8);
  o.solver.max_iterations = integer(t, "max_iterations", o.solver.max_iterations, 1, 1000);
  o.solver.convergence_px = t.number("convergence_px", o.solver.convergence_px, 1e-6, 1.0);
  const bool spline = o.solver.interpolation == Interpolation::kCubicBSpline;
  o.solver.interpolation = t.choice("interpolation", spline ? "cubic_bspline" : "keys",
                                    {"keys", "cubic_bspline"}) == "cubic_bspline"
                               ? Interpolation::kCubicBSpline
                               : Interpolation::kKeys;
  o.max_correction_px = t.number("max_correction_px", o.max_correction_px, 0.01, 1000.0);
  o.min_zncc = t.number("min_zncc", o.min_zncc, -1.0, 1.0);
  o.period_frames = integer(t, "main_match_period_frames", o.period_frames, 1, 4);
  if (o.period_frames == 3)
    throw Error("main_match_period_frames must be 1, 2 or 4 (the tracks share the work on the lattice)",
                {.file = t.file(), .key = t.path_of("main_match_period_frames")});
}

void parse_rounds(YamlSection& t, TrackerOptions::Rounds& o) {
  o.enabled = t.boolean("fixed_shape_pass", o.enabled);
  o.sigma_grid = t.number("fixed_shape_sigma_grid", o.sigma_grid, 0.5, 20.0);
  o.iterations = integer(t, "fixed_shape_iterations", o.iterations, 1, 10);
  o.convergence_px = t.number("fixed_shape_convergence_px", o.convergence_px, 1e-6, 10.0);
  o.resampled = t.boolean("fixed_shape_resampled", o.resampled);
  o.resampled_rounds = integer(t, "fixed_shape_resampled_rounds", o.resampled_rounds, 1, 100);
  o.node_grid = integer(t, "fixed_shape_node_grid", o.node_grid, 1, 8);
  o.smoothed_gradient = t.boolean("smoothed_gradient", o.smoothed_gradient);
  o.subset_radius_px = integer(t, "fixed_shape_radius_px", o.subset_radius_px, 0, 200);
  o.subset_stride = integer(t, "fixed_shape_stride", o.subset_stride, 1, 8);
}

void parse_neighbours(YamlSection& t, TrackerOptions::Neighbours& o) {
  o.enabled = t.boolean("neighbour_check", o.enabled);
  o.tolerance_px = t.number("neighbour_tolerance_px", o.tolerance_px, 0.01, 100.0);
}

void parse_fusion(YamlSection& t, TrackerOptions::Fusion& o) {
  o.sigma_px = t.number("fusion_sigma_px", o.sigma_px, 0.0, 1000.0);
  o.weight = t.number("fusion_weight", o.weight, 0.0, 1000.0);
  o.sweeps = integer(t, "fusion_sweeps", o.sweeps, 0, 1000);
}

void parse_local_fit(YamlSection& t, TrackerOptions::LocalFit& o) {
  o.enabled = t.boolean("local_fit", o.enabled);
  o.max_radius_px = t.number("local_fit_max_radius_px", o.max_radius_px, 0.0, 10000.0);
  o.agreement_chi2 = t.number("local_fit_agreement_chi2", o.agreement_chi2, 0.1, 1e6);
  o.order = integer(t, "local_fit_order", o.order, 1, 2);
  o.per_component = t.boolean("local_fit_per_component", o.per_component);
}

void parse_affine_fit(YamlSection& t, TrackerOptions::AffineFit& o) {
  o.enabled = t.boolean("affine_fit", o.enabled);
  o.max_chi2_per_dof = t.number("affine_fit_max_chi2_per_dof", o.max_chi2_per_dof, 0.0, 100.0);
  o.max_correlation_z = t.number("affine_fit_max_correlation_z", o.max_correlation_z, 0.0, 100.0);
  o.max_hidden_px = t.number("affine_fit_max_hidden_px", o.max_hidden_px, 0.0, 10.0);
}

void parse_rest(YamlSection& t, TrackerOptions::Rest& o) {
  o.average_frames = integer(t, "rest_average_frames", o.average_frames, 1, 10000);
  o.max_chi2_per_dof = t.number("rest_max_chi2_per_dof", o.max_chi2_per_dof, 0.0, 100.0);
  o.max_correlation_z = t.number("rest_max_correlation_z", o.max_correlation_z, 0.0, 100.0);
  o.tolerance_px = t.number("rest_tolerance_px", o.tolerance_px, 0.0, 10.0);
  o.max_motion_chi2 = t.number("rest_max_motion_chi2", o.max_motion_chi2, 0.0, 1e6);
}

void parse_smoothing(YamlSection& t, TrackerOptions::Smoothing& o) {
  o.mode = t.choice("smooth_in_time", o.mode, {"auto", "on", "off"});
  o.gamma = t.number("smooth_in_time_gamma", o.gamma, 0.1, 100.0);
}

void parse_plate(YamlSection& t, TrackerOptions::Plate& o) {
  o.subset_radius_px = integer(t, "plate_subset_radius_px", o.subset_radius_px, 0, 200);
  o.prefilter_sigma_px = t.number("plate_prefilter_sigma_px", o.prefilter_sigma_px, 0.0, 10.0);
  o.grid_step_px = t.number("plate_grid_step_px", o.grid_step_px, 0.0, 1000.0);
  if (o.grid_step_px > 0.0 && o.grid_step_px < 4.0)
    throw Error("plate_grid_step_px must be 0 (automatic) or at least 4 px",
                {.file = t.file(), .key = t.path_of("plate_grid_step_px")});
}

void parse_texture(YamlSection& t, TrackerOptions::Texture& o) {
  o.adapt = t.boolean("adapt_to_texture", o.adapt);
  o.min_quadratic_snr = t.number("min_quadratic_snr", o.min_quadratic_snr, 0.0, 1e6);
  o.min_unfiltered_snr = t.number("min_unfiltered_snr", o.min_unfiltered_snr, 0.0, 1e6);
}

TrackerOptions::Pinned pinned_by(const YamlSection& t) {
  return {t.has("refine"),
          t.has("prefilter_sigma_px"),
          t.has("subset_radius_px"),
          t.has("fusion_sigma_px") || t.has("fusion_weight") || t.has("fusion_sweeps"),
          t.has("subset_stride"),
          t.has("fixed_shape_stride"),
          t.has("main_match_period_frames")};
}

std::string chosen_preset(YamlSection& t, const std::string& preset_override) {
  const std::string preset = t.choice("preset", "auto", preset_names());
  if (preset_override.empty()) return preset;
  if (std::find(preset_names().begin(), preset_names().end(), preset_override) == preset_names().end())
    throw Error("unknown tracking preset '" + preset_override + "' (known: auto, delhaye2016)",
                {.key = "--preset"});
  return preset_override;
}

}  // namespace

TrackerOptions parse_tracking_options(const Scene& scene, const std::string& preset_override) {
  YamlSection t(scene.tracking, scene.file, "tracking");
  const std::string preset = chosen_preset(t, preset_override);
  SceneHints hints = hints_from_scene(scene);
  hints.max_displacement_px = t.number("max_displacement_px", hints.max_displacement_px, 0.0, 1000.0);
  TrackerOptions s = preset_options(preset, hints);
  parse_seeding(t, s.seeding);
  parse_births(t, s.births);
  parse_prediction(t, s.prediction);
  parse_refine(t, s);
  s.pinned = pinned_by(t);
  parse_texture(t, s.texture);
  parse_main_match(t, s.main_match);
  parse_rounds(t, s.rounds);
  parse_neighbours(t, s.neighbours);
  parse_border(t, s.border);
  parse_fusion(t, s.fusion);
  s.reanchor.interval_frames = integer(t, "reanchor_interval_frames", s.reanchor.interval_frames, 0, 100000);
  parse_rest(t, s.rest);
  parse_local_fit(t, s.local_fit);
  parse_affine_fit(t, s.affine_fit);
  parse_smoothing(t, s.smoothing);
  parse_plate(t, s.plate);
  t.finish();
  if (s.neighbours.enabled && !s.refine)
    throw Error(
        "the neighbour check needs refinement (it compares deformation gradients): set refine or "
        "neighbour_check: false",
        {.file = scene.file, .key = t.path_of("neighbour_check")});
  s.check();
  return s;
}

namespace {

[[noreturn]] void fail(const std::string& key, const std::string& message) {
  throw Error(message, {.key = "tracking." + key});
}

}  // namespace

void TrackerOptions::Seeding::check() const {
  if (!(grid_step_px >= 1.0)) fail("grid_step_px", "must be at least 1 px");
  if (max_features < 1) fail("max_features", "must be at least 1");
  if (!(min_eigen_quality >= 0.0 && min_eigen_quality <= 1.0))
    fail("min_eigen_quality", "must lie in [0, 1]");
  if (eigen_block_px < 3) fail("eigen_block_px", "must be at least 3 px");
  if (!(border_margin_px >= 0.0)) fail("border_margin_px", "must not be negative");
}

void TrackerOptions::Births::check() const {
  if (interval_frames < 1) fail("birth_interval_frames", "must be at least 1");
}

void TrackerOptions::Border::check() const {
  if (!(exclusion_px >= 0.0)) fail("border_exclusion_px", "must not be negative");
  if (!(contact_inset_px >= 0.0)) fail("contact_inset_px", "must not be negative");
}

void TrackerOptions::Prediction::check() const {
  if (!(max_displacement_px >= 0.0)) fail("max_displacement_px", "must not be negative");
  if (window_px < 3 || window_px % 2 == 0) fail("window_px", "must be odd and at least 3");
  if (pyramid_levels < 0 || pyramid_levels > 8) fail("pyramid_levels", "must lie in [0, 8]");
  if (max_iterations < 1) fail("lk_max_iterations", "must be at least 1");
  if (!(epsilon_px > 0.0)) fail("lk_epsilon", "must be positive");
  if (!(forward_backward_px > 0.0)) fail("forward_backward_px", "must be positive");
}

void TrackerOptions::MainMatch::check() const {
  if (!(prefilter_sigma_px >= 0.0)) fail("prefilter_sigma_px", "must not be negative");
  if (subset_radius_px < 3) fail("subset_radius_px", "must be at least 3 px");
  if (subset_stride < 1 || subset_stride > subset_radius_px) fail("subset_stride", "must lie in [1, radius]");
  if (solver.max_iterations < 1) fail("max_iterations", "must be at least 1");
  if (!(solver.convergence_px > 0.0)) fail("convergence_px", "must be positive");
  solver.check();
  if (!(min_zncc >= -1.0 && min_zncc <= 1.0)) fail("min_zncc", "must lie in [-1, 1]");
  if (period_frames != 1 && period_frames != 2 && period_frames != 4)
    fail("main_match_period_frames", "must be 1, 2 or 4 (the tracks share the work on the lattice)");
  if (!(max_correction_px > 0.0)) fail("max_correction_px", "must be positive");
}

void TrackerOptions::Rounds::check() const {
  if (subset_radius_px < 0) fail("fixed_shape_radius_px", "must not be negative");
  if (subset_stride < 1) fail("fixed_shape_stride", "must be at least 1");
  if (!(sigma_grid > 0.0)) fail("fixed_shape_sigma_grid", "must be positive");
  if (iterations < 1) fail("fixed_shape_iterations", "must be at least 1");
  if (!(convergence_px > 0.0)) fail("fixed_shape_convergence_px", "must be positive");
  if (resampled_rounds < 1) fail("fixed_shape_resampled_rounds", "must be at least 1");
  if (node_grid < 1 || node_grid > 8) fail("fixed_shape_node_grid", "must lie in [1, 8] grid steps");
}

void TrackerOptions::Neighbours::check() const {
  if (!(radius_px > 0.0)) fail("neighbour_radius_px", "must be positive");
  if (!(tolerance_px > 0.0)) fail("neighbour_tolerance_px", "must be positive");
  if (min_count < 1) fail("min_neighbours", "must be at least 1");
}

void TrackerOptions::Fusion::check() const {
  if (!(sigma_px >= 0.0)) fail("fusion_sigma_px", "must not be negative");
  if (!(weight >= 0.0)) fail("fusion_weight", "must not be negative");
  if (sweeps < 0) fail("fusion_sweeps", "must not be negative");
}

void TrackerOptions::LocalFit::check() const {
  if (!(max_radius_px >= 0.0)) fail("local_fit_max_radius_px", "must not be negative");
  if (!(agreement_chi2 > 0.0)) fail("local_fit_agreement_chi2", "must be positive");
  if (order != 1 && order != 2) fail("local_fit_order", "must be 1 (affine) or 2 (second order)");
}

void TrackerOptions::AffineFit::check() const {
  if (!(max_chi2_per_dof >= 0.0)) fail("affine_fit_max_chi2_per_dof", "must not be negative");
  if (!(max_correlation_z >= 0.0)) fail("affine_fit_max_correlation_z", "must not be negative");
  if (!(max_hidden_px >= 0.0)) fail("affine_fit_max_hidden_px", "must not be negative");
}

void TrackerOptions::Reanchor::check() const {
  if (interval_frames < 0) fail("reanchor_interval_frames", "must not be negative");
  if (!(tolerance_px > 0.0)) fail("reanchor_tolerance_px", "must be positive");
}

void TrackerOptions::Rest::check() const {
  if (average_frames < 1) fail("rest_average_frames", "must be at least 1");
  if (!(max_chi2_per_dof >= 0.0)) fail("rest_max_chi2_per_dof", "must not be negative");
  if (!(max_correlation_z >= 0.0)) fail("rest_max_correlation_z", "must not be negative");
  if (!(tolerance_px >= 0.0)) fail("rest_tolerance_px", "must not be negative");
  if (!(max_motion_chi2 >= 0.0)) fail("rest_max_motion_chi2", "must not be negative");
}

void TrackerOptions::Smoothing::check() const {
  if (mode != "auto" && mode != "on" && mode != "off") fail("smooth_in_time", "must be auto, on or off");
  if (!(gamma > 0.0)) fail("smooth_in_time_gamma", "must be positive");
}

void TrackerOptions::Plate::check() const {
  if (subset_radius_px != 0 && subset_radius_px < 3)
    fail("plate_subset_radius_px", "must be 0 (automatic) or at least 3 px");
  if (grid_step_px != 0.0 && !(grid_step_px >= 4.0))
    fail("plate_grid_step_px", "must be 0 (automatic) or at least 4 px");
  if (!(prefilter_sigma_px >= 0.0)) fail("plate_prefilter_sigma_px", "must not be negative");
}

void TrackerOptions::Texture::check() const {
  if (!(min_unfiltered_snr >= 0.0)) fail("min_unfiltered_snr", "must not be negative");
  if (!(min_quadratic_snr >= 0.0)) fail("min_quadratic_snr", "must not be negative");
}

void TrackerOptions::check() const {
  seeding.check();
  births.check();
  border.check();
  prediction.check();
  main_match.check();
  rounds.check();
  neighbours.check();
  fusion.check();
  local_fit.check();
  affine_fit.check();
  reanchor.check();
  rest.check();
  smoothing.check();
  plate.check();
  texture.check();
  if (neighbours.enabled && !refine) fail("neighbour_check", "needs refinement");
}

}  // namespace tirstrain::flow
