#pragma once
// `tirstrain scene init`: a commented starting scene file from what a recording's images show (size, frame
// rate from the timestamps, the printed pattern band, ridge period and polarity, contact size), with the
// values the images cannot give (calibration, tissue) as placeholders holding the defaults `process` uses.
#include <cstdint>
#include <optional>
#include <string>

#include "core/scene.hpp"

namespace tirstrain::pipeline {

struct SceneInitOptions {
  std::string input;                    // as `process` takes it
  std::optional<double> frame_rate_Hz;  // as `process --frame-rate-Hz` takes it, Hz; unset: none
  std::string out_path;
  std::int64_t max_frames = 300;  // frames read at most (the contact and ridges need a few with contact)
  bool overwrite = false;         // replace an existing out_path (a scene file may hold a calibration)
};

// What the images showed; written as the scene's values and comments.
struct SceneSurvey {
  int width_px = 0, height_px = 0, bit_depth = 8;
  std::int64_t frames_read = 0;
  std::optional<double> frame_rate_hz;  // from the median interval of measured timestamps
  std::string time_source;
  std::optional<RoiPx> band_roi_px;
  std::string band_edge = "none";
  double band_confidence = 0.0;
  std::optional<double> ridge_period_px;  // measured from the ridge spectrum
  std::string ridge_polarity = "auto";    // dark, bright or auto (not seen)
  std::int64_t first_contact_frame = -1;
  double largest_area_mm2 = 0.0;  // at the default px_per_mm
  std::int64_t largest_contact_frame = -1;
  double largest_semi_axes_px[2] = {0.0, 0.0};  // 0 when that contact has no ellipse
  bool largest_touches_edge = false;            // cut by the frame's edge (or the excluded band)
};

// Reads the recording and surveys it; throws Error naming the input when no frame can be decoded.
SceneSurvey survey_recording(const SceneInitOptions& options);
// The commented YAML text of the starting scene.
std::string scene_init_text(const SceneSurvey& survey, const std::string& input);
// Both, and the file written (temporary name, then renamed); returns the survey.
SceneSurvey write_initial_scene(const SceneInitOptions& options);

}  // namespace tirstrain::pipeline
