#pragma once
// One interface for every frame grabber: files (video, image sequences), Aravis (GigE/USB3 Vision), V4L2,
// libcamera. Opened by URI; next() yields frames with device and host timestamps and an honest status.
#include <opencv2/core.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

namespace tirstrain::capture {

enum class FrameStatus : std::int32_t {
  kOk = 0,
  kIncomplete = 1,    // missing packets / partial buffer: content not trustworthy
  kCorrupt = 2,       // could not be decoded (file sources)
  kGapBefore = 3,     // frames were lost before this one (device counter jumped); this frame itself is fine
  kOverrun = 4,       // host could not keep up; set on the frame after the loss
};

const char* to_string(FrameStatus status);

struct Frame {
  cv::Mat image;                    // CV_8UC1 or CV_16UC1, grey
  std::int64_t index = 0;           // 0-based position in this stream as delivered
  std::int64_t device_frame_id = -1;  // camera's counter (unwrapped), file frame number, or -1 if none
  double device_time_s = 0.0;       // device timestamp (or the file's timestamp column); the time axis
  double host_time_s = 0.0;         // host clock (steady) when the frame was received
  FrameStatus status = FrameStatus::kOk;
  std::int64_t frames_lost_before = 0;  // count of frames missing between the previous one and this one
  std::string origin;               // file name or device description, for messages
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // The next frame, or std::nullopt at the end of the stream. Unrecoverable errors throw tirstrain::Error.
  virtual std::optional<Frame> next() = 0;
  // Frames expected in total, if known (files); -1 for live sources.
  virtual std::int64_t frame_count() const { return -1; }
  // Human-readable description and every setting read back from the device (exposure, format, ...).
  virtual std::string describe() const = 0;
  virtual std::map<std::string, std::string> settings() const { return {}; }
};

// Opens a source by URI: "file:PATH", a bare path (folder of frames, printf/glob pattern, or video file),
// "aravis:ID", "v4l2:/dev/videoN", "libcamera:ID". Throws tirstrain::Error with a clear message otherwise.
std::unique_ptr<FrameSource> open_source(const std::string& uri);

}  // namespace tirstrain::capture
