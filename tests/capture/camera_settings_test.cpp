// The scene's camera: section: strict parsing, command-line overrides, messages naming file and key, and
// the record CLI using it (file sources only here; the Aravis tests check that the values reach a device).
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "capture/camera_settings.hpp"
#include "capture/frame_source.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "tests/apps/cli_support.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  return testing::scratch_dir("capture_settings", name);
}

std::string write_scene(const fs::path& dir, const std::string& yaml) {
  const std::string path = (dir / "scene.yaml").string();
  std::ofstream(path) << yaml;
  return path;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

using testing::error_of;

constexpr const char* kFullSection = R"(calibration: {px_per_mm: 40}
camera:
  pixel_format: Mono16
  roi_px: [16, 8, 640, 512]
  exposure_us: 2500
  gain_dB: 1.5
  frame_rate_hz: 400
  trigger: Line1
  packet_size_bytes: 8192
  buffer_count: 48
  frame_timeout_s: 5
)";

TEST(CameraSettingsTest, SceneSectionSetsEveryKey) {
  const fs::path dir = scratch("every_key");
  const std::string path = write_scene(dir, kFullSection);
  const Scene scene = load_scene(path);
  const CameraSettings s = parse_camera_settings(scene);
  EXPECT_EQ(s.pixel_format, "Mono16");
  ASSERT_TRUE(s.roi_px.has_value());
  EXPECT_EQ(*s.roi_px, cv::Rect(16, 8, 640, 512));
  EXPECT_EQ(s.exposure_us, 2500.0);
  EXPECT_EQ(s.gain_dB, 1.5);
  EXPECT_EQ(s.frame_rate_hz, 400.0);
  EXPECT_EQ(s.trigger, "Line1");
  EXPECT_EQ(s.packet_size_bytes, 8192);
  EXPECT_EQ(s.buffer_count, 48);
  EXPECT_EQ(s.frame_timeout_s, 5.0);
  EXPECT_EQ(s.from_scene.size(), 9u);
  EXPECT_EQ(s.scene_file, path);
  EXPECT_EQ(s.key("--exposure-us"), "camera.exposure_us (scene " + path + ")");
  // Unaffected by the camera section: the rest of the scene.
  EXPECT_EQ(scene.px_per_mm, 40.0);
  // The section survives a save and reload.
  const fs::path copy = dir / "copy.yaml";
  save_scene(scene, copy.string());
  const CameraSettings reloaded = parse_camera_settings(load_scene(copy.string()));
  EXPECT_EQ(reloaded.exposure_us, 2500.0);
  EXPECT_EQ(*reloaded.roi_px, cv::Rect(16, 8, 640, 512));
}

TEST(CameraSettingsTest, NoSectionMeansNothingIsChanged) {
  const CameraSettings s = parse_camera_settings(parse_scene_text("tissue: {E_Pa: 2e6}", "x.yaml"));
  EXPECT_TRUE(s.empty());
  EXPECT_TRUE(s.from_scene.empty());
  EXPECT_TRUE(s.scene_file.empty());
  EXPECT_EQ(s.key("--fps"), "--fps");
  EXPECT_TRUE(describe_requested(s).empty());
}

TEST(CameraSettingsTest, CommandLineOverridesTheScene) {
  const fs::path dir = scratch("override");
  const std::string path = write_scene(dir, kFullSection);
  CameraSettings cli;
  cli.frame_rate_hz = 250;
  cli.roi_px = cv::Rect(0, 0, 320, 256);
  const CameraSettings s = override_camera_settings(parse_camera_settings(load_scene(path)), cli);
  EXPECT_EQ(s.frame_rate_hz, 250.0);
  EXPECT_EQ(*s.roi_px, cv::Rect(0, 0, 320, 256));
  EXPECT_EQ(s.exposure_us, 2500.0);  // not given on the command line: the scene's
  EXPECT_EQ(s.pixel_format, "Mono16");
  EXPECT_EQ(s.key("--fps"), "--fps");
  EXPECT_EQ(s.key("--roi"), "--roi");
  EXPECT_EQ(s.key("--exposure-us"), "camera.exposure_us (scene " + path + ")");
  const auto requested = describe_requested(s);
  EXPECT_EQ(requested.size(), 9u);
  EXPECT_EQ(requested.at("frame_rate_hz"), "250 (--fps)");
  EXPECT_EQ(requested.at("roi_px"), "0,0,320,256 (--roi)");
  EXPECT_EQ(requested.at("exposure_us"), "2500 (scene " + path + ")");
  EXPECT_EQ(requested.at("trigger"), "Line1 (scene " + path + ")");
  // What the user typed is separable from what the scene says (file sources ignore the latter).
  const CameraSettings typed = command_line_part(s);
  EXPECT_EQ(typed.frame_rate_hz, 250.0);
  EXPECT_FALSE(typed.exposure_us.has_value());
  EXPECT_TRUE(typed.pixel_format.empty());
  EXPECT_EQ(typed.buffer_count, 0);
  EXPECT_TRUE(command_line_part(parse_camera_settings(load_scene(path))).empty());
  // Every command-line option of the record/live CLI has a scene key.
  for (const char* option : {"--pixel-format", "--roi", "--exposure-us", "--gain-dB", "--fps", "--trigger",
                             "--packet-size", "--buffers", "--frame-timeout-s"})
    EXPECT_FALSE(scene_key_of(option).empty()) << option;
}

TEST(CameraSettingsTest, BadValuesNameTheFileAndTheKey) {
  struct Case {
    std::string yaml, key, message;
  };
  const std::vector<Case> cases = {
      {"camera: {exposure_us: -5}", "camera.exposure_us", "outside the allowed range"},
      {"camera: {exposure_us: fast}", "camera.exposure_us", "expected a number"},
      {"camera: {frame_rate_hz: 0}", "camera.frame_rate_hz", "outside the allowed range"},
      {"camera: {gain_dB: [1, 2]}", "camera.gain_dB", "expected a number"},
      {"camera: {roi_px: [0, 0, 640]}", "camera.roi_px", "expected [x, y, width, height]"},
      {"camera: {roi_px: [0, 0, 640.5, 480]}", "camera.roi_px", "whole pixels"},
      {"camera: {roi_px: [-1, 0, 640, 480]}", "camera.roi_px", "x and y >= 0"},
      {"camera: {roi_px: 640x480}", "camera.roi_px", "expected a list of numbers"},
      {"camera: {packet_size_bytes: 100000}", "camera.packet_size_bytes", "outside the allowed range"},
      {"camera: {packet_size_bytes: 1500.5}", "camera.packet_size_bytes", "expected a whole number"},
      {"camera: {buffer_count: 1}", "camera.buffer_count", "outside the allowed range"},
      {"camera: {trigger: ''}", "camera.trigger", "expected free-run, software or a hardware line"},
      {"camera: {pixel_format: 'Mono 8'}", "camera.pixel_format", "GenICam pixel format name"},
      {"camera: {exposure: 100}", "camera.exposure", "unknown key"},
      {"camera: [Mono8]", "camera", "expected a mapping"},
  };
  const fs::path dir = scratch("bad_values");
  for (const auto& c : cases) {
    const std::string path = write_scene(dir, c.yaml);
    const std::string message = error_of([&] { parse_camera_settings(load_scene(path)); });
    EXPECT_NE(message.find(path), std::string::npos) << c.yaml << " -> " << message;
    EXPECT_NE(message.find("'" + c.key + "'"), std::string::npos) << c.yaml << " -> " << message;
    EXPECT_NE(message.find(c.message), std::string::npos) << c.yaml << " -> " << message;
  }
}

// ---- The record CLI with --scene, on a file source (camera runs are in tests/capture_aravis) ----

std::string write_frames(const fs::path& dir, int n) {
  const fs::path frames = dir / "input";
  fs::create_directories(frames);
  for (int i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    cv::imwrite((frames / name).string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(10 * i)));
  }
  return frames.string();
}

TEST(CameraSettingsCliTest, BadSceneValueStopsRecordBeforeAnything) {
  const fs::path dir = scratch("cli_bad");
  const std::string input = write_frames(dir, 3);
  const std::string scene = write_scene(dir, "camera:\n  frame_rate_hz: quick\n");
  const auto result = tirstrain::testing::run_cli("record " + input + " --scene " + scene + " --out " +
                                                  (dir / "rec").string() + " --quiet");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(scene + ": 'camera.frame_rate_hz': expected a number"), std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(dir / "rec" / "frames.csv"));
}

// A rig scene used with a recording (a file source): its camera: section describes the camera that made the
// recording and is not applied; camera flags typed for a file are still an error.
TEST(CameraSettingsCliTest, FileSourcesIgnoreTheScenesCameraSectionButNotCameraFlags) {
  const fs::path dir = scratch("cli_file_source");
  const std::string input = write_frames(dir, 4);
  const std::string scene = write_scene(dir, "camera: {exposure_us: 2000, frame_rate_hz: 500}\n");
  const std::string out = (dir / "rec").string();
  auto result =
      tirstrain::testing::run_cli("record " + input + " --scene " + scene + " --out " + out + " --quiet");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("4 frames saved"), std::string::npos) << result.output;
  EXPECT_NE(read_text(fs::path(out) / "recording.json").find("\"requested_settings\": {},"),
            std::string::npos)
      << read_text(fs::path(out) / "recording.json");
  result = tirstrain::testing::run_cli("record " + input + " --scene " + scene + " --out " + out +
                                       "2 --exposure-us 100 --quiet");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("only apply to camera sources"), std::string::npos) << result.output;
}

// More --frames than a file holds: all of it is recorded, and the run says the source ended first.
TEST(CameraSettingsCliTest, AFileShorterThanFramesAskedIsRecordedWholeAndSaysSo) {
  const fs::path dir = scratch("cli_file_short");
  const std::string input = write_frames(dir, 3);
  const std::string out = (dir / "rec").string();
  const auto result = tirstrain::testing::run_cli("record " + input + " --out " + out + " --frames 10");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("3 frames saved"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("the source ended after 3 frames, before the 10 --frames asked for"),
            std::string::npos)
      << result.output;
}

// --overwrite replaces a recording folder as a whole: a folder that holds the input, is the input, or holds
// other files is refused before anything is recorded, and all of it stays.
TEST(CameraSettingsCliTest, OverwriteNeverTakesTheInputOrOtherFilesWithIt) {
  const fs::path dir = scratch("cli_overwrite_guard");
  const std::string input = write_frames(dir, 3);
  const std::string rec = (dir / "rec").string();
  ASSERT_EQ(tirstrain::testing::run_cli("record " + input + " --out " + rec + " --quiet").exit_code, 0);
  // The recording itself as the source, into a folder holding it or into itself.
  const auto nested =
      tirstrain::testing::run_cli("record " + rec + " --out " + dir.string() + " --overwrite");
  EXPECT_EQ(nested.exit_code, 1) << nested.output;
  EXPECT_NE(nested.output.find("contains the input"), std::string::npos) << nested.output;
  const auto itself = tirstrain::testing::run_cli("record " + rec + " --out " + rec + " --overwrite");
  EXPECT_EQ(itself.exit_code, 1) << itself.output;
  EXPECT_NE(itself.output.find("is the input"), std::string::npos) << itself.output;
  EXPECT_TRUE(fs::exists(fs::path(rec) / "recording.json"));
  // Notes and force channels beside an earlier recording.
  std::ofstream(fs::path(rec) / "channels.csv") << "t_s,normal_N\n0,1\n";
  const auto foreign = tirstrain::testing::run_cli("record " + input + " --out " + rec + " --overwrite");
  EXPECT_EQ(foreign.exit_code, 1) << foreign.output;
  EXPECT_NE(foreign.output.find("holds 'channels.csv'"), std::string::npos) << foreign.output;
  EXPECT_TRUE(fs::exists(fs::path(rec) / "channels.csv"));
  EXPECT_TRUE(fs::exists(fs::path(rec) / "frames.csv"));
}

}  // namespace
}  // namespace tirstrain::capture
