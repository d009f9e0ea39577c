// URI dispatch for every frame source. File sources live in file_sources.cpp; camera backends add their
// scheme here when they are built.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include "capture/aravis_source.hpp"
#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "capture/libcamera_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {

const char* to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk:
      return "ok";
    case FrameStatus::kIncomplete:
      return "incomplete";
    case FrameStatus::kCorrupt:
      return "corrupt";
    case FrameStatus::kGapBefore:
      return "gap_before";
    case FrameStatus::kOverrun:
      return "overrun";
  }
  return "unknown";
}

std::unique_ptr<FrameSource> open_source(const std::string& uri) {
  return open_source(uri, FileSourceOptions{});
}

std::unique_ptr<FrameSource> open_source(const std::string& uri, const FileSourceOptions& file_options) {
  const auto colon = uri.find(':');
  // A one-letter "scheme" would be a Windows drive; a slash before the colon means a path containing ':'.
  if (colon != std::string::npos && colon > 1 && uri.find('/') > colon) {
    const std::string scheme = uri.substr(0, colon);
    const std::string rest = uri.substr(colon + 1);
    if (scheme == "file") return open_file_source(rest, file_options);
    if (file_options.frame_rate_Hz && scheme != "file")
      throw Error(
          "--frame-rate-Hz times a recorded file that holds no timestamps; a camera stamps its own "
          "frames (set its rate with --fps)",
          {.file = uri, .key = "--frame-rate-Hz"});
    if (scheme == "aravis") return open_aravis_source(rest, {});
    if (scheme == "v4l2") return open_v4l2_source(rest, {});
    if (scheme == "libcamera") return open_libcamera_source(rest, {});
    std::error_code ec;
    const bool word = std::all_of(scheme.begin(), scheme.end(), [](char c) { return std::isalnum(c) != 0; });
    if (word && !std::filesystem::exists(uri, ec) && uri.find_first_of("%*?[") == std::string::npos)
      throw Error("unknown source scheme '" + scheme +
                      ":'; sources are aravis:ID (or aravis:IP), v4l2:/dev/videoN, libcamera:ID, "
                      "file:PATH or a plain path (a folder of frames, an image pattern or a video file)",
                  {.key = "URI"});
  }
  return open_file_source(uri, file_options);
}

}  // namespace tirstrain::capture
