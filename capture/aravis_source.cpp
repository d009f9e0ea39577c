#include "capture/aravis_source.hpp"
#include "capture/file_sources.hpp"

#include <arv.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>

#include "capture/camera_settings.hpp"
#include "capture/libcamera_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {

std::int64_t FrameIdUnwrapper::delta(std::uint64_t raw_id) const {
  constexpr std::uint64_t kGevPeriod = 65535;  // ids 1..65535; 0 is reserved
  if (wide_ || raw_id > 65535) return static_cast<std::int64_t>(raw_id - last_raw_);
  // Work in 0-based ids so the skipped 0 does not count as a lost frame.
  const std::uint64_t now = raw_id == 0 ? 0 : raw_id - 1;
  const std::uint64_t before = last_raw_ == 0 ? 0 : last_raw_ - 1;
  auto d = static_cast<std::int64_t>((now + kGevPeriod - before) % kGevPeriod);
  // More than half a period ahead is a frame from the past delivered late (Aravis can hand a frame over
  // after newer ones, e.g. when its buffer pool ran dry), not a wrap.
  if (d > static_cast<std::int64_t>(kGevPeriod / 2)) d -= static_cast<std::int64_t>(kGevPeriod);
  return d;
}

std::int64_t FrameIdUnwrapper::peek(std::uint64_t raw_id) const {
  return have_last_ ? last_unwrapped_ + delta(raw_id) : static_cast<std::int64_t>(raw_id);
}

std::int64_t FrameIdUnwrapper::unwrap(std::uint64_t raw_id) {
  if (!have_last_) {
    have_last_ = true;
    wide_ = raw_id > 65535;
    last_raw_ = raw_id;
    last_unwrapped_ = static_cast<std::int64_t>(raw_id);
    return last_unwrapped_;
  }
  const std::int64_t d = delta(raw_id);
  if (raw_id > 65535) wide_ = true;
  if (d < 0) return last_unwrapped_ + d;  // late: the newest id stays the reference
  last_raw_ = raw_id;
  last_unwrapped_ += d;
  return last_unwrapped_;
}

namespace {

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double realtime_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// GError is C: always take its message and free it, then throw the project's error.
void throw_if(GError*& error, const std::string& what, ErrorContext context) {
  if (error == nullptr) return;
  const std::string message = what + ": " + error->message;
  g_clear_error(&error);
  throw Error(message, std::move(context));
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

std::vector<std::string> take_strings(const char** strings, guint n) {
  std::vector<std::string> out;
  for (guint i = 0; i < n && strings != nullptr; ++i)
    if (strings[i] != nullptr) out.emplace_back(strings[i]);
  g_free(strings);  // the array is ours, the strings belong to the camera's GenICam tree
  return out;
}

struct PixelLayout {
  int cv_depth = -1;
  int bayer_to_grey = -1;  // cv::COLOR_Bayer*2GRAY code, or -1 for grey formats
};

// GenICam Bayer names give the colour of the first two pixels of the first row; OpenCV's names give those
// of the second row, second and third pixels, hence the swaps.
std::optional<PixelLayout> layout_of(ArvPixelFormat format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_8:
      return PixelLayout{CV_8U, -1};
    case ARV_PIXEL_FORMAT_MONO_10:
    case ARV_PIXEL_FORMAT_MONO_12:
    case ARV_PIXEL_FORMAT_MONO_14:
    case ARV_PIXEL_FORMAT_MONO_16:
      return PixelLayout{CV_16U, -1};
    case ARV_PIXEL_FORMAT_BAYER_RG_8:
      return PixelLayout{CV_8U, cv::COLOR_BayerBG2GRAY};
    case ARV_PIXEL_FORMAT_BAYER_BG_8:
      return PixelLayout{CV_8U, cv::COLOR_BayerRG2GRAY};
    case ARV_PIXEL_FORMAT_BAYER_GR_8:
      return PixelLayout{CV_8U, cv::COLOR_BayerGB2GRAY};
    case ARV_PIXEL_FORMAT_BAYER_GB_8:
      return PixelLayout{CV_8U, cv::COLOR_BayerGR2GRAY};
    default:
      return std::nullopt;
  }
}

constexpr const char* kSupportedFormats =
    "Mono8, Mono10, Mono12, Mono14, Mono16, BayerRG8, BayerBG8, BayerGR8, BayerGB8";

bool is_supported_format(const std::string& name) {
  const std::string list = kSupportedFormats;
  for (std::size_t from = 0; from <= list.size();) {
    const std::size_t end = std::min(list.find(", ", from), list.size());
    if (list.compare(from, end - from, name) == 0) return true;
    from = end + 2;
  }
  return false;
}

enum class TriggerMode { kFreeRun, kSoftware, kHardware };

class AravisSource final : public FrameSource {
 public:
  AravisSource(const std::string& id, const CameraSettings& requested)
      : uri_("aravis:" + id), requested_(requested) {
    GError* error = nullptr;
    camera_ = arv_camera_new(id.empty() ? nullptr : id.c_str(), &error);
    if (camera_ == nullptr || error != nullptr) {
      const std::string reason = error != nullptr ? error->message : "no camera found";
      g_clear_error(&error);
      throw Error("cannot open Aravis camera '" + (id.empty() ? std::string("<first found>") : id) +
                      "': " + reason + ". 'tirstrain cameras' lists the cameras that can be seen",
                  {.file = uri_});
    }
    try {
      // The heartbeat thread notices a vanished camera before our next register access would.
      control_lost_handler_ = g_signal_connect(arv_camera_get_device(camera_), "control-lost",
                                               G_CALLBACK(&AravisSource::on_control_lost), this);
      apply_settings();
      read_back();
      start_stream();
    } catch (...) {
      release();
      throw;
    }
  }

  ~AravisSource() override { release(); }

  AravisSource(const AravisSource&) = delete;
  AravisSource& operator=(const AravisSource&) = delete;

  std::optional<Frame> next() override { return next_by_polling(*this); }

  Poll poll(Frame& frame, double timeout_s) override {
    if (trigger_ == TriggerMode::kSoftware && auto_trigger_ && !trigger_pending_) fire_software_trigger();
    const auto timeout_us = static_cast<guint64>(std::max(0.0, timeout_s) * 1e6);
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream_, timeout_us);
    if (buffer == nullptr) {
      check_stalled();
      return Poll::kTimeout;
    }
    convert(buffer, frame);
    arv_stream_push_buffer(stream_, buffer);
    trigger_pending_ = false;
    last_frame_steady_s_ = steady_now_s();
    return Poll::kFrame;
  }

  bool is_live() const override { return true; }

  std::string describe() const override {
    std::ostringstream out;
    out << "Aravis camera " << readback_.at("vendor") << " " << readback_.at("model") << " (serial "
        << readback_.at("serial") << ", " << uri_ << "): " << readback_.at("width_px") << "x"
        << readback_.at("height_px") << " " << readback_.at("pixel_format") << ", trigger "
        << readback_.at("trigger");
    return out.str();
  }

  std::map<std::string, std::string> settings() const override {
    std::map<std::string, std::string> out = readback_;
    for (const auto& [name, value] : statistics()) out["stream_" + name] = std::to_string(value);
    const int priority = stream_priority_.load();
    out["stream_thread_priority"] = priority == 1   ? "nice -10"
                                    : priority == 0 ? "normal (no permission to raise it)"
                                                    : "not started";
    return out;
  }

  std::map<std::string, std::int64_t> statistics() const {
    guint64 completed = 0, failures = 0, underruns = 0;
    if (stream_ != nullptr) arv_stream_get_statistics(stream_, &completed, &failures, &underruns);
    return {{"completed_buffers", static_cast<std::int64_t>(completed)},
            {"failures", static_cast<std::int64_t>(failures)},
            {"underruns", static_cast<std::int64_t>(underruns)},
            {"frames_delivered", index_},
            {"frames_incomplete", incomplete_},
            {"frames_lost", lost_}};
  }

  void software_trigger() {
    if (trigger_ != TriggerMode::kSoftware)
      throw Error("software trigger requested, but the source was not opened with trigger 'software'",
                  {.file = uri_, .key = requested_.key("--trigger")});
    fire_software_trigger();
  }

  void set_auto_trigger(bool enabled) { auto_trigger_ = enabled; }

 private:
  static void on_control_lost(ArvDevice*, gpointer self) {
    static_cast<AravisSource*>(self)->control_lost_.store(true);
  }

  // Runs on Aravis' stream thread. The thread that reassembles packets must not wait behind writers,
  // analysis or other programs: when it does, Aravis' packet ring or socket overflows and frames arrive
  // incomplete. Best effort: nice -10 (needs CAP_SYS_NICE; not real-time, which on a 2-core machine starves
  // the threads that give the buffers back); the outcome is in settings() ("stream_thread_priority").
  static void on_stream_event(void* self, ArvStreamCallbackType type, ArvBuffer*) {
    if (type != ARV_STREAM_CALLBACK_TYPE_INIT) return;
    const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
    const bool raised = ::setpriority(PRIO_PROCESS, tid, -10) == 0;
    static_cast<AravisSource*>(self)->stream_priority_.store(raised ? 1 : 0);
  }

  void release() {
    if (camera_ != nullptr && control_lost_handler_ != 0)
      g_signal_handler_disconnect(arv_camera_get_device(camera_), control_lost_handler_);
    control_lost_handler_ = 0;
    if (camera_ != nullptr && acquiring_ && !control_lost_.load()) {
      GError* error = nullptr;
      arv_camera_stop_acquisition(camera_, &error);
      g_clear_error(&error);
    }
    acquiring_ = false;
    if (stream_ != nullptr) g_object_unref(stream_);
    stream_ = nullptr;
    if (camera_ != nullptr) g_object_unref(camera_);
    camera_ = nullptr;
  }

  std::string range_text(double lo, double hi) const {
    return "[" + format_double(lo) + ", " + format_double(hi) + "]";
  }

  void apply_settings() {
    const CameraSettings& s = requested_;
    apply_pixel_format(s.pixel_format);
    if (s.roi_px) apply_roi(*s.roi_px);
    if (s.exposure_us)
      apply_bounded(
          {"--exposure-us", "exposure time", "exposure", " us", "", arv_camera_is_exposure_time_available,
           arv_camera_get_exposure_time_bounds, arv_camera_set_exposure_time},
          *s.exposure_us);
    if (s.gain_dB)
      apply_bounded({"--gain-dB", "gain", "gain", "", "", arv_camera_is_gain_available,
                     arv_camera_get_gain_bounds, arv_camera_set_gain},
                    *s.gain_dB);
    if (s.frame_rate_hz)
      apply_bounded(
          {"--fps", "frame rate", "frame rate", " Hz", " (at the current exposure and ROI)",
           arv_camera_is_frame_rate_available, arv_camera_get_frame_rate_bounds, arv_camera_set_frame_rate},
          *s.frame_rate_hz);
    // After the frame rate: Aravis' arv_camera_set_frame_rate() switches triggers off.
    apply_trigger(s.trigger);
    if (arv_camera_is_gv_device(camera_)) apply_packet_size(s.packet_size_bytes);
  }

  // The requested pixel format (when one is), then a check that the camera's format is one this reader
  // unpacks.
  void apply_pixel_format(const std::string& requested) {
    GError* error = nullptr;
    if (!requested.empty()) {
      // Checked before anything is written: a refused format must not stay on the device for later runs.
      if (!is_supported_format(requested))
        throw Error(
            "pixel format '" + requested + "' is not supported (supported: " + kSupportedFormats + ")",
            {.file = uri_, .key = requested_.key("--pixel-format")});
      guint n = 0;
      const char** formats = arv_camera_dup_available_pixel_formats_as_strings(camera_, &n, &error);
      const std::vector<std::string> offered = take_strings(formats, n);
      throw_if(error, "cannot list the camera's pixel formats",
               {.file = uri_, .key = requested_.key("--pixel-format")});
      if (std::find(offered.begin(), offered.end(), requested) == offered.end())
        throw Error(
            "pixel format '" + requested + "' is not offered by this camera; it offers: " + join(offered),
            {.file = uri_, .key = requested_.key("--pixel-format")});
      arv_camera_set_pixel_format_from_string(camera_, requested.c_str(), &error);
      throw_if(error, "cannot set pixel format '" + requested + "'",
               {.file = uri_, .key = requested_.key("--pixel-format")});
    }
    const ArvPixelFormat format = arv_camera_get_pixel_format(camera_, &error);
    throw_if(error, "cannot read the pixel format", {.file = uri_});
    const char* format_name = arv_camera_get_pixel_format_as_string(camera_, &error);
    g_clear_error(&error);
    const std::string name = format_name != nullptr ? format_name : std::to_string(format);
    if (!layout_of(format))
      throw Error("the camera's current pixel format '" + name + "' is not supported (supported: " +
                      kSupportedFormats + "); choose one with --pixel-format",
                  {.file = uri_});
  }

  // A camera control with a range (exposure, gain, frame rate): there, the value within the camera's own
  // range, set; each refusal names the flag.
  struct BoundedControl {
    const char* flag;
    const char* control;  // "this camera has no <control> control"
    const char* name;     // in the other messages
    const char* unit;
    const char* range_note;
    gboolean (*available)(ArvCamera*, GError**);
    void (*bounds)(ArvCamera*, double*, double*, GError**);
    void (*set)(ArvCamera*, double, GError**);
  };
  void apply_bounded(const BoundedControl& c, double value) {
    GError* error = nullptr;
    const ErrorContext where{.file = uri_, .key = requested_.key(c.flag)};
    if (!c.available(camera_, &error))
      throw Error(std::string("this camera has no ") + c.control + " control", where);
    double lo = 0, hi = 0;
    c.bounds(camera_, &lo, &hi, &error);
    throw_if(error, std::string("cannot read ") + c.name + " bounds", where);
    if (!(value >= lo && value <= hi))
      throw Error(std::string(c.name) + " " + format_double(value) + c.unit +
                      " is outside this camera's range " + range_text(lo, hi) + c.unit + c.range_note,
                  where);
    c.set(camera_, value, &error);
    throw_if(error, std::string("cannot set ") + c.name, where);
  }

  // GigE Vision: the requested packet size within the camera's range, or the largest the path carries.
  void apply_packet_size(const std::optional<int>& packet_size_bytes) {
    GError* error = nullptr;
    if (!packet_size_bytes) {
      // Larger packets mean fewer per frame; the negotiation tests what the path really carries.
      arv_camera_gv_auto_packet_size(camera_, &error);
      g_clear_error(&error);
      return;
    }
    gint64 lo = 0, hi = 0;
    arv_camera_get_integer_bounds(camera_, "GevSCPSPacketSize", &lo, &hi, &error);
    throw_if(error, "cannot read packet size bounds", {.file = uri_, .key = requested_.key("--packet-size")});
    if (*packet_size_bytes < lo || *packet_size_bytes > hi)
      throw Error("packet size " + std::to_string(*packet_size_bytes) +
                      " B is outside this camera's range [" + std::to_string(lo) + ", " + std::to_string(hi) +
                      "] B",
                  {.file = uri_, .key = requested_.key("--packet-size")});
    arv_camera_gv_set_packet_size(camera_, *packet_size_bytes, &error);
    throw_if(error, "cannot set packet size", {.file = uri_, .key = requested_.key("--packet-size")});
  }

  void apply_roi(const cv::Rect& roi) {
    GError* error = nullptr;
    gint wmin = 0, wmax = 0, hmin = 0, hmax = 0;
    arv_camera_get_width_bounds(camera_, &wmin, &wmax, &error);
    throw_if(error, "cannot read width bounds", {.file = uri_, .key = requested_.key("--roi")});
    arv_camera_get_height_bounds(camera_, &hmin, &hmax, &error);
    throw_if(error, "cannot read height bounds", {.file = uri_, .key = requested_.key("--roi")});
    gint64 sensor_w = 0, sensor_h = 0;
    sensor_w = arv_camera_get_integer(camera_, "SensorWidth", &error);
    if (error != nullptr) {
      g_clear_error(&error);
      sensor_w = wmax;
    }
    sensor_h = arv_camera_get_integer(camera_, "SensorHeight", &error);
    if (error != nullptr) {
      g_clear_error(&error);
      sensor_h = hmax;
    }
    const gint winc = std::max(1, arv_camera_get_width_increment(camera_, &error));
    g_clear_error(&error);
    const gint hinc = std::max(1, arv_camera_get_height_increment(camera_, &error));
    g_clear_error(&error);
    const std::string text = std::to_string(roi.x) + "," + std::to_string(roi.y) + "," +
                             std::to_string(roi.width) + "," + std::to_string(roi.height);
    if (roi.x < 0 || roi.y < 0 || roi.width < wmin || roi.height < hmin || roi.x + roi.width > sensor_w ||
        roi.y + roi.height > sensor_h)
      throw Error("ROI " + text + " (x,y,width,height) does not fit the sensor: " + std::to_string(sensor_w) +
                      "x" + std::to_string(sensor_h) + " px, width >= " + std::to_string(wmin) +
                      ", height >= " + std::to_string(hmin),
                  {.file = uri_, .key = requested_.key("--roi")});
    if (roi.width % winc != 0 || roi.height % hinc != 0)
      throw Error("ROI " + text + ": width must be a multiple of " + std::to_string(winc) +
                      " and height of " + std::to_string(hinc) + " on this camera",
                  {.file = uri_, .key = requested_.key("--roi")});
    arv_camera_set_region(camera_, roi.x, roi.y, roi.width, roi.height, &error);
    throw_if(error, "cannot set ROI " + text, {.file = uri_, .key = requested_.key("--roi")});
    gint x = 0, y = 0, w = 0, h = 0;
    arv_camera_get_region(camera_, &x, &y, &w, &h, &error);
    throw_if(error, "cannot read the ROI back", {.file = uri_, .key = requested_.key("--roi")});
    if (x != roi.x || y != roi.y || w != roi.width || h != roi.height)
      throw Error("ROI " + text + " was not applied as asked: the camera reports " + std::to_string(x) + "," +
                      std::to_string(y) + "," + std::to_string(w) + "," + std::to_string(h),
                  {.file = uri_, .key = requested_.key("--roi")});
  }

  void apply_trigger(const std::string& trigger) {
    GError* error = nullptr;
    if (trigger.empty()) {
      // Left as the device has it; learn which mode that is so next() behaves accordingly.
      const char* mode = arv_camera_get_string(camera_, "TriggerMode", &error);
      const bool on = error == nullptr && mode != nullptr && std::string(mode) == "On";
      g_clear_error(&error);
      if (!on) {
        trigger_ = TriggerMode::kFreeRun;
        return;
      }
      const char* source = arv_camera_get_trigger_source(camera_, &error);
      const std::string name = error == nullptr && source != nullptr ? source : "";
      g_clear_error(&error);
      trigger_ = name == "Software" ? TriggerMode::kSoftware : TriggerMode::kHardware;
      return;
    }
    if (trigger == "free-run") {
      arv_camera_clear_triggers(camera_, &error);
      throw_if(error, "cannot switch triggers off", {.file = uri_, .key = requested_.key("--trigger")});
      trigger_ = TriggerMode::kFreeRun;
      return;
    }
    if (trigger == "software") {
      const bool supported = arv_camera_is_software_trigger_supported(camera_, &error);
      g_clear_error(&error);
      if (!supported)
        throw Error("this camera has no software trigger",
                    {.file = uri_, .key = requested_.key("--trigger")});
      arv_camera_set_trigger(camera_, "Software", &error);
      throw_if(error, "cannot select the software trigger",
               {.file = uri_, .key = requested_.key("--trigger")});
      trigger_ = TriggerMode::kSoftware;
      return;
    }
    guint n = 0;
    const char** names = arv_camera_dup_available_trigger_sources(camera_, &n, &error);
    const std::vector<std::string> sources = take_strings(names, n);
    throw_if(error, "cannot list trigger sources", {.file = uri_, .key = requested_.key("--trigger")});
    if (std::find(sources.begin(), sources.end(), trigger) == sources.end())
      throw Error(
          "trigger '" + trigger + "' is not available; use free-run, software or one of: " + join(sources),
          {.file = uri_, .key = requested_.key("--trigger")});
    arv_camera_set_trigger(camera_, trigger.c_str(), &error);
    throw_if(error, "cannot select trigger '" + trigger + "'",
             {.file = uri_, .key = requested_.key("--trigger")});
    trigger_ = TriggerMode::kHardware;
  }

  // Every setting as the device reports it after configuration: this is what goes into the recording.
  void read_back() {
    GError* error = nullptr;
    auto text = [&](const char* value) {
      std::string out = error == nullptr && value != nullptr ? value : "";
      g_clear_error(&error);
      return out;
    };
    readback_["uri"] = uri_;
    readback_["kind"] = "aravis";
    readback_["vendor"] = text(arv_camera_get_vendor_name(camera_, &error));
    readback_["model"] = text(arv_camera_get_model_name(camera_, &error));
    readback_["serial"] = text(arv_camera_get_device_serial_number(camera_, &error));
    readback_["device_id"] = text(arv_camera_get_device_id(camera_, &error));
    format_ = arv_camera_get_pixel_format(camera_, &error);
    throw_if(error, "cannot read the pixel format", {.file = uri_});
    readback_["pixel_format"] = text(arv_camera_get_pixel_format_as_string(camera_, &error));
    layout_ = *layout_of(format_);
    gint x = 0, y = 0, w = 0, h = 0;
    arv_camera_get_region(camera_, &x, &y, &w, &h, &error);
    throw_if(error, "cannot read the image size", {.file = uri_});
    width_px_ = w;
    height_px_ = h;
    readback_["offset_x_px"] = std::to_string(x);
    readback_["offset_y_px"] = std::to_string(y);
    readback_["width_px"] = std::to_string(w);
    readback_["height_px"] = std::to_string(h);
    readback_["converted_to_grey"] = layout_.bayer_to_grey >= 0 ? "true (Bayer)" : "false";
    if (arv_camera_is_exposure_time_available(camera_, &error) && error == nullptr) {
      readback_["exposure_us"] = format_double(arv_camera_get_exposure_time(camera_, &error));
      g_clear_error(&error);
    }
    g_clear_error(&error);
    if (arv_camera_is_gain_available(camera_, &error) && error == nullptr) {
      readback_["gain_dB"] = format_double(arv_camera_get_gain(camera_, &error));
      g_clear_error(&error);
    }
    g_clear_error(&error);
    if (arv_camera_is_frame_rate_available(camera_, &error) && error == nullptr) {
      frame_rate_hz_ = arv_camera_get_frame_rate(camera_, &error);
      if (error == nullptr) readback_["frame_rate_hz"] = format_double(frame_rate_hz_);
      g_clear_error(&error);
    }
    g_clear_error(&error);
    const TriggerMode requested_trigger = trigger_;
    apply_trigger("");  // what the device really does now, not what was asked
    if (trigger_ != requested_trigger)
      throw Error("the trigger mode did not stick: the camera reports a different mode after configuration",
                  {.file = uri_, .key = requested_.key("--trigger")});
    readback_["trigger"] = trigger_ == TriggerMode::kFreeRun    ? "free-run"
                           : trigger_ == TriggerMode::kSoftware ? "software"
                                                                : "hardware";
    if (trigger_ == TriggerMode::kHardware)
      readback_["trigger_source"] = text(arv_camera_get_trigger_source(camera_, &error));
    if (arv_camera_is_gv_device(camera_)) {
      readback_["packet_size_bytes"] = std::to_string(arv_camera_gv_get_packet_size(camera_, &error));
      g_clear_error(&error);
    }
    is_gv_ = arv_camera_is_gv_device(camera_);
    payload_bytes_ = arv_camera_get_payload(camera_, &error);
    throw_if(error, "cannot read the payload size", {.file = uri_});
    readback_["payload_bytes"] = std::to_string(payload_bytes_);
    readback_["device_timestamp"] = "camera clock (GigE Vision timestamp), seconds";
  }

  void start_stream() {
    GError* error = nullptr;
    stream_ = arv_camera_create_stream(camera_, &AravisSource::on_stream_event, this, &error);
    if (stream_ == nullptr || error != nullptr) {
      const std::string reason = error != nullptr ? error->message : "unknown reason";
      g_clear_error(&error);
      throw Error("cannot open the camera's image stream: " + reason, {.file = uri_});
    }
    if (ARV_IS_GV_STREAM(stream_)) {
      // A socket buffer of at least one frame keeps the kernel from dropping packets during a scheduling
      // hiccup.
      g_object_set(stream_, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
    }
    int count = requested_.buffer_count;
    if (count <= 0) {
      // About 128 MiB of buffers: ~0.2 s at 500 fps full frame, more for small frames.
      constexpr double kBufferBudgetBytes = 128.0 * 1024 * 1024;
      count = static_cast<int>(
          std::clamp(kBufferBudgetBytes / std::max<double>(payload_bytes_, 1.0), 8.0, 256.0));
    }
    readback_["stream_buffers"] = std::to_string(count);
    for (int i = 0; i < count; ++i) arv_stream_push_buffer(stream_, arv_buffer_new_allocate(payload_bytes_));
    arv_camera_start_acquisition(camera_, &error);
    throw_if(error, "cannot start acquisition", {.file = uri_});
    acquiring_ = true;
    const double period_s = frame_rate_hz_ > 0 ? 1.0 / frame_rate_hz_ : 0.1;
    frame_timeout_s_ =
        requested_.frame_timeout_s > 0 ? requested_.frame_timeout_s : std::max(2.0, 20 * period_s);
    last_frame_steady_s_ = steady_now_s();
    started_steady_s_ = last_frame_steady_s_;
  }

  void fire_software_trigger() {
    GError* error = nullptr;
    arv_camera_software_trigger(camera_, &error);
    throw_if(error, "software trigger failed", {.file = uri_, .frame = index_});
    trigger_pending_ = true;
    last_frame_steady_s_ = steady_now_s();
  }

  // Called when no frame came within the poll timeout. Waiting on a hardware trigger may last forever; a
  // free-running or software-triggered camera that stays silent is either gone or cannot reach us.
  void check_stalled() {
    const double silent_s = steady_now_s() - last_frame_steady_s_;
    if (silent_s < frame_timeout_s_) return;
    const std::string after =
        index_ > 0 ? " after " + std::to_string(index_) + " frames" : std::string(" before the first frame");
    if (control_lost_.load())
      throw Error("lost contact with the camera" + after +
                      " (it stopped answering: unplugged, powered off or crashed)",
                  {.file = uri_, .frame = index_});
    GError* error = nullptr;
    arv_camera_get_integer(camera_, "Width", &error);
    if (error != nullptr) {
      const std::string reason = error->message;
      g_clear_error(&error);
      control_lost_.store(true);
      throw Error(
          "lost contact with the camera" + after + ": " + reason + " (unplugged, powered off or crashed)",
          {.file = uri_, .frame = index_});
    }
    if (trigger_ == TriggerMode::kHardware) {
      last_frame_steady_s_ = steady_now_s();  // alive and waiting for its trigger line: keep waiting
      return;
    }
    if (trigger_ == TriggerMode::kSoftware && !auto_trigger_) {
      last_frame_steady_s_ = steady_now_s();  // nothing was asked for
      return;
    }
    throw Error("the camera answers but sent no frame for " + format_double(std::round(silent_s * 10) / 10) +
                    " s" + after +
                    " (stream blocked by a firewall, wrong network interface, or acquisition stopped by "
                    "another program)",
                {.file = uri_, .frame = index_});
  }

  void convert(ArvBuffer* buffer, Frame& frame) {
    frame = Frame{};
    frame.index = index_++;
    frame.origin = uri_;
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    const bool complete = status == ARV_BUFFER_STATUS_SUCCESS;

    // GigE Vision block id 0 means "no id": Aravis hands over a frame whose leader packet never came with id
    // 0 (and no timestamp). Such a frame is incomplete and cannot be placed in the sequence; it was received,
    // so the gap it sits in counts one frame fewer as lost.
    // An incomplete buffer whose leader never came may also keep the id and timestamp of its previous
    // use (Aravis reuses buffers): an incomplete frame's id that does not advance is not trusted either,
    // or it would repeat an earlier frame's index and add a false gap after it.
    const guint64 raw_id = arv_buffer_get_frame_id(buffer);
    const bool stale_id =
        !complete && is_gv_ && have_last_id_ && raw_id != 0 && frame_ids_.peek(raw_id) <= last_id_;
    if ((raw_id == 0 && is_gv_) || stale_id) {
      frame.device_frame_id = -1;
      ++unidentified_since_last_;
    } else {
      const std::int64_t id = frame_ids_.unwrap(raw_id);
      if (have_last_id_ && id > last_id_ + 1) {
        frame.frames_lost_before = std::max<std::int64_t>(0, id - last_id_ - 1 - unidentified_since_last_);
        lost_ += frame.frames_lost_before;
      } else if (have_last_id_ && id < last_id_ && id > first_id_) {
        // Delivered late, out of order: it was counted as lost when a newer frame came first. -1 takes it
        // back out of the count, so sums of frames_lost_before stay the number of frames never received.
        frame.frames_lost_before = -1;
        --lost_;
      }
      if (id > last_id_ || !have_last_id_) unidentified_since_last_ = 0;
      if (!have_last_id_) first_id_ = id;
      have_last_id_ = true;
      last_id_ = std::max(last_id_, id);
      frame.device_frame_id = id;
    }

    const guint64 device_ns = arv_buffer_get_timestamp(buffer);
    const guint64 system_ns = arv_buffer_get_system_timestamp(buffer);
    // The system timestamp is the host's wall clock when the frame started arriving; express it on the
    // steady clock that Frame::host_time_s uses.
    const double steady_s = steady_now_s();
    frame.host_time_s =
        system_ns > 0 ? steady_s - (realtime_now_s() - static_cast<double>(system_ns) * 1e-9) : steady_s;
    frame.device_time_s = device_ns > 0 && frame.device_frame_id >= 0 ? static_cast<double>(device_ns) * 1e-9
                                                                      : frame.host_time_s;

    cv::Mat raw(height_px_, width_px_, CV_MAKETYPE(layout_.cv_depth, 1));
    std::size_t size = 0;
    const void* data = arv_buffer_get_data(buffer, &size);
    const std::size_t expected = raw.total() * raw.elemSize();
    if (data != nullptr && size > 0) {
      std::memcpy(raw.data, data, std::min(size, expected));
      if (size < expected) std::memset(raw.data + size, 0, expected - size);
    } else {
      raw.setTo(0);
    }
    if (layout_.bayer_to_grey >= 0) {
      cv::cvtColor(raw, frame.image, layout_.bayer_to_grey);
    } else {
      frame.image = raw;
    }

    if (!complete || size < expected || frame.device_frame_id < 0) {
      frame.status = FrameStatus::kIncomplete;
      ++incomplete_;
    } else if (frame.frames_lost_before > 0) {
      guint64 completed = 0, failures = 0, underruns = 0;
      arv_stream_get_statistics(stream_, &completed, &failures, &underruns);
      frame.status = underruns > last_underruns_ ? FrameStatus::kOverrun : FrameStatus::kGapBefore;
      last_underruns_ = underruns;
    }
  }

  std::string uri_;
  CameraSettings requested_;
  ArvCamera* camera_ = nullptr;
  ArvStream* stream_ = nullptr;
  gulong control_lost_handler_ = 0;
  std::atomic<bool> control_lost_{false};
  std::atomic<int> stream_priority_{-1};
  bool acquiring_ = false;
  std::map<std::string, std::string> readback_;
  ArvPixelFormat format_ = 0;
  PixelLayout layout_;
  int width_px_ = 0;
  int height_px_ = 0;
  std::size_t payload_bytes_ = 0;
  double frame_rate_hz_ = 0.0;
  TriggerMode trigger_ = TriggerMode::kFreeRun;
  bool auto_trigger_ = true;
  bool trigger_pending_ = false;
  double frame_timeout_s_ = 2.0;
  double last_frame_steady_s_ = 0.0;
  double started_steady_s_ = 0.0;
  FrameIdUnwrapper frame_ids_;
  bool have_last_id_ = false;
  std::int64_t first_id_ = 0;
  std::int64_t unidentified_since_last_ = 0;
  bool is_gv_ = false;
  std::int64_t last_id_ = 0;
  guint64 last_underruns_ = 0;
  std::int64_t index_ = 0;
  std::int64_t incomplete_ = 0;
  std::int64_t lost_ = 0;
};

AravisSource& as_aravis(FrameSource& source) {
  auto* aravis = dynamic_cast<AravisSource*>(&source);
  if (aravis == nullptr)
    throw Error("this operation needs an Aravis camera source", {.file = source.describe()});
  return *aravis;
}

}  // namespace

std::vector<CameraInfo> list_aravis_cameras() {
  arv_update_device_list();
  std::vector<CameraInfo> cameras;
  const unsigned n = arv_get_n_devices();
  auto text = [](const char* value) { return std::string(value != nullptr ? value : ""); };
  for (unsigned i = 0; i < n; ++i) {
    CameraInfo info;
    info.backend = "aravis";
    info.uri = "aravis:" + text(arv_get_device_id(i));
    info.model = text(arv_get_device_vendor(i)) + " " + text(arv_get_device_model(i));
    info.serial = text(arv_get_device_serial_nbr(i));
    info.address = text(arv_get_device_address(i));
    info.protocol = text(arv_get_device_protocol(i));
    cameras.push_back(std::move(info));
  }
  return cameras;
}

std::unique_ptr<FrameSource> open_aravis_source(const std::string& id, const CameraSettings& settings) {
  return std::make_unique<AravisSource>(id, settings);
}

void software_trigger(FrameSource& source) {
  as_aravis(source).software_trigger();
}

void set_auto_software_trigger(FrameSource& source, bool enabled) {
  as_aravis(source).set_auto_trigger(enabled);
}

std::map<std::string, std::int64_t> aravis_stream_statistics(const FrameSource& source) {
  return as_aravis(const_cast<FrameSource&>(source)).statistics();
}

// Camera settings reach the camera backends; for every other URI they would silently do nothing.
std::unique_ptr<FrameSource> open_source(const std::string& uri, const CameraSettings& settings) {
  return open_source(uri, settings, FileSourceOptions{});
}

std::unique_ptr<FrameSource> open_source(const std::string& uri, const CameraSettings& settings,
                                         const FileSourceOptions& file_options) {
  const auto colon = uri.find(':');
  if (colon != std::string::npos && colon > 1 && uri.find('/') > colon) {
    const std::string scheme = uri.substr(0, colon);
    if (file_options.frame_rate_Hz && scheme != "file") return open_source(uri, file_options);  // refuses it
    if (scheme == "aravis") return open_aravis_source(uri.substr(colon + 1), settings);
    if (scheme == "v4l2") return open_v4l2_source(uri.substr(colon + 1), settings);
    if (scheme == "libcamera") return open_libcamera_source(uri.substr(colon + 1), settings);
  }
  // A scene's camera: section describes the rig, and replaying a recording with that scene is normal; values
  // typed on the command line for a file would silently do nothing.
  if (!command_line_part(settings).empty())
    throw Error(
        "camera settings (pixel format, ROI, exposure, gain, frame rate, trigger) only apply to camera "
        "sources (aravis:<id>, v4l2:/dev/videoN, libcamera:<id>); this input is a file source",
        {.file = uri});
  return open_source(uri, file_options);
}

}  // namespace tirstrain::capture
