#include "capture/camera_settings.hpp"

#include <array>
#include <cmath>
#include <utility>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::capture {
namespace {

// Command-line option and scene key of every setting, in the order they are documented.
constexpr std::array<std::pair<const char*, const char*>, 9> kKeys = {{
    {"--pixel-format", "pixel_format"},
    {"--roi", "roi_px"},
    {"--exposure-us", "exposure_us"},
    {"--gain-dB", "gain_dB"},
    {"--fps", "frame_rate_hz"},
    {"--trigger", "trigger"},
    {"--packet-size", "packet_size_bytes"},
    {"--buffers", "buffer_count"},
    {"--frame-timeout-s", "frame_timeout_s"},
}};

std::string roi_text(const cv::Rect& roi) {
  return std::to_string(roi.x) + "," + std::to_string(roi.y) + "," + std::to_string(roi.width) + "," +
         std::to_string(roi.height);
}

// Which options a settings object sets, as command-line option names.
std::set<std::string> options_set(const CameraSettings& s) {
  std::set<std::string> set;
  if (!s.pixel_format.empty()) set.insert("--pixel-format");
  if (s.roi_px) set.insert("--roi");
  if (s.exposure_us) set.insert("--exposure-us");
  if (s.gain_dB) set.insert("--gain-dB");
  if (s.frame_rate_hz) set.insert("--fps");
  if (!s.trigger.empty()) set.insert("--trigger");
  if (s.packet_size_bytes) set.insert("--packet-size");
  if (s.buffer_count > 0) set.insert("--buffers");
  if (s.frame_timeout_s > 0) set.insert("--frame-timeout-s");
  return set;
}

}  // namespace

std::string scene_key_of(const std::string& option) {
  for (const auto& [cli, scene] : kKeys)
    if (option == cli) return scene;
  return "";
}

std::string CameraSettings::key(const std::string& option) const {
  if (from_scene.count(option) == 0) return option;
  return "camera." + scene_key_of(option) + " (scene " + scene_file + ")";
}

CameraSettings parse_camera_settings(const SceneSection& section, const std::string& file) {
  CameraSettings s;
  YamlSection y(section, file, "camera");
  if (y.has("pixel_format")) {
    s.pixel_format = y.text("pixel_format", "");
    if (s.pixel_format.empty() || s.pixel_format.find_first_of(" \t,") != std::string::npos)
      throw Error("expected a GenICam pixel format name such as Mono8, Mono16 or BayerRG8, got '" +
                      s.pixel_format + "'",
                  {.file = file, .key = "camera.pixel_format"});
  }
  if (y.has("roi_px")) {
    const std::vector<double> roi = y.numbers("roi_px", {});
    bool whole = roi.size() == 4;
    for (const double v : roi) whole = whole && v == std::floor(v) && std::abs(v) < 1e6;
    if (!whole || roi[0] < 0 || roi[1] < 0 || roi[2] <= 0 || roi[3] <= 0)
      throw Error(
          "expected [x, y, width, height] in whole pixels, x and y >= 0, width and height > 0 "
          "(e.g. [0, 0, 1280, 1024])",
          {.file = file, .key = "camera.roi_px"});
    s.roi_px = cv::Rect(static_cast<int>(roi[0]), static_cast<int>(roi[1]), static_cast<int>(roi[2]),
                        static_cast<int>(roi[3]));
  }
  if (y.has("exposure_us")) s.exposure_us = y.number("exposure_us", 0.0, 1e-3, 1e8);
  if (y.has("gain_dB")) s.gain_dB = y.number("gain_dB", 0.0, -100.0, 100.0);
  if (y.has("frame_rate_hz")) s.frame_rate_hz = y.number("frame_rate_hz", 0.0, 1e-3, 1e6);
  if (y.has("trigger")) {
    s.trigger = y.text("trigger", "");
    if (s.trigger.empty())
      throw Error("expected free-run, software or a hardware line name (Line0, Line1, ...)",
                  {.file = file, .key = "camera.trigger"});
  }
  if (y.has("packet_size_bytes"))
    s.packet_size_bytes = static_cast<int>(y.integer("packet_size_bytes", 0, 64, 65535));
  s.buffer_count = static_cast<int>(y.integer("buffer_count", 0, 2, 10000));
  s.frame_timeout_s = y.number("frame_timeout_s", 0.0, 1e-3, 3600.0);
  y.finish();
  s.from_scene = options_set(s);
  if (!s.from_scene.empty()) s.scene_file = file;
  return s;
}

CameraSettings override_camera_settings(const CameraSettings& base, const CameraSettings& overrides) {
  CameraSettings s = base;
  const std::set<std::string> replaced = options_set(overrides);
  if (!overrides.pixel_format.empty()) s.pixel_format = overrides.pixel_format;
  if (overrides.roi_px) s.roi_px = overrides.roi_px;
  if (overrides.exposure_us) s.exposure_us = overrides.exposure_us;
  if (overrides.gain_dB) s.gain_dB = overrides.gain_dB;
  if (overrides.frame_rate_hz) s.frame_rate_hz = overrides.frame_rate_hz;
  if (!overrides.trigger.empty()) s.trigger = overrides.trigger;
  if (overrides.packet_size_bytes) s.packet_size_bytes = overrides.packet_size_bytes;
  if (overrides.buffer_count > 0) s.buffer_count = overrides.buffer_count;
  if (overrides.frame_timeout_s > 0) s.frame_timeout_s = overrides.frame_timeout_s;
  for (const auto& option : replaced) s.from_scene.erase(option);
  if (s.from_scene.empty()) s.scene_file.clear();
  return s;
}

CameraSettings command_line_part(const CameraSettings& settings) {
  CameraSettings s = settings;
  for (const auto& option : settings.from_scene) {
    if (option == "--pixel-format") s.pixel_format.clear();
    if (option == "--roi") s.roi_px.reset();
    if (option == "--exposure-us") s.exposure_us.reset();
    if (option == "--gain-dB") s.gain_dB.reset();
    if (option == "--fps") s.frame_rate_hz.reset();
    if (option == "--trigger") s.trigger.clear();
    if (option == "--packet-size") s.packet_size_bytes.reset();
    if (option == "--buffers") s.buffer_count = 0;
    if (option == "--frame-timeout-s") s.frame_timeout_s = 0.0;
  }
  s.from_scene.clear();
  s.scene_file.clear();
  return s;
}

std::map<std::string, std::string> describe_requested(const CameraSettings& s) {
  std::map<std::string, std::string> out;
  auto put = [&](const char* option, const std::string& value) {
    const std::string origin = s.from_scene.count(option) ? "scene " + s.scene_file : std::string(option);
    out[scene_key_of(option)] = value + " (" + origin + ")";
  };
  if (!s.pixel_format.empty()) put("--pixel-format", s.pixel_format);
  if (s.roi_px) put("--roi", roi_text(*s.roi_px));
  if (s.exposure_us) put("--exposure-us", format_double(*s.exposure_us));
  if (s.gain_dB) put("--gain-dB", format_double(*s.gain_dB));
  if (s.frame_rate_hz) put("--fps", format_double(*s.frame_rate_hz));
  if (!s.trigger.empty()) put("--trigger", s.trigger);
  if (s.packet_size_bytes) put("--packet-size", std::to_string(*s.packet_size_bytes));
  if (s.buffer_count > 0) put("--buffers", std::to_string(s.buffer_count));
  if (s.frame_timeout_s > 0) put("--frame-timeout-s", format_double(s.frame_timeout_s));
  return out;
}

}  // namespace tirstrain::capture
