#include "capture/live.hpp"

#include <opencv2/highgui.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <functional>
#include <map>
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

namespace {

// A file source replayed at its recorded rate: each frame is held back until its offset from the first
// frame's timestamp has passed (in steps of at most 50 ms, so that a stop is not held up), so that the
// display and `--record` receive it as a camera would deliver it; its host time is then its delivery time.
class RecordedRatePacer final : public FrameSource {
 public:
  RecordedRatePacer(FrameSource& inner, std::function<bool()> stopped)
      : inner_(inner), stopped_(std::move(stopped)) {}

  std::optional<Frame> next() override { return next_by_polling(*this); }
  Poll poll(Frame& frame, double timeout_s) override {
    const Poll result = inner_.poll(frame, timeout_s);
    if (result != Poll::kFrame) return result;
    return wait_until_due(frame) ? Poll::kFrame : Poll::kEnd;
  }
  std::int64_t frame_count() const override { return inner_.frame_count(); }
  std::string describe() const override { return inner_.describe() + " at its recorded rate"; }
  std::map<std::string, std::string> settings() const override { return inner_.settings(); }
  bool is_live() const override { return inner_.is_live(); }

 private:
  bool wait_until_due(Frame& frame) {
    if (!start_s_) {
      start_s_ = steady_now_s();
      first_device_time_s_ = frame.device_time_s;
    }
    const double due_s = *start_s_ + (frame.device_time_s - first_device_time_s_);
    for (double now_s = steady_now_s(); now_s < due_s; now_s = steady_now_s()) {
      if (stopped_()) return false;
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(due_s - now_s, 0.05)));
    }
    frame.host_time_s = steady_now_s();
    return true;
  }

  FrameSource& inner_;
  std::function<bool()> stopped_;
  std::optional<double> start_s_;
  double first_device_time_s_ = 0.0;
};

// One live session: a capture thread (the source, or the recorder around it) feeds a mailbox; this thread
// takes the newest frame, analyses and shows it, and keeps the rates and latencies.
class LiveSession {
 public:
  LiveSession(FrameSource& source, const LiveOptions& options)
      : paced_(
            source,
            [this] { return stop_capture_.load() || (options_.stop != nullptr && options_.stop->load()); }),
        source_(options.play_at_recorded_rate ? static_cast<FrameSource&>(paced_) : source),
        options_(options) {}

  LiveReport run() {
    open_window();
    std::thread capture([this] { capture_loop(); });
    CaptureThreadGuard capture_guard(capture, stop_capture_);
    start_s_ = interval_start_s_ = steady_now_s();
    for (;;) {
      if (options_.stop != nullptr && options_.stop->load()) stop_capture_.store(true);
      std::optional<Frame> frame = mailbox_.take(0.05);
      if (!frame && mailbox_.done()) break;
      if (frame) show(*frame);
      poll_keys();
      update_rates();
    }
    // The capture thread ends by itself (limit, end of stream, stop); a stop asked for is already set.
    if (capture.joinable()) capture.join();
    return finish();
  }

 private:
  static constexpr const char* kWindow = "tirstrain live";

  void open_window() const {
    if (!options_.window) return;
    // Before the camera thread starts, so a missing display is a plain error and not a dangling thread.
    check_display();
    try {
      cv::namedWindow(kWindow, cv::WINDOW_NORMAL);
    } catch (const cv::Exception& e) {
      throw Error(std::string("cannot open a window (no display?); use --no-window on headless machines: ") +
                      e.what(),
                  {.key = "--no-window"});
    }
  }

  void on_frame(const Frame& frame) {
    counters_.received.fetch_add(1);
    if (frame.status == FrameStatus::kIncomplete) counters_.incomplete.fetch_add(1);
    counters_.lost.fetch_add(frame.frames_lost_before);
    mailbox_.put(frame);
  }

  // The capture thread owns the source; with --record it is the recorder's capture thread itself.
  void capture_loop() {
    try {
      if (!options_.record_dir.empty())
        record_frames();
      else
        poll_frames();
    } catch (const std::exception& e) {
      capture_error_ = e.what();
    }
    mailbox_.finish();
  }

  void record_frames() {
    RecordOptions record = options_.record;
    record.out_dir = options_.record_dir;
    record.out_option = "--record";
    record.max_frames = options_.max_frames;
    record.max_seconds = options_.max_seconds;
    record.stop = &stop_capture_;
    record.on_frame = [this](const Frame& frame) { on_frame(frame); };
    report_.record = tirstrain::capture::record(source_, record);
    report_.recorded = true;
    if (!report_.record.error.empty()) capture_error_ = report_.record.error;
  }

  void poll_frames() {
    const double start_s = steady_now_s();
    Frame frame;
    while (!stop_capture_.load()) {
      if (options_.max_frames >= 0 && counters_.received.load() >= options_.max_frames) break;
      if (options_.max_seconds >= 0 && steady_now_s() - start_s >= options_.max_seconds) break;
      const FrameSource::Poll result = source_.poll(frame, 0.1);
      if (result == FrameSource::Poll::kEnd) break;
      if (result != FrameSource::Poll::kFrame) continue;
      on_frame(frame);
    }
  }

  void fill_counts() {
    LiveStatus& status = report_.status;
    status.frames_received = counters_.received.load();
    status.frames_incomplete = counters_.incomplete.load();
    status.frames_lost = counters_.lost.load();
    status.elapsed_s = steady_now_s() - start_s_;
  }

  // Analysis and status line on the frame, then its latencies, then the window.
  void show(const Frame& frame) {
    cv::Mat canvas = display_canvas(frame.image);
    if (options_.overlay && report_.analysis_error.empty()) run_analysis(options_, frame, canvas, report_);
    fill_counts();
    const LiveStatus& status = report_.status;
    if (options_.window) {
      const std::string text =
          cv::format("%.1f fps  shown %.1f fps  lost %lld  incomplete %lld  latency %.1f ms",
                     status.receive_rate_hz, status.show_rate_hz, static_cast<long long>(status.frames_lost),
                     static_cast<long long>(status.frames_incomplete), status.latency_ms);
      // The first status line (the stages of the analysis use the others), sized to the canvas.
      OverlayText(canvas.size()).status_line(canvas, 0, text, {0, 255, 0});
    }
    record_latency(frame);
    if (options_.window) {
      cv::imshow(kWindow, canvas);
      receive_to_shown_.add(steady_now_s() - frame.host_time_s);
    }
    ++report_.status.frames_shown;
  }

  // The overlay is ready to show: what the user sees lags the camera by at least this much.
  void record_latency(const Frame& frame) {
    const double ready_s = steady_now_s();
    const double ready_realtime_s = realtime_now_s();
    receive_to_ready_.add(ready_s - frame.host_time_s);
    latency_sum_s_ += ready_s - frame.host_time_s;
    ++latency_count_;
    if (!device_clock_is_host_clock_)
      device_clock_is_host_clock_ = std::abs(ready_realtime_s - frame.device_time_s) < 1.0;
    if (*device_clock_is_host_clock_) device_to_ready_.add(ready_realtime_s - frame.device_time_s);
  }

  void poll_keys() {
    if (!options_.window) return;
    const int key = cv::waitKey(1);
    if (key == 'q' || key == 27) stop_capture_.store(true);
  }

  // Once a second: the receive and show rates and the mean latency over the last second.
  void update_rates() {
    const double now_s = steady_now_s();
    if (now_s - interval_start_s_ < 1.0) return;
    fill_counts();
    LiveStatus& status = report_.status;
    status.receive_rate_hz =
        static_cast<double>(status.frames_received - received_at_interval_) / (now_s - interval_start_s_);
    status.show_rate_hz =
        static_cast<double>(status.frames_shown - shown_at_interval_) / (now_s - interval_start_s_);
    status.latency_ms = latency_count_ > 0 ? 1e3 * latency_sum_s_ / static_cast<double>(latency_count_) : 0.0;
    received_at_interval_ = status.frames_received;
    shown_at_interval_ = status.frames_shown;
    latency_sum_s_ = 0.0;
    latency_count_ = 0;
    interval_start_s_ = now_s;
    if (options_.on_status) options_.on_status(status);
  }

  LiveReport finish() {
    if (options_.window) cv::destroyWindow(kWindow);
    fill_counts();
    if (report_.recorded)
      report_.status.frames_lost =
          report_.record.counts.frames_lost_device + report_.record.counts.frames_dropped_host;
    report_.error = capture_error_;
    report_.receive_to_ready = summarize(receive_to_ready_);
    report_.receive_to_shown = summarize(receive_to_shown_);
    report_.device_to_ready = summarize(device_to_ready_);
    return report_;
  }

  std::atomic<bool> stop_capture_{false};
  RecordedRatePacer paced_;  // the source, held back to its recorded rate (--recorded-rate)
  FrameSource& source_;      // the source or paced_: what the capture thread reads
  const LiveOptions& options_;
  LiveReport report_;
  Mailbox mailbox_;
  Counters counters_;
  std::string capture_error_;  // written by the capture thread, read after it is joined
  double start_s_ = 0.0, interval_start_s_ = 0.0;
  std::int64_t received_at_interval_ = 0, shown_at_interval_ = 0;
  double latency_sum_s_ = 0.0;
  std::int64_t latency_count_ = 0;
  LatencyHistogram receive_to_ready_, receive_to_shown_, device_to_ready_;
  std::optional<bool> device_clock_is_host_clock_;  // decided at the first frame shown
};

}  // namespace

LiveReport run_live(FrameSource& source, const LiveOptions& options) {
  return LiveSession(source, options).run();
}

}  // namespace tirstrain::capture
