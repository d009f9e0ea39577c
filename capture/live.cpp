#include "capture/live.hpp"

#include <opencv2/highgui.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <thread>

#include "core/error.hpp"
#include "core/overlay_text.hpp"

namespace tirstrain::capture {
namespace {

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double realtime_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

constexpr double kLatencyFloorS = 1e-6;
constexpr double kLatencyStep = 1.01;
const double kLogStep = std::log(kLatencyStep);
constexpr std::size_t kLatencyBins = 2084;  // 1 µs * 1.01^2083 ≈ 1000 s

// Holds only the newest frame: the display takes what is there and never queues behind the camera.
class Mailbox {
 public:
  void put(const Frame& frame) {
    {
      std::lock_guard lock(mutex_);
      latest_ = frame;  // shares the pixels (cv::Mat refcount); nobody writes into a delivered frame
    }
    ready_.notify_one();
  }
  std::optional<Frame> take(double timeout_s) {
    std::unique_lock lock(mutex_);
    ready_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                    [this] { return latest_.has_value() || done_; });
    std::optional<Frame> out = std::move(latest_);
    latest_.reset();
    return out;
  }
  void finish() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    ready_.notify_all();
  }
  bool done() {
    std::lock_guard lock(mutex_);
    return done_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::optional<Frame> latest_;
  bool done_ = false;
};

// Stops and joins the capture thread however the display loop ends (an exception included), so the
// recording ends cleanly and no thread is left running at exit (std::terminate).
class CaptureThreadGuard {
 public:
  CaptureThreadGuard(std::thread& thread, std::atomic<bool>& stop) : thread_(thread), stop_(stop) {}
  ~CaptureThreadGuard() { join(); }
  CaptureThreadGuard(const CaptureThreadGuard&) = delete;
  CaptureThreadGuard& operator=(const CaptureThreadGuard&) = delete;
  void join() {
    if (!thread_.joinable()) return;
    stop_.store(true);
    thread_.join();
  }

 private:
  std::thread& thread_;
  std::atomic<bool>& stop_;
};

struct Counters {
  std::atomic<std::int64_t> received{0};
  std::atomic<std::int64_t> incomplete{0};
  std::atomic<std::int64_t> lost{0};
};

// The analysis hook on one frame. Its first error stops the analysis for the rest of the run (its stages'
// state is then unknown) but never the capture or the recording.
void run_analysis(const LiveOptions& options, const Frame& frame, cv::Mat& canvas, LiveReport& report) {
  try {
    options.overlay(frame, canvas);
  } catch (const std::exception& e) {
    std::string message = e.what();
    while (!message.empty() && std::isspace(static_cast<unsigned char>(message.back()))) message.pop_back();
    report.analysis_error = format_error(message, {.frame = frame.index});
    if (options.on_analysis_error) options.on_analysis_error(report.analysis_error);
  }
}

}  // namespace

void LatencyHistogram::add(double seconds) {
  if (bins_.empty()) bins_.assign(kLatencyBins, 0);
  const double s = std::max(seconds, kLatencyFloorS);
  const auto bin = static_cast<std::size_t>(std::log(s / kLatencyFloorS) / kLogStep);
  ++bins_[std::min(bin, kLatencyBins - 1)];
  ++count_;
  max_s_ = std::max(max_s_, seconds);
}

double LatencyHistogram::quantile_ms(double q) const {
  if (count_ == 0) return 0.0;
  const auto rank = std::max<std::int64_t>(
      1, static_cast<std::int64_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(count_))));
  std::int64_t seen = 0;
  for (std::size_t i = 0; i < bins_.size(); ++i) {
    seen += bins_[i];
    if (seen >= rank)
      return std::min(1e3 * kLatencyFloorS * std::pow(kLatencyStep, static_cast<double>(i) + 0.5), max_ms());
  }
  return max_ms();
}

LatencySummary summarize(const LatencyHistogram& histogram) {
  return {histogram.count(), histogram.quantile_ms(0.5), histogram.quantile_ms(0.95), histogram.max_ms()};
}

void check_display() {
  // OpenCV's Qt backend aborts the process without a display instead of throwing: check first.
  const char* x11 = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  const char* qt = std::getenv("QT_QPA_PLATFORM");
  if ((x11 == nullptr || *x11 == '\0') && (wayland == nullptr || *wayland == '\0') && qt == nullptr)
    throw Error("no display (DISPLAY is not set); use --no-window on headless machines",
                {.key = "--no-window"});
}

cv::Mat display_canvas(const cv::Mat& image) {
  cv::Mat grey8;
  if (image.depth() == CV_16U) {
    double max_value = 0;
    cv::minMaxLoc(image, nullptr, &max_value);
    image.convertTo(grey8, CV_8U, max_value > 0 ? 255.0 / max_value : 1.0);
  } else {
    grey8 = image;
  }
  cv::Mat canvas;
  cv::cvtColor(grey8, canvas, cv::COLOR_GRAY2BGR);
  return canvas;
}

LiveReport run_live(FrameSource& source, const LiveOptions& options) {
  const std::string window = "tirstrain live";
  if (options.window) {
    // Before the camera thread starts, so a missing display is a plain error and not a dangling thread.
    check_display();
    try {
      cv::namedWindow(window, cv::WINDOW_NORMAL);
    } catch (const cv::Exception& e) {
      throw Error(std::string("cannot open a window (no display?); use --no-window on headless machines: ") +
                      e.what(),
                  {.key = "--no-window"});
    }
  }
  LiveReport report;
  Mailbox mailbox;
  Counters counters;
  std::atomic<bool> stop_capture{false};
  std::string capture_error;
  const bool recording = !options.record_dir.empty();

  // The capture thread owns the source; with --record it is the recorder's capture thread itself.
  std::thread capture([&] {
    auto on_frame = [&](const Frame& frame) {
      counters.received.fetch_add(1);
      if (frame.status == FrameStatus::kIncomplete) counters.incomplete.fetch_add(1);
      counters.lost.fetch_add(frame.frames_lost_before);
      mailbox.put(frame);
    };
    try {
      if (recording) {
        RecordOptions record = options.record;
        record.out_dir = options.record_dir;
        record.max_frames = options.max_frames;
        record.max_seconds = options.max_seconds;
        record.stop = &stop_capture;
        record.on_frame = on_frame;
        report.record = tirstrain::capture::record(source, record);
        report.recorded = true;
        if (!report.record.error.empty()) capture_error = report.record.error;
      } else {
        const double start_s = steady_now_s();
        Frame frame;
        while (!stop_capture.load()) {
          if (options.max_frames >= 0 && counters.received.load() >= options.max_frames) break;
          if (options.max_seconds >= 0 && steady_now_s() - start_s >= options.max_seconds) break;
          const FrameSource::Poll result = source.poll(frame, 0.1);
          if (result == FrameSource::Poll::kEnd) break;
          if (result == FrameSource::Poll::kFrame) on_frame(frame);
        }
      }
    } catch (const Error& e) {
      capture_error = e.what();
    } catch (const std::exception& e) {
      capture_error = e.what();
    }
    mailbox.finish();
  });
  CaptureThreadGuard capture_guard(capture, stop_capture);

  const double start_s = steady_now_s();
  double interval_start_s = start_s;
  std::int64_t received_at_interval = 0;
  std::int64_t shown_at_interval = 0;
  double latency_sum_s = 0.0;
  std::int64_t latency_count = 0;
  LatencyHistogram receive_to_ready, receive_to_shown, device_to_ready;
  std::optional<bool> device_clock_is_host_clock;  // decided at the first frame shown
  LiveStatus& status = report.status;
  auto fill_counts = [&] {
    status.frames_received = counters.received.load();
    status.frames_incomplete = counters.incomplete.load();
    status.frames_lost = counters.lost.load();
    status.elapsed_s = steady_now_s() - start_s;
  };
  for (;;) {
    if (options.stop != nullptr && options.stop->load()) stop_capture.store(true);
    std::optional<Frame> frame = mailbox.take(0.05);
    if (!frame && mailbox.done()) break;
    if (frame) {
      cv::Mat canvas = display_canvas(frame->image);
      if (options.overlay && report.analysis_error.empty()) run_analysis(options, *frame, canvas, report);
      fill_counts();
      if (options.window) {
        const std::string text = cv::format(
            "%.1f fps  shown %.1f fps  lost %lld  incomplete %lld  latency %.1f ms", status.receive_rate_hz,
            status.show_rate_hz, static_cast<long long>(status.frames_lost),
            static_cast<long long>(status.frames_incomplete), status.latency_ms);
        // The first status line (the stages of the analysis use the others), sized to the canvas.
        OverlayText(canvas.size()).status_line(canvas, 0, text, {0, 255, 0});
      }
      // The overlay is ready to show: what the user sees lags the camera by at least this much.
      const double ready_s = steady_now_s();
      const double ready_realtime_s = realtime_now_s();
      receive_to_ready.add(ready_s - frame->host_time_s);
      latency_sum_s += ready_s - frame->host_time_s;
      ++latency_count;
      if (!device_clock_is_host_clock)
        device_clock_is_host_clock = std::abs(ready_realtime_s - frame->device_time_s) < 1.0;
      if (*device_clock_is_host_clock) device_to_ready.add(ready_realtime_s - frame->device_time_s);
      if (options.window) {
        cv::imshow(window, canvas);
        receive_to_shown.add(steady_now_s() - frame->host_time_s);
      }
      ++status.frames_shown;
    }
    if (options.window) {
      const int key = cv::waitKey(1);
      if (key == 'q' || key == 27) stop_capture.store(true);
    }
    const double now_s = steady_now_s();
    if (now_s - interval_start_s >= 1.0) {
      fill_counts();
      status.receive_rate_hz =
          static_cast<double>(status.frames_received - received_at_interval) / (now_s - interval_start_s);
      status.show_rate_hz =
          static_cast<double>(status.frames_shown - shown_at_interval) / (now_s - interval_start_s);
      status.latency_ms = latency_count > 0 ? 1e3 * latency_sum_s / static_cast<double>(latency_count) : 0.0;
      received_at_interval = status.frames_received;
      shown_at_interval = status.frames_shown;
      latency_sum_s = 0.0;
      latency_count = 0;
      interval_start_s = now_s;
      if (options.on_status) options.on_status(status);
    }
  }
  // The capture thread ends by itself (limit, end of stream, stop); a stop asked for is already set.
  if (capture.joinable()) capture.join();
  if (options.window) cv::destroyWindow(window);
  fill_counts();
  if (report.recorded)
    status.frames_lost = report.record.counts.frames_lost_device + report.record.counts.frames_dropped_host;
  report.error = capture_error;
  report.receive_to_ready = summarize(receive_to_ready);
  report.receive_to_shown = summarize(receive_to_shown);
  report.device_to_ready = summarize(device_to_ready);
  return report;
}

}  // namespace tirstrain::capture
