#pragma once
// Camera options shared by `record` and `live`, and the Ctrl-C flag both honour.
#include <signal.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "capture/camera_settings.hpp"
#include "capture/frame_source.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"

namespace tirstrain::cli {

struct CameraArgs {
  std::string pixel_format, roi, trigger;
  std::optional<double> exposure_us, gain_dB, fps, frame_timeout_s;
  std::optional<int> packet_size, buffers;
};

inline void add_camera_options(CLI::App* sub, const std::shared_ptr<CameraArgs>& args) {
  const std::string group =
      "Camera (aravis: sources; override the scene's camera: section; every value is checked against the "
      "device and read back)";
  sub->add_option("--pixel-format", args->pixel_format,
                  "Mono8, Mono16, BayerRG8, ... (Bayer is stored as grey)")
      ->group(group);
  sub->add_option("--roi", args->roi, "Region of interest on the sensor: X,Y,WIDTH,HEIGHT in pixels")
      ->group(group);
  sub->add_option("--exposure-us", args->exposure_us, "Exposure time in microseconds")->group(group);
  sub->add_option("--gain-dB", args->gain_dB, "Analog gain (camera units, usually dB)")->group(group);
  sub->add_option("--fps", args->fps, "Frame rate in Hz (free-run)")->group(group);
  sub->add_option("--trigger", args->trigger, "free-run, software, or a hardware line (Line0, Line1, ...)")
      ->group(group);
  sub->add_option("--packet-size", args->packet_size,
                  "GigE Vision packet size in bytes (default: negotiated)")
      ->group(group);
  sub->add_option("--buffers", args->buffers, "Stream buffers (default: about 128 MiB worth)")->group(group);
  sub->add_option("--frame-timeout-s", args->frame_timeout_s,
                  "Silence after which the camera is checked and the run stops if it is gone (default: auto)")
      ->group(group);
}

inline capture::CameraSettings to_settings(const CameraArgs& args) {
  capture::CameraSettings s;
  s.pixel_format = args.pixel_format;
  if (!args.roi.empty()) {
    std::istringstream in(args.roi);
    int v[4] = {0, 0, 0, 0};
    char comma[3] = {0, 0, 0};
    std::string rest;
    if (!(in >> v[0] >> comma[0] >> v[1] >> comma[1] >> v[2] >> comma[2] >> v[3]) || comma[0] != ',' ||
        comma[1] != ',' || comma[2] != ',' || (in >> rest))
      throw Error("expected X,Y,WIDTH,HEIGHT in pixels, e.g. 0,0,1280,1024; got '" + args.roi + "'",
                  {.key = "--roi"});
    s.roi_px = cv::Rect(v[0], v[1], v[2], v[3]);
  }
  s.exposure_us = args.exposure_us;
  s.gain_dB = args.gain_dB;
  s.frame_rate_hz = args.fps;
  s.trigger = args.trigger;
  s.packet_size_bytes = args.packet_size;
  if (args.buffers) {
    if (*args.buffers < 2 || *args.buffers > 10000) throw Error("must be 2..10000", {.key = "--buffers"});
    s.buffer_count = *args.buffers;
  }
  if (args.frame_timeout_s) {
    if (!(*args.frame_timeout_s > 0)) throw Error("must be > 0", {.key = "--frame-timeout-s"});
    s.frame_timeout_s = *args.frame_timeout_s;
  }
  return s;
}

// The scene's camera: section (when a scene is given) with every flag given on the command line on top.
inline capture::CameraSettings camera_settings(const CameraArgs& args, const Scene* scene) {
  capture::CameraSettings from_scene;
  if (scene != nullptr) from_scene = capture::parse_camera_settings(*scene);
  return capture::override_camera_settings(from_scene, to_settings(args));
}

// Ctrl-C ends a recording cleanly (frames so far saved, summary written) instead of killing it.
inline std::atomic<bool>& interrupt_flag() {
  static std::atomic<bool> flag{false};
  return flag;
}

inline void install_interrupt_handler() {
  interrupt_flag();  // initialise the static before a signal can touch it
  struct sigaction action {};
  action.sa_handler = [](int) { interrupt_flag().store(true); };
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

}  // namespace tirstrain::cli
