#pragma once
// What `process` decides when the scene leaves it open: which stages to run (no `compute:` list), where the
// plate's printed pattern is (no `reference_pattern.roi_px`), and which calibration and tissue values are
// the defaults. Every such decision is reported on the console and in summary.json.
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace tirstrain::pipeline {

// The channel file looked for beside the frames when the scene has no `channels:` section: channels.csv in
// INPUT (a folder), or in the folder holding INPUT (a file or pattern). Its columns are mapped by the names
// `tirstrain synth` writes (docs/formats.md).
std::string default_channel_file(const std::string& input);

// The `channels:` section for `file` from its header: every known column name mapped to its role. Null when
// the file is absent or maps no role.
SceneSection default_channels_section(const std::string& file);

// For a scene without a compute list: every stage whose inputs exist, in pipeline order. Contact, tracking
// and strain need only the images; channels needs a `channels:` section, or a default channel file (whose
// section is then put into `scene`). `reason` says what was chosen and why.
std::vector<std::string> default_stages(Scene& scene, const std::string& input, std::string& reason);

// Where the reference pattern band comes from, and what it is.
struct PatternBandChoice {
  std::string source;  // "scene", "detected", "none" (looked, not found) or "off" (reference_pattern.detect)
  std::optional<RoiPx> roi_px;
  std::string edge;  // top, bottom, left, right, none; "inside" for a scene band off the edges
  std::optional<double> confidence;  // detection only
  int margin_px = 0;                 // contact segmentation leaves out roi_px grown by this (detection only)
  std::string warning;               // a scene band away from where the images show the dot band
  nlohmann::json to_json() const;
  std::string describe() const;  // one line for the console
};

// Throws Error (naming the scene file and reference_pattern.roi_px) when the scene's band does not lie
// wholly inside frames of `image_size`.
void check_pattern_band(const Scene& scene, cv::Size image_size);

// The scene's band, or the one detected on `first_frame` (then put into `scene`, so that every stage sees it:
// contact segmentation excludes it, tracking measures the plate in it).
PatternBandChoice resolve_pattern_band(Scene& scene, const cv::Mat& first_frame);

// One line for each of calibration and tissue when they are the defaults (empty when the scene gives them).
std::vector<std::string> default_value_notes(const Scene& scene);

}  // namespace tirstrain::pipeline
