#pragma once
// Frame sources backed by files: image sequences (a folder, a printf pattern such as "run/img_%05d.png",
// or a glob such as "run/*.tif") and video files decoded by OpenCV/FFmpeg.
//
// Time axis (DESIGN: time comes from the source's timestamps, never index / fps):
// - image sequences take t_s from a `frames.csv` (`index,t_s`) next to the images, or in the folder that
//   holds the `frames/` directory. Without one there is no clock at all; t_s is then the frame number and
//   settings()["time_source"] says so, so callers can warn the user.
// - video files take t_s from the container's presentation timestamps (CAP_PROP_POS_MSEC).
#include <memory>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"

namespace tirstrain::capture {

// A folder of frames: DIR/frames/*.png (+ DIR/frames.csv) or images directly in DIR (+ DIR/frames.csv).
std::unique_ptr<FrameSource> open_image_folder(const std::string& dir);
// "a/b_%06d.png" (printf) or "a/*.png" (glob, wildcards only in the file name).
std::unique_ptr<FrameSource> open_image_pattern(const std::string& pattern);
std::unique_ptr<FrameSource> open_video_file(const std::string& path);
// Chooses among the three by what `path` is. Throws Error naming the path if nothing fits.
std::unique_ptr<FrameSource> open_file_source(const std::string& path);

// Image extensions read as frames (lower case, with the dot).
bool is_image_file_name(const std::string& name);
// Orders "f2.png" before "f10.png": digit runs compare by value.
bool natural_less(const std::string& a, const std::string& b);

}  // namespace tirstrain::capture
