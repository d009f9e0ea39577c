#pragma once
// One interface for every frame grabber: files (video, image sequences), Aravis (GigE/USB3 Vision), V4L2,
// libcamera. Opened by URI; next() yields frames with device and host timestamps and an honest status.
#include <opencv2/core.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>

namespace tirstrain::capture {

enum class FrameStatus : std::int32_t {
  kOk = 0,
  kIncomplete = 1,  // missing packets / partial buffer: content not trustworthy
  kCorrupt = 2,     // could not be decoded (file sources)
  kGapBefore = 3,   // frames were lost before this one (device counter jumped); this frame itself is fine
  kOverrun = 4,     // host could not keep up; set on the frame after the loss
};

const char* to_string(FrameStatus status);

struct Frame {
  cv::Mat image;                      // CV_8UC1 or CV_16UC1, grey
  std::int64_t index = 0;             // 0-based position in this stream as delivered
  std::int64_t device_frame_id = -1;  // camera's counter (unwrapped), file frame number, or -1 if none
  double device_time_s = 0.0;         // device timestamp (or the file's timestamp column); the time axis
  double host_time_s = 0.0;           // host clock (steady) when the frame was received
  FrameStatus status = FrameStatus::kOk;
  // Frames missing between the previous one and this one; -1 on a frame delivered late (out of order) that
  // an earlier gap had already counted as lost, so that sums over a stream count frames never received.
  std::int64_t frames_lost_before = 0;
  std::string origin;  // file name or device description, for messages
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

  // Live sources (cameras) can wait without blocking forever, so a recorder can honour --seconds and Ctrl-C
  // while no frame arrives (e.g. waiting for a hardware trigger). kTimeout: nothing yet, the stream goes on.
  enum class Poll { kFrame, kTimeout, kEnd };
  virtual Poll poll(Frame& frame, double timeout_s) {
    (void)timeout_s;
    std::optional<Frame> next_frame = next();
    if (!next_frame) return Poll::kEnd;
    frame = std::move(*next_frame);
    return Poll::kFrame;
  }
  virtual bool is_live() const { return false; }
};

// next() of a live source: short polls until a frame arrives or the stream ends (the poll timeout only keeps
// the wait interruptible; nothing is dropped by it).
inline std::optional<Frame> next_by_polling(FrameSource& source) {
  Frame frame;
  for (;;) {
    const FrameSource::Poll result = source.poll(frame, 0.1);
    if (result == FrameSource::Poll::kFrame) return frame;
    if (result == FrameSource::Poll::kEnd) return std::nullopt;
  }
}

// Camera settings from the scene file or the CLI. Unset fields leave the device as it is; every value is
// checked against the device's bounds before it is written and read back afterwards (see settings()).
struct CameraSettings {
  std::string pixel_format;           // "Mono8", "Mono16", "BayerRG8", ... (Bayer is converted to grey)
  std::optional<cv::Rect> roi_px;     // region of interest on the sensor
  std::optional<double> exposure_us;  // GenICam ExposureTime is in microseconds
  std::optional<double> gain_dB;
  std::optional<double> frame_rate_hz;
  std::string trigger;  // "" (leave), "free-run", "software", or a hardware line name ("Line0", "Line1", ...)
  std::optional<int> packet_size_bytes;  // GigE Vision only; default: negotiated with the device
  int buffer_count = 0;                  // stream buffers; 0 chooses from the frame size
  double frame_timeout_s = 0.0;          // no frame for this long: check the camera is still there; 0 = auto

  // Where values came from, for messages (capture/camera_settings.hpp): the command-line options (e.g.
  // "--fps") whose value was read from the `camera:` section of `scene_file`. Backends name
  // key("--fps") in errors about a value: "--fps", or "camera.frame_rate_hz (scene rig.yaml)".
  std::string scene_file;
  std::set<std::string> from_scene;
  std::string key(const std::string& option) const;

  bool empty() const {
    return pixel_format.empty() && !roi_px && !exposure_us && !gain_dB && !frame_rate_hz && trigger.empty() &&
           !packet_size_bytes && buffer_count == 0 && frame_timeout_s == 0.0;
  }
};

// Like open_source(uri), with camera settings applied to camera URIs. Settings given for a file source are an
// error (they would silently do nothing). Defined with the camera backends (aravis_source.cpp).
std::unique_ptr<FrameSource> open_source(const std::string& uri, const CameraSettings& settings);

// Opens a source by URI: "file:PATH", a bare path (folder of frames, printf/glob pattern, or video file),
// "aravis:ID", "v4l2:/dev/videoN", "libcamera:ID". Throws tirstrain::Error with a clear message otherwise.
std::unique_ptr<FrameSource> open_source(const std::string& uri);

}  // namespace tirstrain::capture
