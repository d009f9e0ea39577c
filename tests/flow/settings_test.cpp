// Presets and the scene's `tracking:` section.
#include <gtest/gtest.h>

#include <functional>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "flow/settings.hpp"
#include "tests/support/expect_error.hpp"

namespace tirstrain::flow {
namespace {

Scene scene_with(const std::string& tracking_yaml) {
  Scene s;
  s.file = "scene.yaml";
  s.tracking = SceneSection::parse(tracking_yaml);
  return s;
}

TEST(Settings, Delhaye2016IsThePapersFixedSettings) {
  const TrackerOptions s = preset_options("delhaye2016", SceneHints{});
  EXPECT_EQ(s.seeding.grid_step_px, 9.0);
  EXPECT_EQ(s.prediction.window_px, 101);
  EXPECT_EQ(s.seeding.max_features, 3000);
  EXPECT_FALSE(s.refine);
  EXPECT_FALSE(s.rounds.enabled);
}

TEST(Settings, AutoIsSizedFromTheRidgePeriod) {
  SceneHints h;
  h.ridge_period_px = 0.45 * 52.0;  // 23.4 px
  h.max_displacement_px = 12.0;
  const TrackerOptions s = preset_options("auto", h);
  EXPECT_EQ(s.prediction.window_px, 17);  // odd(0.7 P)
  EXPECT_DOUBLE_EQ(s.prediction.epsilon_px, 0.1);
  EXPECT_EQ(s.main_match.subset_radius_px, 13);
  EXPECT_EQ(s.seeding.grid_step_px, 8.0);
  EXPECT_TRUE(s.rounds.enabled);
  EXPECT_EQ(s.rounds.subset_radius_px, 20);   // round(0.85 P)
  EXPECT_EQ(s.prediction.pyramid_levels, 2);  // 12 px needs two levels above a 17 px window's reach of ~4 px
  // The fixed-shape rounds on the resampled frame, seeded by an affine match on every 3rd pixel.
  EXPECT_TRUE(s.rounds.resampled);
  EXPECT_EQ(s.rounds.resampled_rounds, 3);
  EXPECT_EQ(s.rounds.node_grid, 2);  // the rounds' field nodes every other seeding-lattice point
  EXPECT_EQ(s.main_match.shape, ShapeFunction::kAffine);
  EXPECT_EQ(s.main_match.subset_stride, 3);
  EXPECT_EQ(s.rounds.subset_stride, 2);
  EXPECT_EQ(s.main_match.period_frames, 4);  // a quarter of the frame-0 tracks take the main match per frame
  EXPECT_EQ(preset_options("delhaye2016", h).main_match.period_frames, 1);
  h.max_displacement_px = 2.0;
  EXPECT_EQ(preset_options("auto", h).prediction.pyramid_levels, 0);
  h.max_displacement_px = 200.0;  // capped: ridges must survive the pyramid (23.4 / 2^L >= 4 px)
  EXPECT_EQ(preset_options("auto", h).prediction.pyramid_levels, 2);
}

TEST(Settings, SceneSectionOverridesPreset) {
  const TrackerOptions s =
      parse_tracking_options(scene_with("{preset: auto, grid_step_px: 6, refine: affine, window_px: 31}"));
  EXPECT_EQ(s.seeding.grid_step_px, 6.0);
  EXPECT_EQ(s.main_match.shape, ShapeFunction::kAffine);
  EXPECT_EQ(s.prediction.window_px, 31);
  EXPECT_EQ(parse_tracking_options(scene_with("{}"), "delhaye2016").prediction.window_px, 101);
  // The moving frame's affine fit: on by default, its keys read from the scene.
  EXPECT_TRUE(s.affine_fit.enabled);
  const TrackerOptions affine =
      parse_tracking_options(scene_with("{affine_fit: false, affine_fit_max_hidden_px: 0.01}"));
  EXPECT_FALSE(affine.affine_fit.enabled);
  EXPECT_EQ(affine.affine_fit.max_hidden_px, 0.01);
  // What the scene sets is pinned: the texture adaptation leaves it alone, and adapts the rest.
  EXPECT_TRUE(s.texture.adapt);
  EXPECT_TRUE(s.pinned.shape);
  EXPECT_FALSE(s.pinned.prefilter);
  EXPECT_FALSE(s.pinned.subset_radius);
  EXPECT_FALSE(s.pinned.fusion);
  EXPECT_TRUE(parse_tracking_options(scene_with("{fusion_weight: 0.1}")).pinned.fusion);
  EXPECT_FALSE(s.pinned.subset_stride);
  EXPECT_TRUE(parse_tracking_options(scene_with("{subset_stride: 1}")).pinned.subset_stride);
  EXPECT_FALSE(s.pinned.fixed_shape_stride);
  EXPECT_TRUE(parse_tracking_options(scene_with("{fixed_shape_stride: 1}")).pinned.fixed_shape_stride);
  EXPECT_FALSE(s.pinned.main_match_period);
  const TrackerOptions every = parse_tracking_options(scene_with("{main_match_period_frames: 1}"));
  EXPECT_TRUE(every.pinned.main_match_period);
  EXPECT_EQ(every.main_match.period_frames, 1);
  EXPECT_EQ(parse_tracking_options(scene_with("{main_match_period_frames: 2}")).main_match.period_frames, 2);
  // The tracks share the work on a checkerboard (2) or a 2×2 pattern (4) of the lattice: 3 has no pattern.
  EXPECT_THROW(parse_tracking_options(scene_with("{main_match_period_frames: 3}")), Error);
  EXPECT_THROW(parse_tracking_options(scene_with("{main_match_period_frames: 8}")), Error);
  EXPECT_FALSE(parse_tracking_options(scene_with("{adapt_to_texture: false}")).texture.adapt);
  EXPECT_FALSE(parse_tracking_options(scene_with("{}"), "delhaye2016").texture.adapt);
  // The anchor is averaged over the frames at rest by the automatic preset only (the paper has no anchor).
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).rest.average_frames, 16);
  EXPECT_EQ(parse_tracking_options(scene_with("{}"), "delhaye2016").rest.average_frames, 1);
  const TrackerOptions rest = parse_tracking_options(
      scene_with("{rest_average_frames: 4, rest_max_chi2_per_dof: 2, rest_max_correlation_z: 4}"));
  EXPECT_EQ(rest.rest.average_frames, 4);
  EXPECT_EQ(rest.rest.max_chi2_per_dof, 2.0);
  EXPECT_EQ(rest.rest.max_correlation_z, 4.0);
  // The plate's band is smoothed by 0.7 px unless the scene says otherwise; negative is an error.
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).plate.prefilter_sigma_px, 0.7);
  EXPECT_EQ(parse_tracking_options(scene_with("{plate_prefilter_sigma_px: 0}")).plate.prefilter_sigma_px,
            0.0);
  EXPECT_THROW(parse_tracking_options(scene_with("{plate_prefilter_sigma_px: -1}")), Error);
  EXPECT_THROW(parse_tracking_options(scene_with("{plate_grid_step_px: 2}")), Error);
  EXPECT_EQ(parse_tracking_options(scene_with("{plate_grid_step_px: 30}")).plate.grid_step_px, 30.0);
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).plate.grid_step_px, 0.0);  // subsets side by side
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).rounds.convergence_px, 0.1);
  EXPECT_EQ(parse_tracking_options(scene_with("{fixed_shape_convergence_px: 0.01}")).rounds.convergence_px,
            0.01);
  const TrackerOptions rounds =
      parse_tracking_options(scene_with("{fixed_shape_resampled: false, fixed_shape_resampled_rounds: 5, "
                                        "lk_max_iterations: 10, lk_epsilon: 0.05}"));
  EXPECT_FALSE(rounds.rounds.resampled);
  EXPECT_EQ(rounds.rounds.resampled_rounds, 5);
  EXPECT_EQ(rounds.prediction.max_iterations, 10);
  EXPECT_EQ(rounds.prediction.epsilon_px, 0.05);
  EXPECT_THROW(parse_tracking_options(scene_with("{fixed_shape_resampled_rounds: 0}")), Error);
  EXPECT_EQ(parse_tracking_options(scene_with("{fixed_shape_node_grid: 1}")).rounds.node_grid, 1);
  EXPECT_THROW(parse_tracking_options(scene_with("{fixed_shape_node_grid: 0}")), Error);
  EXPECT_THROW(parse_tracking_options(scene_with("{fixed_shape_node_grid: 9}")), Error);
  EXPECT_THROW(parse_tracking_options(scene_with("{lk_epsilon: 0}")), Error);
  // The measured contact is inset by 1 px for tracking (both presets) unless the scene says otherwise.
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).border.contact_inset_px, 1.0);
  EXPECT_EQ(parse_tracking_options(scene_with("{}"), "delhaye2016").border.contact_inset_px, 1.0);
  EXPECT_EQ(parse_tracking_options(scene_with("{contact_inset_px: 0}")).border.contact_inset_px, 0.0);
  EXPECT_THROW(parse_tracking_options(scene_with("{contact_inset_px: -1}")), Error);
  // Smoothing in time: on noisy texture by the automatic preset, never by the paper's.
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).smoothing.mode, "auto");
  EXPECT_EQ(parse_tracking_options(scene_with("{}"), "delhaye2016").smoothing.mode, "off");
  const TrackerOptions smooth =
      parse_tracking_options(scene_with("{smooth_in_time: on, smooth_in_time_gamma: 2}"));
  EXPECT_EQ(smooth.smoothing.mode, "on");
  EXPECT_EQ(smooth.smoothing.gamma, 2.0);
  EXPECT_THROW(parse_tracking_options(scene_with("{smooth_in_time: sometimes}")), Error);
  EXPECT_THROW(parse_tracking_options(scene_with("{smooth_in_time_gamma: 0}")), Error);
  // The local fit: second order, on in the automatic preset, off in the paper's; affine on request.
  EXPECT_TRUE(parse_tracking_options(scene_with("{}")).local_fit.enabled);
  EXPECT_EQ(parse_tracking_options(scene_with("{}")).local_fit.order, 2);
  EXPECT_FALSE(parse_tracking_options(scene_with("{}"), "delhaye2016").local_fit.enabled);
  EXPECT_FALSE(parse_tracking_options(scene_with("{local_fit: false}")).local_fit.enabled);
  EXPECT_EQ(parse_tracking_options(scene_with("{local_fit_order: 1}")).local_fit.order, 1);
  EXPECT_THROW(parse_tracking_options(scene_with("{local_fit_order: 3}")), Error);
}

TEST(Settings, StrictParsingNamesTheKey) {
  try {
    parse_tracking_options(scene_with("{grid_stepp_px: 6}"));
    FAIL() << "unknown key accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("tracking.grid_stepp_px"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_tracking_options(scene_with("{window_px: 20}")), Error);  // even
  EXPECT_THROW(parse_tracking_options(scene_with("{preset: fast}")), Error);   // unknown preset
  EXPECT_THROW(parse_tracking_options(scene_with("{}"), "paper"), Error);      // --preset
  EXPECT_THROW(parse_tracking_options(scene_with("{refine: none}")), Error);   // check needs refine
  EXPECT_NO_THROW(parse_tracking_options(scene_with("{refine: none, neighbour_check: false}")));
}

// Options built in code are checked group by group, and the error names the scene key of the bad value.
TEST(Settings, EachGroupsCheckNamesTheSceneKey) {
  const TrackerOptions good = preset_options("auto", SceneHints{});
  EXPECT_NO_THROW(good.check());
  EXPECT_NO_THROW(preset_options("delhaye2016", SceneHints{}).check());
  const std::vector<std::pair<std::function<void(TrackerOptions&)>, std::string>> cases = {
      {[](TrackerOptions& o) { o.seeding.grid_step_px = 0.5; }, "tracking.grid_step_px"},
      {[](TrackerOptions& o) { o.births.interval_frames = 0; }, "tracking.birth_interval_frames"},
      {[](TrackerOptions& o) { o.border.exclusion_px = -1.0; }, "tracking.border_exclusion_px"},
      {[](TrackerOptions& o) { o.prediction.window_px = 20; }, "tracking.window_px"},
      {[](TrackerOptions& o) { o.main_match.period_frames = 3; }, "tracking.main_match_period_frames"},
      {[](TrackerOptions& o) { o.main_match.solver.convergence_px = 0.0; }, "tracking.convergence_px"},
      {[](TrackerOptions& o) { o.rounds.node_grid = 9; }, "tracking.fixed_shape_node_grid"},
      {[](TrackerOptions& o) { o.neighbours.tolerance_px = 0.0; }, "tracking.neighbour_tolerance_px"},
      {[](TrackerOptions& o) { o.fusion.sigma_px = -1.0; }, "tracking.fusion_sigma_px"},
      {[](TrackerOptions& o) { o.local_fit.agreement_chi2 = 0.0; }, "tracking.local_fit_agreement_chi2"},
      {[](TrackerOptions& o) { o.local_fit.order = 0; }, "tracking.local_fit_order"},
      {[](TrackerOptions& o) { o.affine_fit.max_hidden_px = -0.1; }, "tracking.affine_fit_max_hidden_px"},
      {[](TrackerOptions& o) { o.reanchor.interval_frames = -1; }, "tracking.reanchor_interval_frames"},
      {[](TrackerOptions& o) { o.rest.average_frames = 0; }, "tracking.rest_average_frames"},
      {[](TrackerOptions& o) { o.smoothing.mode = "sometimes"; }, "tracking.smooth_in_time"},
      {[](TrackerOptions& o) { o.plate.grid_step_px = 2.0; }, "tracking.plate_grid_step_px"},
      {[](TrackerOptions& o) { o.texture.min_quadratic_snr = -1.0; }, "tracking.min_quadratic_snr"},
      {[](TrackerOptions& o) { o.refine = false; }, "tracking.neighbour_check"},
  };
  for (const auto& [edit, key] : cases) {
    TrackerOptions bad = good;
    edit(bad);
    EXPECT_EQ(testing::expect_error([&] { bad.check(); }).context().key, key);
  }
}

}  // namespace
}  // namespace tirstrain::flow
