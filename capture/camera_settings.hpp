#pragma once
// Camera settings from the scene file's `camera:` section, with command-line flags on top.
//
//   camera:
//     pixel_format: Mono8          # Mono8, Mono10..16, BayerRG8/BG8/GR8/GB8 (Bayer is stored as grey)
//     roi_px: [0, 0, 1280, 1024]   # x, y, width, height on the sensor
//     exposure_us: 2000
//     gain_dB: 0
//     frame_rate_hz: 500           # free-run frame rate
//     trigger: free-run            # free-run | software | a hardware line name (Line0, Line1, ...)
//     packet_size_bytes: 8192      # GigE Vision only; default: negotiated with the device
//     buffer_count: 64             # stream buffers; default: about 128 MiB worth
//     frame_timeout_s: 2           # silence before the camera is checked; default: auto
//
// Every key is optional; an absent key leaves the device as it is. Parsing is strict (unknown keys, wrong
// types and out-of-range values are errors naming the file and the key, e.g. "camera.exposure_us"); the
// device's own bounds are checked when the camera opens, and those errors name the same key and file.
#include <map>
#include <string>

#include "capture/frame_source.hpp"
#include "core/scene.hpp"

namespace tirstrain::capture {

// The `camera:` section of a scene (an absent section gives empty settings). `file` is used in messages and
// recorded as the settings' origin.
CameraSettings parse_camera_settings(const SceneSection& section, const std::string& file);
inline CameraSettings parse_camera_settings(const Scene& scene) {
  return parse_camera_settings(scene.camera, scene.file);
}

// `base` (usually from the scene) with every field that `overrides` sets (usually from the command line)
// replaced; replaced fields no longer count as coming from the scene.
CameraSettings override_camera_settings(const CameraSettings& base, const CameraSettings& overrides);

// Only the values that did not come from a scene file (what the user typed on the command line).
CameraSettings command_line_part(const CameraSettings& settings);

// The scene key of a command-line option ("--fps" -> "frame_rate_hz"), or "" for an unknown option.
std::string scene_key_of(const std::string& option);

// What was asked for, one entry per set field (scene key names): "2000 (scene rig.yaml)" or "500 (--fps)".
// Recorded next to the values read back from the device (recording.json "requested_settings").
std::map<std::string, std::string> describe_requested(const CameraSettings& settings);

}  // namespace tirstrain::capture
