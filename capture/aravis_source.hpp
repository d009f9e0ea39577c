#pragma once
// GigE Vision / USB3 Vision cameras through Aravis ("aravis:<device id or IP address>").
//
// Frame accounting: every buffer the stream hands back becomes a Frame. Buffers that are not complete
// (missing packets, timeout, size mismatch, aborted) come out with FrameStatus::kIncomplete and are never
// labelled ok. The device's 16-bit GigE Vision block id (1..65535, 0 is reserved and skipped on wrap) is
// unwrapped to a monotonic 64-bit counter; a jump in it marks the next frame kGapBefore (or kOverrun when
// the host stream ran out of buffers meanwhile) with the number of frames lost.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"

namespace tirstrain::capture {

// Turns a device frame counter that wraps into a monotonic one. GigE Vision 1.x block ids count
// 1..65535 and then restart at 1 (0 is reserved), so the period is 65535, not 65536. Counters that exceed
// 16 bits (GEV 2 extended ids, USB3 Vision) are taken as they are.
class FrameIdUnwrapper {
 public:
  std::int64_t unwrap(std::uint64_t raw_id);
  // What unwrap would return, without taking the id as the newest.
  std::int64_t peek(std::uint64_t raw_id) const;
  void reset() { have_last_ = false; }

 private:
  std::int64_t delta(std::uint64_t raw_id) const;
  bool have_last_ = false;
  bool wide_ = false;
  std::uint64_t last_raw_ = 0;
  std::int64_t last_unwrapped_ = 0;
};

struct CameraInfo {
  std::string backend;  // "aravis", "v4l2", "libcamera"
  std::string uri;      // what to pass to record/live, e.g. "aravis:Aravis-Fake-GV01"
  std::string model;
  std::string serial;
  std::string address;   // IP address, device node, ...
  std::string protocol;  // "GigEVision", "USB3Vision", ...
};

// Discovers Aravis cameras (GigE Vision broadcast discovery takes about a second).
std::vector<CameraInfo> list_aravis_cameras();

// Opens an Aravis camera by device id ("Basler-21234567"), IP address ("192.168.1.20") or, with an empty
// id, the first camera found. Applies `settings`, starts acquisition. Throws Error with the URI and the
// offending option on anything wrong.
std::unique_ptr<FrameSource> open_aravis_source(const std::string& id, const CameraSettings& settings);

// Sends one software trigger to an Aravis source opened with trigger "software" and auto triggering
// turned off (see AravisSourceOptions). Throws Error if `source` is not such a source.
void software_trigger(FrameSource& source);
// Software-trigger sources normally fire one trigger per next()/poll() call that has no frame pending;
// tests turn that off to check that no frame arrives without a trigger.
void set_auto_software_trigger(FrameSource& source, bool enabled);

// Host-side stream counters as Aravis reports them (completed, failures, underruns).
std::map<std::string, std::int64_t> aravis_stream_statistics(const FrameSource& source);

}  // namespace tirstrain::capture
