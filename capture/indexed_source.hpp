#pragma once
// The common part of the single-file recordings (capture/file_formats.hpp): frames read by number from one
// file, each stamped with its time from the clock chosen by resolve_frame_clock().
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "capture/file_formats.hpp"
#include "capture/frame_source.hpp"

namespace tirstrain::capture {

struct FrameClock {
  std::vector<double> t_s;  // one per frame, s
  std::string source;       // where the times come from, for describe()/settings()
  bool measured = false;    // false when t_s is the frame number
};

// The time axis of `count` frames of `path` (order in capture/file_formats.hpp). `camera_t_s` are the
// file's own timestamps (empty when it has none); `camera_rate_Hz` the rate its header states (0 = none).
FrameClock resolve_frame_clock(const std::string& path, std::int64_t count, std::vector<double> camera_t_s,
                               double camera_rate_Hz, const FileSourceOptions& options);

class IndexedFileSource : public FrameSource {
 public:
  std::optional<Frame> next() override {
    if (next_ >= count_) return std::nullopt;
    const std::int64_t i = next_++;
    Frame frame;
    frame.index = i;
    frame.device_frame_id = i;
    frame.device_time_s = clock_.t_s[static_cast<std::size_t>(i)];
    frame.host_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    frame.origin = path_ + " frame " + std::to_string(i);
    frame.image = read_frame(i);
    return frame;
  }
  std::int64_t frame_count() const override { return count_; }
  std::string describe() const override {
    return kind_ + " " + path_ + " (" + std::to_string(count_) + " frames; time: " + clock_.source + ")";
  }
  std::map<std::string, std::string> settings() const override {
    std::map<std::string, std::string> s = extra_settings_;
    s["kind"] = kind_;
    s["file"] = path_;
    s["frames"] = std::to_string(count_);
    s["time_source"] = clock_.source;
    s["time_measured"] = clock_.measured ? "true" : "false";
    return s;
  }

 protected:
  IndexedFileSource(std::string path, std::string kind) : path_(std::move(path)), kind_(std::move(kind)) {}
  // Called once the frame count and clock are known (by the derived constructor).
  void set_frames(std::int64_t count, FrameClock clock) {
    count_ = count;
    clock_ = std::move(clock);
  }
  virtual cv::Mat read_frame(std::int64_t index) = 0;

  std::string path_;
  std::string kind_;
  std::map<std::string, std::string> extra_settings_;

 private:
  std::int64_t count_ = 0;
  FrameClock clock_;
  std::int64_t next_ = 0;
};

}  // namespace tirstrain::capture
