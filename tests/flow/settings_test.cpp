// Presets and the scene's `tracking:` section.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "core/error.hpp"
#include "flow/settings.hpp"

namespace tirstrain::flow {
namespace {

Scene scene_with(const std::string& tracking_yaml) {
  Scene s;
  s.file = "scene.yaml";
  s.tracking = YAML::Load(tracking_yaml);
  return s;
}

TEST(Settings, Delhaye2016IsThePapersFixedSettings) {
  const TrackerSettings s = preset_settings("delhaye2016", SceneHints{});
  EXPECT_EQ(s.grid_step_px, 9.0);
  EXPECT_EQ(s.window_px, 101);
  EXPECT_EQ(s.max_features, 3000);
  EXPECT_FALSE(s.refine);
  EXPECT_FALSE(s.fixed_shape_pass);
}

TEST(Settings, AutoIsSizedFromTheRidgePeriod) {
  SceneHints h;
  h.ridge_period_px = 0.45 * 52.0;  // 23.4 px
  h.max_displacement_px = 12.0;
  const TrackerSettings s = preset_settings("auto", h);
  EXPECT_EQ(s.window_px, 17);  // odd(0.7 P)
  EXPECT_DOUBLE_EQ(s.lk_epsilon, 0.1);
  EXPECT_EQ(s.subset_radius_px, 13);
  EXPECT_EQ(s.grid_step_px, 8.0);
  EXPECT_TRUE(s.fixed_shape_pass);
  EXPECT_EQ(s.fixed_shape_radius_px, 20);  // round(0.85 P)
  EXPECT_EQ(s.pyramid_levels, 2);          // 12 px needs two levels above a 17 px window's reach of ~4 px
  // The fixed-shape rounds on the resampled frame, seeded by an affine match on every 3rd pixel.
  EXPECT_TRUE(s.fixed_shape_resampled);
  EXPECT_EQ(s.fixed_shape_resampled_rounds, 3);
  EXPECT_EQ(s.fixed_shape_node_grid, 2);  // the rounds' field nodes every other seeding-lattice point
  EXPECT_EQ(s.shape, ShapeFunction::kAffine);
  EXPECT_EQ(s.subset_stride, 3);
  EXPECT_EQ(s.fixed_shape_stride, 2);
  EXPECT_EQ(s.main_match_period_frames, 4);  // a quarter of the frame-0 tracks take the main match per frame
  EXPECT_EQ(preset_settings("delhaye2016", h).main_match_period_frames, 1);
  h.max_displacement_px = 2.0;
  EXPECT_EQ(preset_settings("auto", h).pyramid_levels, 0);
  h.max_displacement_px = 200.0;  // capped: ridges must survive the pyramid (23.4 / 2^L >= 4 px)
  EXPECT_EQ(preset_settings("auto", h).pyramid_levels, 2);
}

TEST(Settings, SceneSectionOverridesPreset) {
  const TrackerSettings s =
      parse_tracking_settings(scene_with("{preset: auto, grid_step_px: 6, refine: affine, window_px: 31}"));
  EXPECT_EQ(s.grid_step_px, 6.0);
  EXPECT_EQ(s.shape, ShapeFunction::kAffine);
  EXPECT_EQ(s.window_px, 31);
  EXPECT_EQ(parse_tracking_settings(scene_with("{}"), "delhaye2016").window_px, 101);
  // What the scene sets is pinned: the texture adaptation leaves it alone, and adapts the rest.
  EXPECT_TRUE(s.adapt_to_texture);
  EXPECT_TRUE(s.pinned.shape);
  EXPECT_FALSE(s.pinned.prefilter);
  EXPECT_FALSE(s.pinned.subset_radius);
  EXPECT_FALSE(s.pinned.fusion);
  EXPECT_TRUE(parse_tracking_settings(scene_with("{fusion_weight: 0.1}")).pinned.fusion);
  EXPECT_FALSE(s.pinned.subset_stride);
  EXPECT_TRUE(parse_tracking_settings(scene_with("{subset_stride: 1}")).pinned.subset_stride);
  EXPECT_FALSE(s.pinned.fixed_shape_stride);
  EXPECT_TRUE(parse_tracking_settings(scene_with("{fixed_shape_stride: 1}")).pinned.fixed_shape_stride);
  EXPECT_FALSE(s.pinned.main_match_period);
  const TrackerSettings every = parse_tracking_settings(scene_with("{main_match_period_frames: 1}"));
  EXPECT_TRUE(every.pinned.main_match_period);
  EXPECT_EQ(every.main_match_period_frames, 1);
  EXPECT_EQ(parse_tracking_settings(scene_with("{main_match_period_frames: 2}")).main_match_period_frames, 2);
  // The tracks share the work on a checkerboard (2) or a 2×2 pattern (4) of the lattice: 3 has no pattern.
  EXPECT_THROW(parse_tracking_settings(scene_with("{main_match_period_frames: 3}")), Error);
  EXPECT_THROW(parse_tracking_settings(scene_with("{main_match_period_frames: 8}")), Error);
  EXPECT_FALSE(parse_tracking_settings(scene_with("{adapt_to_texture: false}")).adapt_to_texture);
  EXPECT_FALSE(parse_tracking_settings(scene_with("{}"), "delhaye2016").adapt_to_texture);
  // The anchor is averaged over the frames at rest by the automatic preset only (the paper has no anchor).
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).rest_average_frames, 16);
  EXPECT_EQ(parse_tracking_settings(scene_with("{}"), "delhaye2016").rest_average_frames, 1);
  const TrackerSettings rest = parse_tracking_settings(
      scene_with("{rest_average_frames: 4, rest_max_chi2_per_dof: 2, rest_max_correlation_z: 4}"));
  EXPECT_EQ(rest.rest_average_frames, 4);
  EXPECT_EQ(rest.rest_max_chi2_per_dof, 2.0);
  EXPECT_EQ(rest.rest_max_correlation_z, 4.0);
  // The plate's band is smoothed by 0.7 px unless the scene says otherwise; negative is an error.
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).plate_prefilter_sigma_px, 0.7);
  EXPECT_EQ(parse_tracking_settings(scene_with("{plate_prefilter_sigma_px: 0}")).plate_prefilter_sigma_px,
            0.0);
  EXPECT_THROW(parse_tracking_settings(scene_with("{plate_prefilter_sigma_px: -1}")), Error);
  EXPECT_THROW(parse_tracking_settings(scene_with("{plate_grid_step_px: 2}")), Error);
  EXPECT_EQ(parse_tracking_settings(scene_with("{plate_grid_step_px: 30}")).plate_grid_step_px, 30.0);
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).plate_grid_step_px, 0.0);  // subsets side by side
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).fixed_shape_convergence_px, 0.1);
  EXPECT_EQ(
      parse_tracking_settings(scene_with("{fixed_shape_convergence_px: 0.01}")).fixed_shape_convergence_px,
      0.01);
  const TrackerSettings rounds =
      parse_tracking_settings(scene_with("{fixed_shape_resampled: false, fixed_shape_resampled_rounds: 5, "
                                         "lk_max_iterations: 10, lk_epsilon: 0.05}"));
  EXPECT_FALSE(rounds.fixed_shape_resampled);
  EXPECT_EQ(rounds.fixed_shape_resampled_rounds, 5);
  EXPECT_EQ(rounds.lk_max_iterations, 10);
  EXPECT_EQ(rounds.lk_epsilon, 0.05);
  EXPECT_THROW(parse_tracking_settings(scene_with("{fixed_shape_resampled_rounds: 0}")), Error);
  EXPECT_EQ(parse_tracking_settings(scene_with("{fixed_shape_node_grid: 1}")).fixed_shape_node_grid, 1);
  EXPECT_THROW(parse_tracking_settings(scene_with("{fixed_shape_node_grid: 0}")), Error);
  EXPECT_THROW(parse_tracking_settings(scene_with("{fixed_shape_node_grid: 9}")), Error);
  EXPECT_THROW(parse_tracking_settings(scene_with("{lk_epsilon: 0}")), Error);
  // The measured contact is inset by 1 px for tracking (both presets) unless the scene says otherwise.
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).contact_inset_px, 1.0);
  EXPECT_EQ(parse_tracking_settings(scene_with("{}"), "delhaye2016").contact_inset_px, 1.0);
  EXPECT_EQ(parse_tracking_settings(scene_with("{contact_inset_px: 0}")).contact_inset_px, 0.0);
  EXPECT_THROW(parse_tracking_settings(scene_with("{contact_inset_px: -1}")), Error);
  // Smoothing in time: on noisy texture by the automatic preset, never by the paper's.
  EXPECT_EQ(parse_tracking_settings(scene_with("{}")).smooth_in_time, "auto");
  EXPECT_EQ(parse_tracking_settings(scene_with("{}"), "delhaye2016").smooth_in_time, "off");
  const TrackerSettings smooth =
      parse_tracking_settings(scene_with("{smooth_in_time: on, smooth_in_time_gamma: 2}"));
  EXPECT_EQ(smooth.smooth_in_time, "on");
  EXPECT_EQ(smooth.smooth_in_time_gamma, 2.0);
  EXPECT_THROW(parse_tracking_settings(scene_with("{smooth_in_time: sometimes}")), Error);
  EXPECT_THROW(parse_tracking_settings(scene_with("{smooth_in_time_gamma: 0}")), Error);
}

TEST(Settings, StrictParsingNamesTheKey) {
  try {
    parse_tracking_settings(scene_with("{grid_stepp_px: 6}"));
    FAIL() << "unknown key accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("tracking.grid_stepp_px"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_tracking_settings(scene_with("{window_px: 20}")), Error);  // even
  EXPECT_THROW(parse_tracking_settings(scene_with("{preset: fast}")), Error);   // unknown preset
  EXPECT_THROW(parse_tracking_settings(scene_with("{}"), "paper"), Error);      // --preset
  EXPECT_THROW(parse_tracking_settings(scene_with("{refine: none}")), Error);   // check needs refine
  EXPECT_NO_THROW(parse_tracking_settings(scene_with("{refine: none, neighbour_check: false}")));
}

}  // namespace
}  // namespace tirstrain::flow
