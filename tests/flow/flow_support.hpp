#pragma once
// Synthetic trials for the flow tests and benchmark, rendered in memory by samples/, and the scoring of a
// tracker run against their exact fields.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "flow/tracker.hpp"
#include "samples/synth_config.hpp"
#include "samples/trial.hpp"

namespace tirstrain::flow::testing {

// A small Cattaneo–Mindlin trial: Hertz contact of radius ≈ 1.2 mm (≈ 62 px), the plate moving slowly
// enough that the stick zone shrinks over the trial; 16-bit, no noise unless the caller adds it.
inline YAML::Node cm_scene(int width_px, int height_px, int frames, double frame_rate_hz) {
  YAML::Node root = YAML::Load(R"(
calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
synthesis:
  seed: 11
  image: {bit_depth: 16}
  timing: {}
  contact: {shape: hertz, normal_N: 0.5, radius_m: 0.0055, border_irregularity: 0.02}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 20, plate_speed_mm_s: 1.0}
  fingerprint: {vignetting: 0.0, core_offset_mm: [0.2, -0.3]}
  sensor: {}
  channels: {}
  truth: {grid_step_px: 8}
)");
  root["synthesis"]["image"]["width_px"] = width_px;
  root["synthesis"]["image"]["height_px"] = height_px;
  root["synthesis"]["timing"]["frames"] = frames;
  root["synthesis"]["timing"]["frame_rate_hz"] = frame_rate_hz;
  return root;
}

inline samples::SynthConfig config_of(const YAML::Node& root) {
  return samples::parse_synth_config(parse_scene_text(YAML::Dump(root), "flow-test-scene.yaml"));
}

struct Score {
  double rms_px = 0.0;               // displacement error over all live tracks and frames after the first
  double max_px = 0.0;               // largest error of any live track in any frame
  long samples = 0;                  // (track, frame) pairs scored
  long wrong = 0;                    // live tracks with an error > 1 px (silently wrong)
  std::vector<double> frame_rms_px;  // per frame (0 for frame 0)
  std::vector<int> frame_alive;
  int tracks_started = 0;
  int born = 0;
  double birth_rms_px = 0.0;  // reference position of newborns against the exact inverse map
  double birth_max_px = 0.0;
  double plate_rms_px = 0.0;
  double plate_max_px = 0.0;
  double seconds = 0.0;               // tracking time only (rendering excluded)
  std::vector<double> frame_seconds;  // per frame; frame 0 is the seeding (start)
  int rest_frames_averaged = 0;  // frames that joined frame 0's anchor (FrameStats::rest_frames_averaged)
  int rest_frames_on_fit = 0;    // frames reported on the rest motion's fit (FrameStats::at_rest)
  long main_matched = 0;  // track-frames that took the main match (FrameStats::main_matched), frames ≥ 1
  long entering = 0;      // track-frames alive when their frame began, frames ≥ 1
};

// Renders every frame first (so timing covers tracking only), then tracks and scores.
struct RenderedTrial {
  std::vector<cv::Mat> frames;
  cv::Mat mask;
};

inline RenderedTrial render(const samples::Trial& trial, bool sensor) {
  RenderedTrial r;
  r.mask = trial.contact_mask();
  for (int f = 0; f < trial.frames(); ++f) {
    const cv::Mat clean = trial.render_clean(f);
    if (sensor) {
      r.frames.push_back(trial.apply_sensor(clean, f));
    } else {
      cv::Mat u16;
      clean.convertTo(u16, CV_16U, 65535.0);
      r.frames.push_back(u16);
    }
  }
  return r;
}

Score run_and_score(const samples::Trial& trial, const RenderedTrial& frames, const TrackerOptions& settings,
                    bool with_plate);

}  // namespace tirstrain::flow::testing
