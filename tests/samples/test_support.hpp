#pragma once
// Small noise-free scenes for the samples tests, built in memory so each test states what it varies.
#include <sys/wait.h>
#include <yaml-cpp/yaml.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/scene.hpp"
#include "samples/synth_config.hpp"

namespace tirstrain::samples::testing {

// A clean scene: no noise, blur, drift, vignetting or jitter; 16-bit output so quantisation is negligible.
inline YAML::Node clean_scene(int width_px, int height_px, int frames, double frame_rate_hz) {
  YAML::Node root = YAML::Load(R"(
calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
synthesis:
  seed: 7
  image: {bit_depth: 16}
  timing: {}
  contact: {shape: hertz, normal_N: 1.0, radius_m: 0.01, border_irregularity: 0.02}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 5.0}
  fingerprint: {vignetting: 0.0, core_offset_mm: [0.2, -0.4]}
  sensor: {}
  channels: {}
  truth: {grid_step_px: 4}
)");
  root["synthesis"]["image"]["width_px"] = width_px;
  root["synthesis"]["image"]["height_px"] = height_px;
  root["synthesis"]["timing"]["frames"] = frames;
  root["synthesis"]["timing"]["frame_rate_hz"] = frame_rate_hz;
  return root;
}

inline SynthConfig config_of(const YAML::Node& root) {
  return parse_synth_config(parse_scene_text(YAML::Dump(root), "test-scene.yaml"));
}

inline std::string scratch_dir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "samples" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

inline void write_yaml(const YAML::Node& root, const std::string& path) {
  YAML::Emitter e;
  e.SetDoublePrecision(17);
  e << root;
  std::ofstream(path) << e.c_str() << '\n';
}

struct CliResult {
  int exit_code = 0;
  std::string output;  // stdout + stderr
};

inline CliResult run_cli(const std::string& arguments, const std::string& log_path) {
  const std::string command = std::string(TIRSTRAIN_CLI) + " " + arguments + " > " + log_path + " 2>&1";
  const int status = std::system(command.c_str());
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log_path);
  r.output.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return r;
}

}  // namespace tirstrain::samples::testing
