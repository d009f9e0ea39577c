#pragma once
// Video4Linux2 capture devices ("v4l2:/dev/videoN", or "v4l2:N" for /dev/videoN), with mmap streaming
// through the V4L2 ioctls directly.
//
// Pixel formats: GREY (8-bit), Y16 (16-bit, little-endian) and YUYV (its luma plane is taken as the grey
// image, exactly, with no colour conversion). Frame rate (VIDIOC_S_PARM) and exposure
// (V4L2_CID_EXPOSURE_ABSOLUTE, 100 µs units) are set where the device has them and read back into
// settings(); asking for one the device does not have is an error, never silently ignored.
//
// Frame accounting: the driver's 32-bit buffer sequence number is unwrapped to the device frame id and its
// timestamp (CLOCK_MONOTONIC for every driver that streams) is the device time. A jump in the sequence marks
// the next frame kGapBefore with the number of frames lost (the driver dropped buffers, or the host did not
// queue them back in time); a buffer with V4L2_BUF_FLAG_ERROR comes out kIncomplete. A device that goes away
// while streaming (unplugged, driver unbound) ends the stream with an Error saying so, after every frame
// received before it.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "capture/aravis_source.hpp"  // CameraInfo
#include "capture/frame_source.hpp"

namespace tirstrain::capture {

// Frames lost between consecutive V4L2 buffers, from their 32-bit sequence numbers (pure; tested on the
// host). The counter is unwrapped modulo 2^32.
class SequenceGapCounter {
 public:
  struct Step {
    std::int64_t frame_id = 0;     // unwrapped sequence number, relative to nothing (the driver's own count)
    std::int64_t lost_before = 0;  // > 0: frames missing before this one; -1: a late frame already counted
  };
  Step add(std::uint32_t sequence);
  std::int64_t lost() const { return lost_; }     // sum of lost_before so far
  std::int64_t frames() const { return count_; }  // buffers seen
  void reset() { *this = SequenceGapCounter{}; }

 private:
  bool have_last_ = false;
  std::uint32_t last_raw_ = 0;
  std::int64_t last_id_ = 0;
  std::int64_t lost_ = 0;
  std::int64_t count_ = 0;
};

// "v4l2:" URI body → device node: "/dev/video3" stays, "3" becomes "/dev/video3". Throws Error on an empty
// or malformed body.
std::string v4l2_device_path(const std::string& uri_body);

// Pixel format names accepted in CameraSettings::pixel_format for V4L2 ("GREY"/"Mono8", "Y16"/"Mono16",
// "YUYV"), to the V4L2 fourcc; throws Error naming settings.key("--pixel-format") otherwise.
std::uint32_t v4l2_fourcc_of(const std::string& name, const std::string& key);
std::string fourcc_to_string(std::uint32_t fourcc);

// Capture-capable V4L2 nodes (metadata and output nodes are left out), for `tirstrain cameras`.
std::vector<CameraInfo> list_v4l2_cameras();

// Opens and starts streaming. Throws Error with the URI and the offending option on anything wrong.
std::unique_ptr<FrameSource> open_v4l2_source(const std::string& uri_body, const CameraSettings& settings);

}  // namespace tirstrain::capture
