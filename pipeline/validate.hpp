#pragma once
// `tirstrain validate`: a processed synthetic trial against its exact truth. The trial (its scene file
// carries the synthesis section, so the generator's exact field can be evaluated anywhere, not only on
// truth.h5's grid) is compared per frame with the measured contact (hull against the truth mask, ellipse
// against the same direct fit of the mask's outline), per frame and triangle with the measured strain, per
// track with the measured displacement, and per frame with the measured energy and stick zone; the analytic
// Cattaneo–Mindlin stick radius c is the reference for the stick zone.
//
// Where: the contact interior, i.e. triangles whose reference centroid and true current centroid both lie
// more than `border_exclusion_mm` inside the contact border (the ridge contrast fades there and the field's
// derivatives are unbounded at r = a). Two strain references are reported:
//   point:    the exact Green–Lagrange strain at the triangle's reference centroid (what a user compares);
//   triangle: the strain of the same triangle with its vertices moved by the exact field (the linear
//             triangle's own discretisation error removed, so what is left is the tracking error).
// Beside the interior, coverage and accuracy by ring of the true contact out to its edge, where slip begins
// (pipeline/validate_rings.hpp).
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"

namespace tirstrain::pipeline {

struct ValidateOptions {
  std::optional<std::string> scene_path;  // synthesise this scene into OUT/trial first
  std::optional<std::string> trial_dir;   // or an existing synthesised trial folder
  std::optional<std::string> result_dir;  // an existing result of processing the trial (skips processing)
  std::string out_dir;
  // Folders around out_dir that the caller is staging (bench): paths recorded in the outputs name where
  // they will be once swapped in.
  std::vector<StagedFolder> staged_folders;
  // Scene used for processing (e.g. with other tracking settings); default: the trial's own scene.yaml. The
  // truth always comes from the trial's scene.
  std::optional<std::string> process_scene_path;
  // Process with no scene at all (what a recording without one gets: defaults, stages and pattern band
  // found from the images); the truth still comes from the trial's scene.
  bool process_defaults = false;
  std::string tracking_preset;      // "" = the scene's
  std::string segmentation_preset;  // "" = the scene's
  std::string strain_mode;          // "" = the scene's
  double border_exclusion_mm = 0.3;
  int map_frame = -1;  // frame drawn in the side-by-side maps; −1: the frame of largest true energy
  bool write_maps = true;
  bool quiet = false;
  std::FILE* log = stderr;
};

struct ErrorStats {
  std::string quantity;   // e.g. "E_xx"
  std::string reference;  // "point", "triangle", "tracks", "model" ...
  std::string mode;       // "exact", "incremental" or "" when not a strain
  std::string unit;       // "" for strain, "px", "J/m3", "%", "mm"
  double rms = 0.0;
  double max_abs = 0.0;
  double mean = 0.0;  // signed: measured − truth
  long samples = 0;
};

struct ValidationReport {
  std::vector<ErrorStats> rows;
  std::string result_dir;
  std::vector<std::string> outputs;
  double process_wall_s = 0.0;
  int frames = 0;
  // What the reader must know to read the rows (a result processed with another calibration).
  std::vector<std::string> warnings;
  const ErrorStats* find(const std::string& quantity, const std::string& reference,
                         const std::string& mode = "") const;
};

ValidationReport run_validate(const ValidateOptions& options);

}  // namespace tirstrain::pipeline
