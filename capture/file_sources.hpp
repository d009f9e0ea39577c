#pragma once
// Frame sources backed by files: image sequences (a folder, a printf pattern such as "run/img_%05d.png",
// or a glob such as "run/*.tif"), single-file recordings (capture/file_formats.hpp) and video files decoded
// by OpenCV/FFmpeg.
//
// Time axis (DESIGN: time comes from the source's timestamps, never index / fps):
// - image sequences take t_s from a `frames.csv` (`index,t_s`) next to the images, or in the folder that
//   holds the `frames/` directory. Without one there is no clock at all; t_s is then the frame number and
//   settings()["time_source"] says so, so callers can warn the user.
// - video files take t_s from the container's presentation timestamps (CAP_PROP_POS_MSEC).
#include <memory>
#include <string>
#include <vector>

#include "capture/file_formats.hpp"
#include "capture/frame_source.hpp"

namespace tirstrain::capture {

// A folder of frames: DIR/frames/*.png (+ DIR/frames.csv) or images directly in DIR (+ DIR/frames.csv, or
// for a folder named frames the frames.csv beside it). Without a frames.csv, `options.frame_rate_Hz` times
// the frames; with one, giving it too is an error (one clock).
std::unique_ptr<FrameSource> open_image_folder(const std::string& dir, const FileSourceOptions& options = {});
// "a/b_%06d.png" (printf) or "a/*.png" (glob, wildcards only in the file name); times as for a folder.
std::unique_ptr<FrameSource> open_image_pattern(const std::string& pattern,
                                                const FileSourceOptions& options = {});
// A video through FFmpeg; `options.frame_rate_Hz` replaces the container's timestamps (an export that plays
// back at another rate than the camera recorded). A video of more than 8 bits per sample is refused: the
// reader decodes to 8 bits.
std::unique_ptr<FrameSource> open_video_file(const std::string& path, const FileSourceOptions& options = {});
// Chooses by what `path` is: a folder, a pattern, or a file judged by its first bytes (multi-page TIFF,
// BigTIFF, .cine, .mraw/.cih: capture/file_formats.hpp), then by its name (an image, else a video). Throws
// Error naming the path, what it holds and the formats read if nothing fits.
std::unique_ptr<FrameSource> open_file_source(const std::string& path, const FileSourceOptions& options = {});

// open_source(uri) (capture/frame_source.hpp) with options for file sources; giving them for a camera URI is
// an error.
std::unique_ptr<FrameSource> open_source(const std::string& uri, const FileSourceOptions& file_options);

// open_source(uri, settings) (capture/frame_source.hpp) with options for file sources as well.
std::unique_ptr<FrameSource> open_source(const std::string& uri, const CameraSettings& settings,
                                         const FileSourceOptions& file_options);

// Image extensions read as frames (lower case, with the dot).
bool is_image_file_name(const std::string& name);
// Orders "f2.png" before "f10.png": digit runs compare by value.
bool natural_less(const std::string& a, const std::string& b);

}  // namespace tirstrain::capture
