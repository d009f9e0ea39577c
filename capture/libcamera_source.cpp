// libcamera backend (see libcamera_source.hpp). libcamera's C++17 headers are confined to this file.
#include "capture/libcamera_source.hpp"

#include <sys/mman.h>

#include <libcamera/libcamera.h>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "capture/v4l2_source.hpp"  // SequenceGapCounter
#include "core/error.hpp"

namespace tirstrain::capture {
namespace {

namespace lc = libcamera;

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// One camera manager at a time may exist in a process (libcamera's rule); it also owns the threads that
// complete requests. Quiet unless something is wrong (LIBCAMERA_LOG_LEVELS still overrides).
std::unique_ptr<lc::CameraManager> start_manager(const std::string& uri) {
  // libcamera reads its log levels once, when its logger is first used.
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
  auto manager = std::make_unique<lc::CameraManager>();
  if (const int r = manager->start(); r < 0)
    throw Error("cannot start the libcamera camera manager: " + std::string(std::strerror(-r)),
                {.file = uri});
  return manager;
}

std::string model_of(const lc::Camera& camera) {
  const auto model = camera.properties().get(lc::properties::Model);
  return model ? *model : std::string();
}

struct Layout {
  lc::PixelFormat format;
  int cv_type;
  int conversion;  // cv::COLOR_* or -1 for a straight copy
  int channels;
  int bytes_per_channel;
};

// libcamera formats follow DRM naming: RGB888 is stored B, G, R in memory.
std::optional<Layout> layout_of(const lc::PixelFormat& format) {
  if (format == lc::formats::R8) return Layout{format, CV_8UC1, -1, 1, 1};
  if (format == lc::formats::RGB888) return Layout{format, CV_8UC3, cv::COLOR_BGR2GRAY, 3, 1};
  if (format == lc::formats::BGR888) return Layout{format, CV_8UC3, cv::COLOR_RGB2GRAY, 3, 1};
  if (format == lc::formats::XRGB8888) return Layout{format, CV_8UC4, cv::COLOR_BGRA2GRAY, 4, 1};
  if (format == lc::formats::YUYV) return Layout{format, CV_8UC2, cv::COLOR_YUV2GRAY_YUYV, 2, 1};
  return std::nullopt;
}

std::optional<lc::PixelFormat> format_from_name(const std::string& name) {
  if (name == "GREY" || name == "Mono8" || name == "R8") return lc::formats::R8;
  if (name == "RGB888") return lc::formats::RGB888;
  if (name == "BGR888") return lc::formats::BGR888;
  if (name == "XRGB8888") return lc::formats::XRGB8888;
  if (name == "YUYV") return lc::formats::YUYV;
  return std::nullopt;
}

class LibcameraSource final : public FrameSource {
 public:
  LibcameraSource(const std::string& id, const CameraSettings& requested)
      : uri_("libcamera:" + id), requested_(requested) {
    manager_ = start_manager(uri_);
    try {
      select_camera(id);
      configure();
      start();
    } catch (...) {
      release();
      throw;
    }
  }

  ~LibcameraSource() override { release(); }
  LibcameraSource(const LibcameraSource&) = delete;
  LibcameraSource& operator=(const LibcameraSource&) = delete;

  std::optional<Frame> next() override { return next_by_polling(*this); }

  Poll poll(Frame& frame, double timeout_s) override {
    lc::Request* request = nullptr;
    {
      std::unique_lock lock(mutex_);
      completed_cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, timeout_s)),
                             [this] { return !completed_.empty() || disconnected_; });
      if (disconnected_)
        throw Error(
            "the libcamera camera '" + camera_->id() + "' went away after " + std::to_string(index_) +
                " frames (unplugged, or its driver was unbound); every frame before this was delivered",
            {.file = uri_});
      if (completed_.empty()) {
        check_stalled();
        return Poll::kTimeout;
      }
      request = completed_.front();
      completed_.pop_front();
    }
    convert(*request, frame);
    request->reuse(lc::Request::ReuseBuffers);
    if (const int r = camera_->queueRequest(request); r < 0)
      throw Error("cannot queue a capture request: " + std::string(std::strerror(-r)), {.file = uri_});
    last_frame_steady_s_ = steady_now_s();
    return Poll::kFrame;
  }

  bool is_live() const override { return true; }

  std::string describe() const override {
    std::ostringstream out;
    out << "libcamera camera " << readback_.at("model") << " (" << readback_.at("camera_id")
        << "): " << readback_.at("width_px") << "x" << readback_.at("height_px") << " "
        << readback_.at("pixel_format");
    return out.str();
  }

  std::map<std::string, std::string> settings() const override {
    std::map<std::string, std::string> out = readback_;
    out["frames_delivered"] = std::to_string(index_);
    out["frames_incomplete"] = std::to_string(incomplete_);
    out["frames_lost"] = std::to_string(gaps_.lost());
    return out;
  }

 private:
  void select_camera(const std::string& id) {
    const auto cameras = manager_->cameras();
    std::string seen;
    for (const auto& c : cameras) seen += (seen.empty() ? "" : ", ") + ("'" + c->id() + "'");
    if (cameras.empty())
      throw Error("libcamera finds no camera (is the driver loaded, and udev running?)", {.file = uri_});
    if (id.empty()) {
      camera_ = cameras.front();
    } else if (auto exact = manager_->get(id)) {
      camera_ = exact;
    } else {
      for (const auto& c : cameras) {
        if (c->id().find(id) == std::string::npos && model_of(*c) != id) continue;
        if (camera_)
          throw Error("'" + id + "' matches more than one libcamera camera (" + seen + "); give the whole id",
                      {.file = uri_});
        camera_ = c;
      }
      if (!camera_)
        throw Error("no libcamera camera matches '" + id + "'; cameras found: " + seen, {.file = uri_});
    }
    if (camera_->acquire() < 0) {
      camera_.reset();
      throw Error("the libcamera camera is in use by another program", {.file = uri_});
    }
    acquired_ = true;
    readback_["camera_id"] = camera_->id();
    readback_["model"] = model_of(*camera_);
    camera_->disconnected.connect(this, &LibcameraSource::on_disconnected);
  }

  void configure() {
    config_ = camera_->generateConfiguration({lc::StreamRole::Viewfinder});
    if (!config_ || config_->empty())
      throw Error("libcamera cannot generate a configuration for this camera", {.file = uri_});
    lc::StreamConfiguration& stream_config = config_->at(0);
    std::string offered;
    for (const auto& f : stream_config.formats().pixelformats())
      if (layout_of(f)) offered += (offered.empty() ? "" : ", ") + f.toString();
    ask_for_requested(stream_config);
    validate_configuration(stream_config, offered);
    if (camera_->configure(config_.get()) < 0)
      throw Error("libcamera could not apply the stream configuration " + stream_config.toString(),
                  {.file = uri_});
    record_configuration(stream_config);
    check_controls();
  }

  // The requested pixel format (or one this backend reads), image size and buffer count.
  void ask_for_requested(lc::StreamConfiguration& stream_config) {
    if (!requested_.pixel_format.empty()) {
      const auto want = format_from_name(requested_.pixel_format);
      if (!want)
        throw Error("pixel format '" + requested_.pixel_format +
                        "' is not supported by the libcamera backend (choices: GREY or R8, RGB888, BGR888, "
                        "XRGB8888, YUYV)",
                    {.file = uri_, .key = requested_.key("--pixel-format")});
      stream_config.pixelFormat = *want;
    } else if (!layout_of(stream_config.pixelFormat)) {
      for (const auto& f : stream_config.formats().pixelformats())
        if (layout_of(f)) {
          stream_config.pixelFormat = f;
          break;
        }
    }
    if (requested_.roi_px) {
      if (requested_.roi_px->x != 0 || requested_.roi_px->y != 0)
        throw Error("the libcamera backend sets the image size only; the ROI offset must be 0,0",
                    {.file = uri_, .key = requested_.key("--roi")});
      stream_config.size = lc::Size(static_cast<unsigned>(requested_.roi_px->width),
                                    static_cast<unsigned>(requested_.roi_px->height));
    }
    if (requested_.buffer_count > 0)
      stream_config.bufferCount = static_cast<unsigned>(requested_.buffer_count);
  }

  // libcamera's validation may adjust what was asked: a rejected configuration, a format this backend cannot
  // read or another format than the one requested is an error; an adjusted size is recorded.
  void validate_configuration(lc::StreamConfiguration& stream_config, const std::string& offered) {
    const std::string format_key = requested_.key("--pixel-format");
    const lc::PixelFormat asked_format = stream_config.pixelFormat;
    const lc::Size asked_size = stream_config.size;
    if (config_->validate() == lc::CameraConfiguration::Invalid)
      throw Error("libcamera rejects the stream configuration " + asked_size.toString() + " " +
                      asked_format.toString(),
                  {.file = uri_, .key = requested_.key("--roi")});
    if (!layout_of(stream_config.pixelFormat))
      throw Error("the camera cannot deliver a pixel format this backend reads (it offers " +
                      (offered.empty() ? std::string("none of them") : offered) + ")",
                  {.file = uri_, .key = format_key});
    if (!requested_.pixel_format.empty() && stream_config.pixelFormat != asked_format)
      throw Error("asked for pixel format " + asked_format.toString() + ", the camera can only give " +
                      stream_config.pixelFormat.toString() + " (it offers " + offered + ")",
                  {.file = uri_, .key = format_key});
    if (stream_config.size != asked_size) {
      readback_["requested_size"] = asked_size.toString();
      readback_["size_adjusted"] = "true";
    }
  }

  // The stream as configured: what frames are unpacked from, and the read-back settings.
  void record_configuration(const lc::StreamConfiguration& stream_config) {
    stream_ = stream_config.stream();
    layout_ = *layout_of(stream_config.pixelFormat);
    width_ = static_cast<int>(stream_config.size.width);
    height_ = static_cast<int>(stream_config.size.height);
    stride_ = stream_config.stride;
    readback_["pixel_format"] = stream_config.pixelFormat.toString();
    readback_["width_px"] = std::to_string(width_);
    readback_["height_px"] = std::to_string(height_);
    readback_["bytes_per_line"] = std::to_string(stride_);
    readback_["converted_to"] =
        layout_.conversion < 0 ? "grey" : "grey (from " + stream_config.pixelFormat.toString() + ")";
  }

  // Controls go with each request: the camera must have those asked for before their values are accepted.
  // libcamera cameras run free (no trigger).
  void check_controls() {
    const auto& controls = camera_->controls();
    auto need = [&](const lc::ControlId& id, const std::string& option) {
      if (controls.find(&id) == controls.end())
        throw Error("the camera has no " + id.name() + " control",
                    {.file = uri_, .key = requested_.key(option)});
    };
    if (requested_.exposure_us) need(lc::controls::ExposureTime, "--exposure");
    if (requested_.gain_dB) need(lc::controls::AnalogueGain, "--gain");
    if (requested_.frame_rate_hz) need(lc::controls::FrameDurationLimits, "--fps");
    if (!requested_.trigger.empty() && requested_.trigger != "free-run")
      throw Error("libcamera cameras run free; trigger '" + requested_.trigger + "' is not available",
                  {.file = uri_, .key = requested_.key("--trigger")});
  }

  void start() {
    allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream_) < 0)
      throw Error("cannot allocate libcamera frame buffers", {.file = uri_});
    for (const auto& buffer : allocator_->buffers(stream_)) {
      auto request = camera_->createRequest(static_cast<std::uint64_t>(requests_.size()));
      if (!request || request->addBuffer(stream_, buffer.get()) < 0)
        throw Error("cannot create a libcamera capture request", {.file = uri_});
      // Map every plane once; planes of one buffer usually share a dmabuf at increasing offsets.
      const auto& plane = buffer->planes().front();
      const std::size_t length = plane.offset + plane.length;
      void* data = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      if (data == MAP_FAILED) throw Error("cannot map a libcamera frame buffer", {.file = uri_});
      mappings_[buffer.get()] = {static_cast<const std::uint8_t*>(data) + plane.offset, length, data};
      requests_.push_back(std::move(request));
    }
    readback_["buffer_count"] = std::to_string(requests_.size());
    lc::ControlList start_controls(lc::controls::controls);
    if (requested_.exposure_us) {
      start_controls.set(lc::controls::AeEnable, false);
      start_controls.set(lc::controls::ExposureTime,
                         static_cast<std::int32_t>(std::lround(*requested_.exposure_us)));
    }
    if (requested_.gain_dB)
      start_controls.set(lc::controls::AnalogueGain,
                         static_cast<float>(std::pow(10.0, *requested_.gain_dB / 20.0)));
    if (requested_.frame_rate_hz) {
      const auto us = static_cast<std::int64_t>(std::lround(1e6 / *requested_.frame_rate_hz));
      start_controls.set(lc::controls::FrameDurationLimits, lc::Span<const std::int64_t, 2>({us, us}));
    }
    camera_->requestCompleted.connect(this, &LibcameraSource::on_request_completed);
    if (const int r = camera_->start(&start_controls); r < 0)
      throw Error("cannot start the libcamera camera: " + std::string(std::strerror(-r)), {.file = uri_});
    started_ = true;
    for (auto& request : requests_)
      if (const int r = camera_->queueRequest(request.get()); r < 0)
        throw Error("cannot queue a capture request: " + std::string(std::strerror(-r)), {.file = uri_});
    last_frame_steady_s_ = steady_now_s();
  }

  // Runs on libcamera's pipeline thread.
  void on_request_completed(lc::Request* request) {
    if (request->status() == lc::Request::RequestCancelled) return;
    {
      std::lock_guard lock(mutex_);
      completed_.push_back(request);
    }
    completed_cv_.notify_one();
  }

  void on_disconnected() {
    {
      std::lock_guard lock(mutex_);
      disconnected_ = true;
    }
    completed_cv_.notify_one();
  }

  void convert(lc::Request& request, Frame& frame) {
    lc::FrameBuffer* buffer = request.findBuffer(stream_);
    const lc::FrameMetadata& meta = buffer->metadata();
    const auto& mapping = mappings_.at(buffer);
    const std::size_t row_bytes =
        static_cast<std::size_t>(width_) * layout_.channels * layout_.bytes_per_channel;
    const std::size_t needed =
        static_cast<std::size_t>(stride_) * static_cast<std::size_t>(height_ - 1) + row_bytes;
    const std::size_t used = meta.planes().empty() ? mapping.length : meta.planes()[0].bytesused;
    const bool incomplete = meta.status != lc::FrameMetadata::FrameSuccess || used < needed;
    if (mapping.length >= needed) {
      const cv::Mat raw(height_, width_, layout_.cv_type, const_cast<std::uint8_t*>(mapping.data), stride_);
      if (layout_.conversion < 0)
        raw.copyTo(frame.image);
      else
        cv::cvtColor(raw, frame.image, layout_.conversion);
    } else {
      frame.image = cv::Mat::zeros(height_, width_, CV_8UC1);
    }
    const SequenceGapCounter::Step step = gaps_.add(meta.sequence);
    frame.index = index_++;
    frame.device_frame_id = step.frame_id;
    frame.frames_lost_before = step.lost_before;
    frame.device_time_s = static_cast<double>(meta.timestamp) * 1e-9;
    frame.host_time_s = steady_now_s();
    frame.origin = uri_;
    if (incomplete) {
      frame.status = FrameStatus::kIncomplete;
      ++incomplete_;
    } else {
      frame.status = step.lost_before > 0 ? FrameStatus::kGapBefore : FrameStatus::kOk;
    }
  }

  void check_stalled() {
    const double timeout = requested_.frame_timeout_s > 0.0 ? requested_.frame_timeout_s : 5.0;
    const double waited = steady_now_s() - last_frame_steady_s_;
    if (waited < timeout) return;
    // libcamera 0.0.3 sends no `disconnected` signal when a driver is unbound, and Camera::stop() on such a
    // camera aborts the process (assertion "data->queuedRequests_.empty()", pipeline_handler.cpp:343). A
    // stalled camera may have gone, so it is abandoned instead of stopped (see release()).
    abandon_ = true;
    throw Error("no frame from the libcamera camera for " + std::to_string(static_cast<int>(waited)) +
                    " s after " + std::to_string(index_) + " frames",
                {.file = uri_, .key = requested_.key("--frame-timeout")});
  }

  // The objects a stalled camera needs kept alive, held by a pointer that is never freed: stopping or
  // destroying them could abort in libcamera (see check_stalled()).
  struct Abandoned {
    std::unique_ptr<lc::CameraManager> manager;
    std::shared_ptr<lc::Camera> camera;
    std::unique_ptr<lc::FrameBufferAllocator> allocator;
    std::vector<std::unique_ptr<lc::Request>> requests;
    std::unique_ptr<lc::CameraConfiguration> config;
  };
  static std::vector<Abandoned*>& abandoned() {
    static auto* list = new std::vector<Abandoned*>();
    return *list;
  }

  void release() {
    if (abandon_ && camera_) {
      camera_->requestCompleted.disconnect(this);
      camera_->disconnected.disconnect(this);
      abandoned().push_back(new Abandoned{std::move(manager_), std::move(camera_), std::move(allocator_),
                                          std::move(requests_), std::move(config_)});
      return;  // the buffers stay mapped: a late completion may still touch them
    }
    if (camera_) {
      if (started_) camera_->stop();  // completes every pending request as cancelled
      started_ = false;
      camera_->requestCompleted.disconnect(this);
      camera_->disconnected.disconnect(this);
    }
    {
      std::lock_guard lock(mutex_);
      completed_.clear();
    }
    requests_.clear();
    for (auto& [buffer, mapping] : mappings_) ::munmap(mapping.base, mapping.length);
    mappings_.clear();
    if (allocator_ && stream_ != nullptr) allocator_->free(stream_);
    allocator_.reset();
    config_.reset();
    if (camera_ && acquired_) camera_->release();
    acquired_ = false;
    camera_.reset();
    if (manager_) manager_->stop();
    manager_.reset();
  }

  struct Mapping {
    const std::uint8_t* data;
    std::size_t length;
    void* base;
  };

  std::string uri_;
  CameraSettings requested_;
  std::unique_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  bool acquired_ = false;
  bool started_ = false;
  std::unique_ptr<lc::CameraConfiguration> config_;
  lc::Stream* stream_ = nullptr;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  std::map<const lc::FrameBuffer*, Mapping> mappings_;
  Layout layout_{};
  int width_ = 0;
  int height_ = 0;
  unsigned stride_ = 0;

  std::mutex mutex_;
  std::condition_variable completed_cv_;
  std::deque<lc::Request*> completed_;
  bool disconnected_ = false;
  bool abandon_ = false;

  double last_frame_steady_s_ = 0.0;
  std::int64_t index_ = 0;
  std::int64_t incomplete_ = 0;
  SequenceGapCounter gaps_;
  std::map<std::string, std::string> readback_;
};

}  // namespace

std::vector<CameraInfo> list_libcamera_cameras() {
  auto manager = start_manager("libcamera:");
  std::vector<CameraInfo> out;
  for (const auto& camera : manager->cameras()) {
    CameraInfo info;
    info.backend = "libcamera";
    info.uri = "libcamera:" + camera->id();
    info.model = model_of(*camera);
    info.address = camera->id();
    out.push_back(std::move(info));
  }
  manager->stop();
  return out;
}

std::unique_ptr<FrameSource> open_libcamera_source(const std::string& id, const CameraSettings& settings) {
  return std::make_unique<LibcameraSource>(id, settings);
}

}  // namespace tirstrain::capture
