#pragma once
// `tirstrain process`: frames in, result.h5 + frames.csv + summary.json + overlay out. Runs the stages the
// scene's `compute` list asks for, or without one every stage whose inputs exist (pipeline/stage.hpp,
// pipeline/process_defaults.hpp) over a frame source (capture/), with decoding
// overlapped with analysis, and writes every output under a temporary name, renamed only when complete:
// result.h5 last, so its presence means the run finished.
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"

namespace tirstrain::pipeline {

enum class OverlayMode { kNone, kMp4, kPng };

struct ProcessOptions {
  std::string input;  // folder, pattern, video file or source URI
  // Frame rate of a recording whose file holds no timestamps (a multi-page TIFF without frames.csv), Hz;
  // unset: none (capture/file_formats.hpp).
  std::optional<double> frame_rate_Hz;
  // Absent: INPUT/scene.yaml when INPUT is a folder holding one (a synthesised or saved trial), otherwise
  // the documented defaults with the rest measured from the images.
  std::optional<std::string> scene_path;
  // false: without scene_path, the defaults even when INPUT holds a scene.yaml (--no-scene).
  bool folder_scene = true;
  std::string out_dir;
  // Folders around the input that a caller is staging (validate, bench): the paths recorded in the
  // outputs name where the input will be once they are swapped in.
  std::vector<StagedFolder> staged_folders;
  bool quiet = false;
  // Stop at the first corrupt frame, at a requested stage that is not available, or when the input has
  // no timestamps, instead of marking/skipping/assuming.
  bool strict = false;
  OverlayMode overlay = OverlayMode::kMp4;
  // Overrides of the scene (empty: the scene's value): extra stages to compute, the tracking preset, the
  // segmentation preset (accurate, balanced or fast: segmentation.preset; keys the scene's segmentation
  // section sets itself still apply), the strain mode.
  std::vector<std::string> compute;
  std::string tracking_preset;
  std::string segmentation_preset;
  std::string strain_mode;
  // Frames between flushes of the partial result: a run killed later leaves every frame before the last
  // flush readable in OUT.partial (result.h5.partial, summary.json `complete: false`). ≥ 1.
  std::int64_t flush_every_frames = 64;
  // Continue the run interrupted in OUT.partial from its last checkpoint (written with the first flush, then
  // with a flush once checkpoint_every_s of wall time and 50 times the last one's writing time have passed,
  // so that they take at most 2 % of the run) instead of from the first frame: the same input, scene and
  // options, or an error. Without a checkpoint there, the run starts from the first frame.
  bool resume = false;
  double checkpoint_every_s = 30.0;
  std::FILE* log = stderr;  // warnings and progress
};

struct ProcessReport {
  std::int64_t frames = 0;
  std::int64_t frames_skipped = 0;  // corrupt / undecodable
  std::int64_t frames_with_contact = 0;
  std::vector<std::string> outputs;  // paths written
  std::vector<std::string> warnings;
};

ProcessReport run_process(const ProcessOptions& options);

}  // namespace tirstrain::pipeline
