#pragma once
// `tirstrain synth`: renders a synthetic trial and writes it as a trial directory
//   DIR/frames/000000.png ..., DIR/frames.csv, DIR/channels.csv, DIR/scene.yaml, DIR/truth.h5
// (layout in docs/formats.md). The directory is staged at DIR.partial and renamed when complete.
#include <cstdint>
#include <optional>
#include <string>

#include "samples/synth_config.hpp"
#include "samples/trial.hpp"

namespace tirstrain::samples {

struct SynthOptions {
  std::string scene_path;
  std::string out_dir;
  std::optional<std::uint64_t> seed;  // overrides synthesis.seed
  bool quiet = false;
};

struct SynthSummary {
  int frames = 0;
  double render_s = 0.0;  // wall time of rendering + writing
  std::string out_dir;
};

// Loads and validates the scene, builds the trial (both before anything is created on disk), then renders
// and writes it. Throws tirstrain::Error; on any failure no DIR (and no DIR.partial) is left behind.
SynthSummary synthesize(const SynthOptions& options);

// Writes an already-built trial to `out_dir` (staged; replaces an existing directory on success).
void write_trial(const Trial& trial, const std::string& out_dir, bool quiet);

// Format tag and version written to truth.h5's root attributes.
inline constexpr const char* kTruthFormat = "tirstrain-truth";
inline constexpr double kTruthVersion = 1.0;

}  // namespace tirstrain::samples
