#include "pipeline/tracking_report.hpp"

#include <cmath>
#include <cstdio>

namespace tirstrain::pipeline {

nlohmann::json tracking_settings_json(const flow::TrackerOptions& s) {
  return {
      {"preset", s.preset},
      {"grid_step_px", s.seeding.grid_step_px},
      {"max_features", s.seeding.max_features},
      {"window_px", s.prediction.window_px},
      {"pyramid_levels", s.prediction.pyramid_levels},
      {"refine", s.refine ? flow::to_string(s.main_match.shape) : std::string("none")},
      {"subset_radius_px", s.main_match.subset_radius_px},
      {"subset_stride", s.main_match.subset_stride},
      {"fixed_shape_pass", s.rounds.enabled},
      {"fixed_shape_radius_px", s.rounds.subset_radius_px},
      {"fixed_shape_stride", s.rounds.subset_stride},
      {"main_match_period_frames", s.main_match.period_frames},
      {"prefilter_sigma_px", s.main_match.prefilter_sigma_px},
      {"fusion_sigma_px", s.fusion.sigma_px},
      {"fusion_weight", s.fusion.weight},
      {"border_exclusion_px", s.border.exclusion_px},
      {"contact_inset_px", s.border.contact_inset_px},
      {"max_displacement_px", s.prediction.max_displacement_px},
      {"rest_average_frames", s.rest.average_frames},
      {"rest_max_chi2_per_dof", s.rest.max_chi2_per_dof},
      {"rest_max_correlation_z", s.rest.max_correlation_z},
      {"rest_tolerance_px", s.rest.tolerance_px},
      {"rest_max_motion_chi2", s.rest.max_motion_chi2},
      {"smooth_in_time", s.smoothing.mode},
      {"interpolation",
       s.main_match.solver.interpolation == flow::Interpolation::kCubicBSpline ? "cubic_bspline" : "keys"},
      {"local_fit", s.local_fit.enabled},
      {"local_fit_agreement_chi2", s.local_fit.agreement_chi2},
      {"local_fit_order", s.local_fit.order},
      {"local_fit_per_component", s.local_fit.per_component},
      {"affine_fit", s.affine_fit.enabled},
      {"affine_fit_max_chi2_per_dof", s.affine_fit.max_chi2_per_dof},
      {"affine_fit_max_correlation_z", s.affine_fit.max_correlation_z},
      {"affine_fit_max_hidden_px", s.affine_fit.max_hidden_px},
      {"ridge_period_px", s.ridge_period_px},
      {"adapt_to_texture", s.texture.adapt}};
}

namespace {

// Frame 0's sizing of the main subsets for the affine test: what the test could not see at the preset's
// radius and at the radius in effect (NaN: not predicted, JSON null).
nlohmann::json sizing_json(const flow::MainSubsetSizing& sizing) {
  const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  return {{"preset_radius_px", sizing.preset_radius_px},
          {"radius_px", sizing.radius_px},
          {"predicted_hidden_px", number(sizing.predicted_hidden_px)},
          {"predicted_hidden_after_px", number(sizing.predicted_hidden_after_px)}};
}

}  // namespace

nlohmann::json texture_json(const flow::FeatureTracker& tracker) {
  const flow::TextureQuality& q = tracker.texture();
  return {{"snr", q.snr},
          {"noise_sigma", q.noise_sigma},
          {"ridge_rms", q.ridge_rms},
          {"coherence", q.coherence},
          {"ridges", q.ridges},
          {"low_snr_texture", tracker.low_snr_texture()},
          {"main_subsets_for_affine_test", sizing_json(tracker.main_subset_sizing())},
          {"note", texture_note(tracker)}};
}

std::string texture_note(const flow::FeatureTracker& tracker) {
  const flow::TrackerOptions& s = tracker.settings();
  const flow::TextureQuality& q = tracker.texture();
  char text[320];
  if (!s.refine || q.pixels == 0)
    std::snprintf(text, sizeof text, "texture not measured (unrefined tracking or nothing to measure)");
  else if (!q.ridges)
    std::snprintf(text, sizeof text,
                  "no ridges (coherence %.2f < %.2f): ridge-period heuristics off; subsets of radius %d px "
                  "(fixed-shape %d px) as the preset sizes them for a %.1f px period, no smoothing",
                  q.coherence, flow::kMinRidgeCoherence, s.main_match.subset_radius_px,
                  s.rounds.subset_radius_px, s.ridge_period_px);
  else
    std::snprintf(text, sizeof text,
                  "ridges (coherence %.2f), SNR %.1f: subsets of radius %d px, smoothing sigma %.1f px%s",
                  q.coherence, q.snr, s.main_match.subset_radius_px, s.main_match.prefilter_sigma_px,
                  tracker.low_snr_texture() ? ", low-SNR subsets" : "");
  std::string note = text;
  const flow::MainSubsetSizing& sizing = tracker.main_subset_sizing();
  if (sizing.grown()) {
    std::snprintf(text, sizeof text,
                  "; main subsets grown from %d to %d px so that the affine test sees %.3f px (predicted "
                  "%.3f px unseen at %d px, %.3f px at %d px)",
                  sizing.preset_radius_px, sizing.radius_px, s.affine_fit.max_hidden_px,
                  sizing.predicted_hidden_px, sizing.preset_radius_px, sizing.predicted_hidden_after_px,
                  sizing.radius_px);
    note += text;
  }
  return note;
}

}  // namespace tirstrain::pipeline
