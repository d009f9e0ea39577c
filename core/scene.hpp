#pragma once
// The scene file (YAML): one trial or one rig. Core parses what every stage shares (calibration, tissue,
// reference pattern, what to compute); sections owned by one module (synthesis, segmentation, tracking,
// strain, channels, camera) are kept as they are (SceneSection) and parsed strictly by that module with
// YamlSection, each in one place.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/scene_section.hpp"

namespace tirstrain {

struct RoiPx {
  int x = 0, y = 0, width = 0, height = 0;
};

struct Tissue {
  double young_Pa = 1.0e6;
  double poisson = 0.4;
  double depth_m = 0.002;  // thickness used for plane-strain energy U = depth * sum(u_i A_i)
};

struct Scene {
  std::string file;  // where it was read from; empty for defaults
  double px_per_mm = 52.0;
  std::optional<double> ridge_period_mm;  // fixed ridge period; absent: measured from the images
  std::string ridge_polarity = "auto";    // "dark", "bright" or "auto" (ridges in contact dark/bright)
  Tissue tissue;
  std::optional<RoiPx> reference_pattern_roi;  // band of the image showing the pattern printed on the glass
  // reference_pattern.detect: without roi_px, `process` looks for the band along the image edges
  // (pipeline/pattern_band.hpp); false says the plate shows no pattern.
  bool reference_pattern_detect = true;
  // Set by `process` for a detected band, not read from files: contact segmentation leaves out the band grown
  // by this much (px), because a detected rectangle lies inside the band (the plate is measured on pattern
  // only) and the band's true edge may be up to this much further in. A scene's roi_px is exact: 0.
  int reference_pattern_margin_px = 0;
  std::vector<std::string> compute = {"contact"};  // stages requested, in pipeline order
  bool compute_given = false;                      // the file has a compute list (else `process` picks)
  // Which calibration and tissue values the file gives; the others are defaults, and results say so.
  bool px_per_mm_given = false;
  bool tissue_given = false;
  // Module-owned sections, parsed by their modules.
  SceneSection synthesis;     // samples/synth_config.cpp
  SceneSection segmentation;  // contact stage options (pipeline/contact_stage.cpp)
  SceneSection tracking;      // flow/settings.cpp
  SceneSection strain;        // strain/settings.cpp
  SceneSection channels;      // pipeline/channels_stage.cpp
  SceneSection camera;        // camera settings for record/live (capture/camera_settings.cpp)
};

// Known stage names for `compute`.
const std::vector<std::string>& known_stages();

// Reads and validates a scene file; throws Error naming the file and key of anything wrong.
Scene load_scene(const std::string& path);
// Validates a YAML document as a scene; `file` is used in messages.
Scene parse_scene(const SceneSection& root, const std::string& file);
// The same from YAML text.
Scene parse_scene_text(const std::string& yaml, const std::string& file);
// The scene as YAML text, readable back by parse_scene_text.
std::string scene_to_yaml(const Scene& scene);
// Writes scene_to_yaml to a file (temporary name, then rename).
void save_scene(const Scene& scene, const std::string& path);

}  // namespace tirstrain
