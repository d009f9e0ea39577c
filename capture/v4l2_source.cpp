// V4L2 capture backend: mmap streaming with the V4L2 ioctls directly (see v4l2_source.hpp).
#include "capture/v4l2_source.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "core/error.hpp"

namespace tirstrain::capture {

SequenceGapCounter::Step SequenceGapCounter::add(std::uint32_t sequence) {
  Step step;
  if (!have_last_) {
    have_last_ = true;
    step.frame_id = sequence;
  } else {
    // Signed 32-bit difference: forward jumps (with wrap) are positive, late frames negative.
    const auto delta = static_cast<std::int32_t>(sequence - last_raw_);
    step.frame_id = last_id_ + delta;
    if (delta > 1) step.lost_before = delta - 1;
    if (delta < 0) step.lost_before = -1;  // late: it had been counted as lost when a newer one came first
  }
  lost_ += step.lost_before;
  ++count_;
  if (step.frame_id >= last_id_ || count_ == 1) {
    last_id_ = step.frame_id;
    last_raw_ = sequence;
  }
  return step;
}

std::string v4l2_device_path(const std::string& uri_body) {
  if (uri_body.empty())
    throw Error("no V4L2 device given: use v4l2:/dev/videoN or v4l2:N ('tirstrain cameras' lists them)",
                {.file = "v4l2:"});
  if (std::all_of(uri_body.begin(), uri_body.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return "/dev/video" + uri_body;
  if (uri_body.front() != '/')
    throw Error("a V4L2 device is a device node path such as /dev/video0 or a number, not '" + uri_body + "'",
                {.file = "v4l2:" + uri_body});
  return uri_body;
}

std::uint32_t v4l2_fourcc_of(const std::string& name, const std::string& key) {
  if (name == "GREY" || name == "Mono8") return V4L2_PIX_FMT_GREY;
  if (name == "Y16" || name == "Mono16") return V4L2_PIX_FMT_Y16;
  if (name == "YUYV") return V4L2_PIX_FMT_YUYV;
  throw Error("pixel format '" + name +
                  "' is not supported by the V4L2 backend (choices: GREY or Mono8, Y16 or "
                  "Mono16, YUYV)",
              {.key = key});
}

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string out;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    if (c != ' ') out += (c >= 32 && c < 127) ? c : '?';
  }
  return out;
}

namespace {

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int xioctl(int fd, unsigned long request, void* arg) {
  int r = 0;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

std::string errno_text(int err) {
  return std::strerror(err);
}

bool is_supported(std::uint32_t fourcc) {
  return fourcc == V4L2_PIX_FMT_GREY || fourcc == V4L2_PIX_FMT_Y16 || fourcc == V4L2_PIX_FMT_YUYV;
}

std::string format_double(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str();
}

class V4l2Source final : public FrameSource {
 public:
  V4l2Source(const std::string& uri_body, const CameraSettings& requested)
      : device_(v4l2_device_path(uri_body)), uri_("v4l2:" + device_), requested_(requested) {
    fd_ = ::open(device_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      const int err = errno;
      std::string hint = ". 'tirstrain cameras --backend v4l2' lists the capture devices";
      if (err == ENOENT) hint = " (is the driver loaded and the camera plugged in?)" + hint;
      if (err == EACCES) hint = " (add the user to the 'video' group)";
      throw Error("cannot open V4L2 device " + device_ + ": " + errno_text(err) + hint, {.file = uri_});
    }
    try {
      check_capabilities();
      apply_format();
      apply_frame_rate();
      apply_exposure();
      reject_unsupported();
      start_stream();
    } catch (...) {
      release();
      throw;
    }
  }

  ~V4l2Source() override { release(); }
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  std::optional<Frame> next() override { return next_by_polling(*this); }

  Poll poll(Frame& frame, double timeout_s) override {
    pollfd pfd{fd_, POLLIN, 0};
    const int ms = static_cast<int>(std::ceil(std::max(0.0, timeout_s) * 1000.0));
    const int n = ::poll(&pfd, 1, ms);
    if (n < 0 && errno != EINTR) disconnected("poll failed: " + errno_text(errno));
    if (n <= 0) {
      check_stalled();
      return Poll::kTimeout;
    }
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    bool error_flag = false;
    if (xioctl(fd_, VIDIOC_DQBUF, &buf) < 0) {
      const int err = errno;
      if (err == EAGAIN) {
        if (pfd.revents & (POLLERR | POLLHUP)) disconnected("the device reported an error (POLLERR)");
        check_stalled();
        return Poll::kTimeout;
      }
      if (err == EIO && buf.index < buffers_.size()) {
        error_flag = true;  // older drivers report a failed buffer this way
      } else {
        disconnected("VIDIOC_DQBUF failed: " + errno_text(err));
      }
    }
    if (buf.flags & V4L2_BUF_FLAG_ERROR) error_flag = true;
    convert(buf, error_flag, frame);
    if (xioctl(fd_, VIDIOC_QBUF, &buf) < 0) disconnected("VIDIOC_QBUF failed: " + errno_text(errno));
    last_frame_steady_s_ = steady_now_s();
    return Poll::kFrame;
  }

  bool is_live() const override { return true; }

  std::string describe() const override {
    std::ostringstream out;
    out << "V4L2 device " << readback_.at("card") << " (" << readback_.at("driver") << ", " << uri_
        << "): " << width_ << "x" << height_ << " " << fourcc_to_string(fourcc_);
    if (readback_.count("frame_rate_hz") != 0) out << " at " << readback_.at("frame_rate_hz") << " Hz";
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
  void check_capabilities() {
    v4l2_capability caps{};
    if (xioctl(fd_, VIDIOC_QUERYCAP, &caps) < 0)
      throw Error(device_ + " is not a V4L2 device (VIDIOC_QUERYCAP: " + errno_text(errno) + ")",
                  {.file = uri_});
    const std::uint32_t device_caps =
        (caps.capabilities & V4L2_CAP_DEVICE_CAPS) ? caps.device_caps : caps.capabilities;
    readback_["driver"] = reinterpret_cast<const char*>(caps.driver);
    readback_["card"] = reinterpret_cast<const char*>(caps.card);
    readback_["bus_info"] = reinterpret_cast<const char*>(caps.bus_info);
    readback_["device"] = device_;
    if (!(device_caps & V4L2_CAP_VIDEO_CAPTURE))
      throw Error(device_ + " (" + readback_["card"] +
                      ") cannot capture video (it is an output, metadata or multi-planar node); "
                      "'tirstrain cameras --backend v4l2' lists the capture devices",
                  {.file = uri_});
    if (!(device_caps & V4L2_CAP_STREAMING))
      throw Error(device_ + " does not support streaming I/O, which this backend needs", {.file = uri_});
  }

  std::vector<std::uint32_t> enumerate_formats() {
    std::vector<std::uint32_t> formats;
    for (std::uint32_t i = 0;; ++i) {
      v4l2_fmtdesc desc{};
      desc.index = i;
      desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (xioctl(fd_, VIDIOC_ENUM_FMT, &desc) < 0) break;
      formats.push_back(desc.pixelformat);
    }
    return formats;
  }

  void apply_format() {
    const std::vector<std::uint32_t> formats = enumerate_formats();
    std::string offered;
    for (auto f : formats) offered += (offered.empty() ? "" : ", ") + fourcc_to_string(f);
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_G_FMT, &fmt) < 0)
      throw Error("VIDIOC_G_FMT failed: " + errno_text(errno), {.file = uri_});
    std::uint32_t want = fmt.fmt.pix.pixelformat;
    const std::string format_key = requested_.key("--pixel-format");
    if (!requested_.pixel_format.empty()) {
      want = v4l2_fourcc_of(requested_.pixel_format, format_key);
      if (std::find(formats.begin(), formats.end(), want) == formats.end())
        throw Error("the device does not offer pixel format " + fourcc_to_string(want) + " (it offers " +
                        offered + ")",
                    {.file = uri_, .key = format_key});
    } else if (!is_supported(want)) {
      // The device's current format cannot become grey: take the first usable one it offers, best first.
      want = 0;
      for (std::uint32_t preferred : {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_YUYV})
        if (want == 0 && std::find(formats.begin(), formats.end(), preferred) != formats.end())
          want = preferred;
      if (want == 0)
        throw Error(
            "the device offers none of the pixel formats this backend reads (GREY, Y16, YUYV); it offers " +
                offered,
            {.file = uri_});
    }
    fmt.fmt.pix.pixelformat = want;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    const std::string roi_key = requested_.key("--roi");
    if (requested_.roi_px) {
      const cv::Rect& roi = *requested_.roi_px;
      if (roi.x != 0 || roi.y != 0)
        throw Error("the V4L2 backend sets the image size only; the ROI offset must be 0,0 (got " +
                        std::to_string(roi.x) + "," + std::to_string(roi.y) + ")",
                    {.file = uri_, .key = roi_key});
      fmt.fmt.pix.width = static_cast<std::uint32_t>(roi.width);
      fmt.fmt.pix.height = static_cast<std::uint32_t>(roi.height);
    }
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) < 0)
      throw Error("cannot set pixel format " + fourcc_to_string(want) + ": " + errno_text(errno),
                  {.file = uri_, .key = format_key});
    if (fmt.fmt.pix.pixelformat != want)
      throw Error("asked for pixel format " + fourcc_to_string(want) + ", the device chose " +
                      fourcc_to_string(fmt.fmt.pix.pixelformat),
                  {.file = uri_, .key = format_key});
    if (requested_.roi_px && (static_cast<int>(fmt.fmt.pix.width) != requested_.roi_px->width ||
                              static_cast<int>(fmt.fmt.pix.height) != requested_.roi_px->height))
      throw Error("the device cannot capture " + std::to_string(requested_.roi_px->width) + "x" +
                      std::to_string(requested_.roi_px->height) + " in " + fourcc_to_string(want) +
                      "; the nearest size it offers is " + std::to_string(fmt.fmt.pix.width) + "x" +
                      std::to_string(fmt.fmt.pix.height),
                  {.file = uri_, .key = roi_key});
    fourcc_ = fmt.fmt.pix.pixelformat;
    width_ = static_cast<int>(fmt.fmt.pix.width);
    height_ = static_cast<int>(fmt.fmt.pix.height);
    stride_ = fmt.fmt.pix.bytesperline;
    const std::size_t bpp = fourcc_ == V4L2_PIX_FMT_GREY ? 1 : 2;
    if (stride_ < width_ * bpp) stride_ = static_cast<std::uint32_t>(width_ * bpp);
    readback_["pixel_format"] = fourcc_to_string(fourcc_);
    readback_["width_px"] = std::to_string(width_);
    readback_["height_px"] = std::to_string(height_);
    readback_["bytes_per_line"] = std::to_string(stride_);
    readback_["converted_to"] = fourcc_ == V4L2_PIX_FMT_YUYV ? "grey (luma plane)" : "grey";
  }

  void apply_frame_rate() {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const bool can_get = xioctl(fd_, VIDIOC_G_PARM, &parm) == 0;
    has_timeperframe_ = can_get && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME);
    const std::string key = requested_.key("--fps");
    if (requested_.frame_rate_hz) {
      const double fps = *requested_.frame_rate_hz;
      if (!(fps > 0.0) || !std::isfinite(fps))
        throw Error("frame rate must be positive, got " + format_double(fps), {.file = uri_, .key = key});
      if (!has_timeperframe_)
        throw Error("the device has no frame-rate control (no V4L2_CAP_TIMEPERFRAME)",
                    {.file = uri_, .key = key});
      parm.parm.capture.timeperframe.numerator = 1000;
      parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(fps * 1000.0));
      if (xioctl(fd_, VIDIOC_S_PARM, &parm) < 0)
        throw Error("cannot set the frame rate: " + errno_text(errno), {.file = uri_, .key = key});
      xioctl(fd_, VIDIOC_G_PARM, &parm);
      const auto& tpf = parm.parm.capture.timeperframe;
      const double got = tpf.numerator > 0 ? double(tpf.denominator) / double(tpf.numerator) : 0.0;
      if (std::abs(got - fps) > 0.01 * fps)
        throw Error("asked for " + format_double(fps) + " frames/s; the device can only do " +
                        format_double(got) + " at this size and format",
                    {.file = uri_, .key = key});
    }
    if (has_timeperframe_) {
      const auto& tpf = parm.parm.capture.timeperframe;
      if (tpf.numerator > 0 && tpf.denominator > 0) {
        frame_period_s_ = double(tpf.numerator) / double(tpf.denominator);
        readback_["frame_rate_hz"] = format_double(1.0 / frame_period_s_);
      }
    }
  }

  std::optional<v4l2_queryctrl> query_control(std::uint32_t id) {
    v4l2_queryctrl q{};
    q.id = id;
    if (xioctl(fd_, VIDIOC_QUERYCTRL, &q) < 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) return std::nullopt;
    return q;
  }

  void apply_exposure() {
    const auto exposure = query_control(V4L2_CID_EXPOSURE_ABSOLUTE);
    const std::string key = requested_.key("--exposure");
    if (requested_.exposure_us) {
      if (!exposure)
        throw Error("the device has no exposure control (V4L2_CID_EXPOSURE_ABSOLUTE)",
                    {.file = uri_, .key = key});
      if (query_control(V4L2_CID_EXPOSURE_AUTO)) {
        v4l2_control manual{V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL};
        if (xioctl(fd_, VIDIOC_S_CTRL, &manual) < 0)
          throw Error("cannot turn automatic exposure off: " + errno_text(errno), {.file = uri_, .key = key});
      }
      // V4L2_CID_EXPOSURE_ABSOLUTE counts 100 µs units.
      const double units = *requested_.exposure_us / 100.0;
      if (!(units >= exposure->minimum && units <= exposure->maximum))
        throw Error("exposure " + format_double(*requested_.exposure_us) +
                        " µs is outside the device's range " + std::to_string(exposure->minimum * 100) +
                        ".." + std::to_string(exposure->maximum * 100) + " µs",
                    {.file = uri_, .key = key});
      v4l2_control set{V4L2_CID_EXPOSURE_ABSOLUTE, static_cast<std::int32_t>(std::lround(units))};
      if (xioctl(fd_, VIDIOC_S_CTRL, &set) < 0)
        throw Error("cannot set the exposure: " + errno_text(errno), {.file = uri_, .key = key});
    }
    if (exposure) {
      v4l2_control get{V4L2_CID_EXPOSURE_ABSOLUTE, 0};
      if (xioctl(fd_, VIDIOC_G_CTRL, &get) == 0) readback_["exposure_us"] = std::to_string(get.value * 100);
    }
    if (const auto gain = query_control(V4L2_CID_GAIN)) {
      v4l2_control get{V4L2_CID_GAIN, 0};
      if (xioctl(fd_, VIDIOC_G_CTRL, &get) == 0) readback_["gain_raw"] = std::to_string(get.value);
    }
  }

  void reject_unsupported() {
    if (requested_.gain_dB)
      throw Error(
          "V4L2 gain controls have no defined unit, so a gain in dB cannot be set on this device; leave "
          "the gain unset (the raw value is read back as gain_raw)",
          {.file = uri_, .key = requested_.key("--gain")});
    if (!requested_.trigger.empty() && requested_.trigger != "free-run")
      throw Error("V4L2 devices run free; trigger '" + requested_.trigger + "' is not available",
                  {.file = uri_, .key = requested_.key("--trigger")});
    if (requested_.packet_size_bytes)
      throw Error("a packet size applies to GigE Vision cameras only",
                  {.file = uri_, .key = requested_.key("--packet-size")});
  }

  void start_stream() {
    v4l2_requestbuffers req{};
    req.count = static_cast<std::uint32_t>(requested_.buffer_count > 0 ? requested_.buffer_count : 8);
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) < 0)
      throw Error("cannot allocate stream buffers (VIDIOC_REQBUFS): " + errno_text(errno) +
                      (errno == EBUSY ? " — another program is using the device" : ""),
                  {.file = uri_});
    if (req.count < 2) throw Error("the device granted fewer than 2 stream buffers", {.file = uri_});
    readback_["buffer_count"] = std::to_string(req.count);
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) < 0)
        throw Error("VIDIOC_QUERYBUF failed: " + errno_text(errno), {.file = uri_});
      void* data = ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
      if (data == MAP_FAILED) throw Error("cannot map stream buffer: " + errno_text(errno), {.file = uri_});
      buffers_.push_back({data, buf.length});
    }
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (xioctl(fd_, VIDIOC_QBUF, &buf) < 0)
        throw Error("VIDIOC_QBUF failed: " + errno_text(errno), {.file = uri_});
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0)
      throw Error("cannot start streaming: " + errno_text(errno), {.file = uri_});
    streaming_ = true;
    last_frame_steady_s_ = steady_now_s();
  }

  void convert(const v4l2_buffer& buf, bool error_flag, Frame& frame) {
    const auto& mapping = buffers_.at(buf.index);
    const auto* bytes = static_cast<const std::uint8_t*>(mapping.data);
    const std::size_t used = buf.bytesused != 0 ? buf.bytesused : mapping.length;
    const std::size_t needed = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(height_ - 1) +
                               static_cast<std::size_t>(width_) * (fourcc_ == V4L2_PIX_FMT_GREY ? 1 : 2);
    bool incomplete = error_flag || used < needed || mapping.length < needed;
    if (fourcc_ == V4L2_PIX_FMT_GREY) {
      frame.image.create(height_, width_, CV_8UC1);
    } else if (fourcc_ == V4L2_PIX_FMT_Y16) {
      frame.image.create(height_, width_, CV_16UC1);
    } else {
      frame.image.create(height_, width_, CV_8UC1);
    }
    if (mapping.length >= needed) {
      for (int y = 0; y < height_; ++y) {
        const std::uint8_t* row = bytes + static_cast<std::size_t>(y) * stride_;
        if (fourcc_ == V4L2_PIX_FMT_YUYV) {
          auto* out = frame.image.ptr<std::uint8_t>(y);
          for (int x = 0; x < width_; ++x) out[x] = row[2 * x];  // Y0 U Y1 V: luma at even bytes
        } else {
          std::memcpy(frame.image.ptr(y), row, static_cast<std::size_t>(width_) * frame.image.elemSize());
        }
      }
    } else {
      frame.image.setTo(0);
    }
    const SequenceGapCounter::Step step = gaps_.add(buf.sequence);
    frame.index = index_++;
    frame.device_frame_id = step.frame_id;
    frame.frames_lost_before = step.lost_before;
    frame.device_time_s = double(buf.timestamp.tv_sec) + double(buf.timestamp.tv_usec) * 1e-6;
    frame.host_time_s = steady_now_s();
    frame.origin = uri_;
    if (incomplete) {
      frame.status = FrameStatus::kIncomplete;
      ++incomplete_;
    } else if (step.lost_before > 0) {
      frame.status = FrameStatus::kGapBefore;
    } else {
      frame.status = FrameStatus::kOk;
    }
  }

  double frame_timeout_s() const {
    if (requested_.frame_timeout_s > 0.0) return requested_.frame_timeout_s;
    return std::max(5.0, 20.0 * frame_period_s_);
  }

  void check_stalled() {
    const double now = steady_now_s();
    if (now - last_frame_steady_s_ < frame_timeout_s()) return;
    // Still there? A device node that has gone answers ENODEV to every ioctl.
    v4l2_capability caps{};
    if (xioctl(fd_, VIDIOC_QUERYCAP, &caps) < 0)
      disconnected("the device stopped answering: " + errno_text(errno));
    throw Error("no frame for " + format_double(std::round((now - last_frame_steady_s_) * 10.0) / 10.0) +
                    " s although the device is still there (stalled driver?) after " +
                    std::to_string(index_) + " frames",
                {.file = uri_, .key = requested_.key("--frame-timeout")});
  }

  [[noreturn]] void disconnected(const std::string& reason) {
    streaming_ = false;  // STREAMOFF on a vanished device would only fail again
    throw Error("the V4L2 device went away after " + std::to_string(index_) + " frames (" + reason +
                    "): unplugged, or its driver was unbound; every frame before this was delivered",
                {.file = uri_});
  }

  void release() {
    if (fd_ >= 0 && streaming_) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      xioctl(fd_, VIDIOC_STREAMOFF, &type);
    }
    streaming_ = false;
    for (auto& b : buffers_) ::munmap(b.data, b.length);
    buffers_.clear();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  struct Mapping {
    void* data;
    std::size_t length;
  };

  std::string device_;
  std::string uri_;
  CameraSettings requested_;
  int fd_ = -1;
  bool streaming_ = false;
  bool has_timeperframe_ = false;
  std::vector<Mapping> buffers_;
  std::uint32_t fourcc_ = 0;
  int width_ = 0;
  int height_ = 0;
  std::uint32_t stride_ = 0;
  double frame_period_s_ = 0.0;
  double last_frame_steady_s_ = 0.0;
  std::int64_t index_ = 0;
  std::int64_t incomplete_ = 0;
  SequenceGapCounter gaps_;
  std::map<std::string, std::string> readback_;
};

}  // namespace

std::vector<CameraInfo> list_v4l2_cameras() {
  std::vector<CameraInfo> out;
  std::vector<std::string> nodes;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) == 0) nodes.push_back(entry.path().string());
  }
  // /dev/video2 before /dev/video10.
  std::sort(nodes.begin(), nodes.end(), [](const std::string& a, const std::string& b) {
    return a.size() != b.size() ? a.size() < b.size() : a < b;
  });
  for (const auto& node : nodes) {
    const int fd = ::open(node.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) continue;
    v4l2_capability caps{};
    const bool ok = xioctl(fd, VIDIOC_QUERYCAP, &caps) == 0;
    ::close(fd);
    if (!ok) continue;
    const std::uint32_t device_caps =
        (caps.capabilities & V4L2_CAP_DEVICE_CAPS) ? caps.device_caps : caps.capabilities;
    if (!(device_caps & V4L2_CAP_VIDEO_CAPTURE)) continue;
    CameraInfo info;
    info.backend = "v4l2";
    info.uri = "v4l2:" + node;
    info.model = reinterpret_cast<const char*>(caps.card);
    info.address = reinterpret_cast<const char*>(caps.bus_info);
    info.protocol = reinterpret_cast<const char*>(caps.driver);
    out.push_back(std::move(info));
  }
  return out;
}

std::unique_ptr<FrameSource> open_v4l2_source(const std::string& uri_body, const CameraSettings& settings) {
  return std::make_unique<V4l2Source>(uri_body, settings);
}

}  // namespace tirstrain::capture
