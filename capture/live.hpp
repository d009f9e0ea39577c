#pragma once
// Live view: a capture thread keeps only the newest frame for the display, so a slow display (or slow
// analysis in the overlay hook) skips frames on screen but never slows acquisition or the optional
// recording running on the same thread as the capture.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"

namespace tirstrain::capture {

// Latency distribution over a whole run (log-spaced bins 1 % wide from 1 µs to 1000 s, so memory stays
// bounded however long the run is; median and p95 are good to ±0.5 %, max is exact).
class LatencyHistogram {
 public:
  void add(double seconds);
  std::int64_t count() const { return count_; }
  double quantile_ms(double q) const;  // 0 when empty
  double max_ms() const { return 1e3 * max_s_; }

 private:
  std::vector<std::int64_t> bins_;
  std::int64_t count_ = 0;
  double max_s_ = 0.0;
};

struct LatencySummary {
  std::int64_t frames = 0;  // frames measured
  double median_ms = 0.0, p95_ms = 0.0, max_ms = 0.0;
};
LatencySummary summarize(const LatencyHistogram& histogram);

struct LiveStatus {
  std::int64_t frames_received = 0;
  std::int64_t frames_shown = 0;  // displayed (window) or analysed (--no-window)
  std::int64_t frames_incomplete = 0;
  std::int64_t frames_lost = 0;  // device gaps + host drops (recording queue full)
  double receive_rate_hz = 0.0;
  double show_rate_hz = 0.0;
  double latency_ms = 0.0;  // frame arrival on the host -> overlay ready, mean over the last interval
  double elapsed_s = 0.0;
};

struct LiveOptions {
  bool window = true;
  std::string record_dir;  // record at the same time when not empty (record options below)
  RecordOptions record;    // out_dir is taken from record_dir
  std::int64_t max_frames = -1;
  double max_seconds = -1.0;
  // A recording is delivered as fast as it is read; true delivers each frame at its timestamp's offset from
  // the first (a replay at the recorded rate, as the camera gave it). Cameras ignore it: they pace
  // themselves.
  bool play_at_recorded_rate = false;
  const std::atomic<bool>* stop = nullptr;
  // Analysis and drawing for one displayed frame, on the display thread. `canvas` is the frame as 8-bit
  // BGR at full size; draw contact hull, ellipse, tracks, strain heat map onto it as those stages exist.
  // Without a window it still runs (headless analysis), on a canvas nobody sees.
  std::function<void(const Frame& frame, cv::Mat& canvas)> overlay;
  // Once, with the message, when the overlay hook throws: the analysis stops, capture and recording go on.
  std::function<void(const std::string&)> on_analysis_error;
  // Once per second with the current counts (prints status lines in the CLI).
  std::function<void(const LiveStatus&)> on_status;
};

struct LiveReport {
  LiveStatus status;
  // Capture -> display latency of every frame shown, from the frame's host receive time (Frame::host_time_s:
  // the start of its arrival) to: the overlay being ready to show (canvas converted, analysis stages run and
  // drawn, status text drawn); and, with a window, cv::imshow returning. device_to_ready starts at the
  // device timestamp instead, and is measured only when the device clock runs on the host's wall clock
  // (within 1 s at the first frame: PTP-synchronised cameras, Aravis' fake camera); otherwise frames = 0.
  LatencySummary receive_to_ready;
  LatencySummary receive_to_shown;
  LatencySummary device_to_ready;
  RecordReport record;  // when recording
  bool recorded = false;
  std::string error;           // source error (camera lost) or recording error
  std::string analysis_error;  // why the analysis stopped (the overlay hook threw); empty when it did not
};

LiveReport run_live(FrameSource& source, const LiveOptions& options);

// Throws Error (pointing at --no-window) when there is no display to open a window on.
void check_display();

// The frame as 8-bit BGR for drawing: 16-bit frames are scaled by their own maximum so dim images show.
cv::Mat display_canvas(const cv::Mat& image);

}  // namespace tirstrain::capture
