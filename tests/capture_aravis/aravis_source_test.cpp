// The Aravis backend against real GigE Vision peers (Aravis' in-process ArvGvFakeCamera serving our own
// images, and the arv-fake-gv-camera-0.8 process), all inside a loopback-only network namespace (see
// netns_main.cpp). Each test starts its own fresh camera.
#include <arv.h>
#include <gtest/gtest.h>
#include <sys/mount.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <set>

#include "capture/aravis_source.hpp"
#include "capture/camera_settings.hpp"
#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "tests/capture_aravis/netns.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;
using tirstrain::testing::Child;
using tirstrain::testing::FakeCameraProcess;
using tirstrain::testing::read_text;
using tirstrain::testing::test_dir;

// The image the fake camera serves for a given raw 16-bit block id: every pixel depends on the id, so a
// frame read back under the wrong id, or a stale or torn buffer, cannot match.
cv::Mat expected_raw(int width, int height, bool sixteen_bit, std::uint64_t raw_id) {
  cv::Mat image(height, width, sixteen_bit ? CV_16UC1 : CV_8UC1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::uint64_t v =
          static_cast<std::uint64_t>(x) * 3 + static_cast<std::uint64_t>(y) * 5 + raw_id * 7;
      if (sixteen_bit)
        image.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(v * 257 + (raw_id >> 3));
      else
        image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(v);
    }
  }
  return image;
}

void fill_pattern(ArvBuffer* buffer, void*, guint32, guint32, ArvPixelFormat format) {
  size_t size = 0;
  auto* data = static_cast<unsigned char*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
  const int width = arv_buffer_get_image_width(buffer);
  const int height = arv_buffer_get_image_height(buffer);
  const cv::Mat image =
      expected_raw(width, height, format == ARV_PIXEL_FORMAT_MONO_16, arv_buffer_get_frame_id(buffer));
  std::memcpy(data, image.data, image.total() * image.elemSize());
}

// The raw GigE Vision id (1..65535) behind an unwrapped frame counter that started at a raw id.
std::uint64_t raw_of(std::int64_t unwrapped) {
  return static_cast<std::uint64_t>((unwrapped - 1) % 65535 + 1);
}

cv::Mat expected_frame(const Frame& frame, const std::string& pixel_format) {
  const bool wide = pixel_format == "Mono16";
  cv::Mat raw = expected_raw(frame.image.cols, frame.image.rows, wide, raw_of(frame.device_frame_id));
  if (pixel_format == "BayerRG8") {
    cv::Mat grey;
    cv::cvtColor(raw, grey, cv::COLOR_BayerBG2GRAY);
    return grey;
  }
  return raw;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::countNonZero(a != b) == 0;
}

class InProcessCamera {
 public:
  InProcessCamera() {
    gv_ = arv_gv_fake_camera_new("127.0.0.1", "TIRS01");
    fake_ = arv_gv_fake_camera_get_fake_camera(gv_);
    arv_fake_camera_set_fill_pattern(fake_, fill_pattern, nullptr);
  }
  ~InProcessCamera() { g_object_unref(gv_); }
  InProcessCamera(const InProcessCamera&) = delete;
  InProcessCamera& operator=(const InProcessCamera&) = delete;
  bool running() { return arv_gv_fake_camera_is_running(gv_); }
  ArvFakeCamera* fake() { return fake_; }

 private:
  ArvGvFakeCamera* gv_ = nullptr;
  ArvFakeCamera* fake_ = nullptr;
};

class AravisTest : public ::testing::Test {
 protected:
  void SetUp() override {
    TIRSTRAIN_REQUIRE_NETNS();
    camera_ = std::make_unique<InProcessCamera>();
    ASSERT_TRUE(camera_->running()) << "the in-process fake camera did not start on 127.0.0.1";
  }
  CameraSettings small(const std::string& format, double fps) {
    CameraSettings s;
    s.pixel_format = format;
    s.roi_px = cv::Rect(0, 0, 96, 64);
    s.frame_rate_hz = fps;
    s.trigger = "free-run";
    s.frame_timeout_s = 3.0;
    return s;
  }
  std::unique_ptr<InProcessCamera> camera_;
};

using testing::error_of;

// Acquires n frames and checks size, exact content, consecutive unwrapped ids and rising timestamps.
void acquire_and_check(FrameSource& source, const std::string& format, int n) {
  std::int64_t previous_id = -1;
  double previous_t = 0;
  for (int i = 0; i < n; ++i) {
    std::optional<Frame> frame = source.next();
    ASSERT_TRUE(frame.has_value());
    ASSERT_EQ(frame->status, FrameStatus::kOk) << "frame " << i << " " << to_string(frame->status);
    ASSERT_EQ(frame->index, i);
    ASSERT_EQ(frame->image.cols, 96);
    ASSERT_EQ(frame->image.rows, 64);
    ASSERT_EQ(frame->image.depth(), format == "Mono16" ? CV_16U : CV_8U);
    ASSERT_TRUE(same(frame->image, expected_frame(*frame, format)))
        << "frame " << i << " id " << frame->device_frame_id;
    if (previous_id >= 0) {
      EXPECT_EQ(frame->device_frame_id, previous_id + 1);
      EXPECT_GT(frame->device_time_s, previous_t);
    }
    EXPECT_EQ(frame->frames_lost_before, 0);
    previous_id = frame->device_frame_id;
    previous_t = frame->device_time_s;
  }
}

TEST(FrameIdUnwrapperTest, GigEVisionIdsSkipZeroOnWrap) {
  FrameIdUnwrapper u;
  EXPECT_EQ(u.unwrap(65534), 65534);
  EXPECT_EQ(u.unwrap(65535), 65535);
  EXPECT_EQ(u.unwrap(1), 65536);  // 0 is reserved: 65535 -> 1 is one step
  EXPECT_EQ(u.unwrap(2), 65537);
  EXPECT_EQ(u.unwrap(5), 65540);  // two frames lost
  EXPECT_EQ(u.unwrap(3), 65538);  // one of them delivered late (Aravis hands incomplete frames over late)
  EXPECT_EQ(u.unwrap(6), 65541);  // the newest id stays the reference
  FrameIdUnwrapper v;
  EXPECT_EQ(v.unwrap(65530), 65530);
  EXPECT_EQ(v.unwrap(65533), 65533);
  EXPECT_EQ(v.unwrap(3), 65538);      // wrap with a loss: 65534, 65535, 1, 2 lost
  EXPECT_EQ(v.unwrap(65534), 65534);  // late across the wrap: not a second wrap
  EXPECT_EQ(v.unwrap(4), 65539);
  FrameIdUnwrapper wide;
  EXPECT_EQ(wide.unwrap(70000), 70000);  // above 16 bits: taken as is
  EXPECT_EQ(wide.unwrap(70001), 70001);
  EXPECT_EQ(wide.unwrap(69999), 69999);  // late
  EXPECT_EQ(wide.unwrap(70002), 70002);
}

TEST_F(AravisTest, Mono8FramesReadBackExactly) {
  auto source = open_source("aravis:127.0.0.1", small("Mono8", 200));
  EXPECT_EQ(source->settings().at("pixel_format"), "Mono8");
  EXPECT_EQ(source->settings().at("width_px"), "96");
  EXPECT_EQ(source->settings().at("frame_rate_hz"), "200");
  acquire_and_check(*source, "Mono8", 40);
}

TEST_F(AravisTest, Mono16FramesReadBackExactly) {
  auto source = open_source("aravis:127.0.0.1", small("Mono16", 200));
  EXPECT_EQ(source->settings().at("pixel_format"), "Mono16");
  acquire_and_check(*source, "Mono16", 40);
}

TEST_F(AravisTest, BayerIsConvertedToGrey) {
  auto source = open_source("aravis:127.0.0.1", small("BayerRG8", 200));
  EXPECT_EQ(source->settings().at("converted_to_grey"), "true (Bayer)");
  acquire_and_check(*source, "BayerRG8", 10);
}

// The fake camera starts its 16-bit block id near 65400 on purpose: 300 frames at 1 kHz cross the wrap.
TEST_F(AravisTest, FrameIdWrapAroundIsUnwrapped) {
  auto source = open_source("aravis:127.0.0.1", small("Mono8", 1000));
  std::int64_t first = -1, last = -1;
  for (int i = 0; i < 300; ++i) {
    std::optional<Frame> frame = source->next();
    ASSERT_TRUE(frame.has_value());
    if (first < 0) first = frame->device_frame_id;
    if (last >= 0) {
      ASSERT_EQ(frame->device_frame_id, last + 1) << "at frame " << i;
    }
    ASSERT_EQ(frame->status, FrameStatus::kOk);
    ASSERT_TRUE(same(frame->image, expected_frame(*frame, "Mono8"))) << "id " << frame->device_frame_id;
    last = frame->device_frame_id;
  }
  EXPECT_LT(first, 65535);
  EXPECT_GT(last, 65535) << "the run should have crossed the 16-bit wrap (first id " << first << ")";
}

TEST_F(AravisTest, SoftwareTriggerDeliversOneFramePerTrigger) {
  arv_fake_camera_set_trigger_frequency(camera_->fake(), 200.0);  // how often the fake camera checks
  CameraSettings s = small("Mono8", 100);
  s.trigger = "software";
  auto source = open_source("aravis:127.0.0.1", s);
  EXPECT_EQ(source->settings().at("trigger"), "software");
  set_auto_software_trigger(*source, false);
  Frame frame;
  EXPECT_EQ(source->poll(frame, 0.3), FrameSource::Poll::kTimeout) << "a frame arrived without a trigger";
  std::int64_t last = -1;
  for (int i = 0; i < 3; ++i) {
    software_trigger(*source);
    ASSERT_EQ(source->poll(frame, 2.0), FrameSource::Poll::kFrame) << "no frame after trigger " << i;
    EXPECT_EQ(frame.status, FrameStatus::kOk);
    if (last >= 0) {
      EXPECT_EQ(frame.device_frame_id, last + 1);
    }
    last = frame.device_frame_id;
    EXPECT_EQ(source->poll(frame, 0.15), FrameSource::Poll::kTimeout) << "more than one frame per trigger";
  }
  // With auto triggering (the default, as record uses it) every next() fires one trigger.
  set_auto_software_trigger(*source, true);
  for (int i = 0; i < 3; ++i) {
    std::optional<Frame> f = source->next();
    ASSERT_TRUE(f.has_value());
    EXPECT_EQ(f->device_frame_id, last + 1);
    last = f->device_frame_id;
  }
}

TEST_F(AravisTest, UnsupportedAndUnofferedPixelFormatsAreClear) {
  CameraSettings s = small("RGB8", 50);
  std::string message = error_of([&] { open_source("aravis:127.0.0.1", s); });
  EXPECT_NE(message.find("'RGB8' is not supported"), std::string::npos) << message;
  EXPECT_NE(message.find("--pixel-format"), std::string::npos) << message;
  // The refused format was never written: the camera opens as it was, without asking for a format.
  s.pixel_format.clear();
  EXPECT_EQ(error_of([&] { open_source("aravis:127.0.0.1", s); }), "(no error)");
  s.pixel_format = "Mono12";
  message = error_of([&] { open_source("aravis:127.0.0.1", s); });
  EXPECT_NE(message.find("'Mono12' is not offered by this camera; it offers: "), std::string::npos)
      << message;
  EXPECT_NE(message.find("Mono16"), std::string::npos) << message;
}

TEST_F(AravisTest, ImpossibleSettingsAreClear) {
  struct Case {
    std::function<void(CameraSettings&)> set;
    std::string expected, key;
  };
  const std::vector<Case> cases = {
      {[](CameraSettings& s) { s.exposure_us = 12345678; },
       "exposure 12345678 us is outside this camera's range", "--exposure-us"},
      {[](CameraSettings& s) { s.frame_rate_hz = 5000; }, "frame rate 5000 Hz is outside this camera's range",
       "--fps"},
      {[](CameraSettings& s) { s.roi_px = cv::Rect(0, 0, 4096, 16); }, "does not fit the sensor: 2048x2048",
       "--roi"},
      {[](CameraSettings& s) { s.trigger = "Line7"; }, "trigger 'Line7' is not available", "--trigger"},
      {[](CameraSettings& s) { s.packet_size_bytes = 100000; }, "packet size 100000 B is outside",
       "--packet-size"},
  };
  for (const auto& c : cases) {
    CameraSettings s = small("Mono8", 50);
    c.set(s);
    const std::string message = error_of([&] { open_source("aravis:127.0.0.1", s); });
    EXPECT_NE(message.find(c.expected), std::string::npos) << message;
    EXPECT_NE(message.find(c.key), std::string::npos) << message;
  }
}

TEST_F(AravisTest, BadUrisAndUnknownDevicesAreClear) {
  std::string message = error_of([] { open_source("aravis:No-Such-Camera-42"); });
  EXPECT_NE(message.find("cannot open Aravis camera 'No-Such-Camera-42'"), std::string::npos) << message;
  EXPECT_NE(message.find("tirstrain cameras"), std::string::npos) << message;
  message = error_of([] { open_source("aravis:127.0.0.9"); });  // nothing answers there
  EXPECT_NE(message.find("cannot open Aravis camera '127.0.0.9'"), std::string::npos) << message;
  CameraSettings s;
  s.exposure_us = 100;
  message = error_of([&] { open_source(std::string(TIRSTRAIN_SOURCE_DIR), s); });
  EXPECT_NE(message.find("only apply to camera sources"), std::string::npos) << message;
}

// Recording reads back as a normal image-folder source: same pixels, frames.csv time axis, every row.
TEST_F(AravisTest, RecordingIsAReadableImageFolder) {
  const std::string dir = test_dir("record_readback");
  for (const std::string format : {"Mono8", "Mono16"}) {
    auto source = open_source("aravis:127.0.0.1", small(format, 200));
    RecordOptions options;
    options.out_dir = dir + "/" + format;
    options.max_frames = 25;
    const RecordReport report = record(*source, options);
    ASSERT_TRUE(report.ok()) << report.error;
    EXPECT_EQ(report.stop_reason, "frames");
    EXPECT_EQ(report.counts.frames_received, 25);
    EXPECT_EQ(report.counts.frames_saved, 25);
    EXPECT_EQ(report.counts.frames_dropped_host, 0);
    const CsvTable table = read_numeric_csv(options.out_dir + "/frames.csv");
    ASSERT_EQ(table.rows(), 25u);
    const auto& ids = table.column("device_frame_id");
    const auto& t_s = table.column("t_s");
    auto folder = open_source(options.out_dir);
    EXPECT_EQ(folder->settings().at("time_measured"), "true");
    for (std::size_t i = 0; i < 25; ++i) {
      std::optional<Frame> frame = folder->next();
      ASSERT_TRUE(frame.has_value());
      EXPECT_EQ(frame->status, FrameStatus::kOk);
      EXPECT_DOUBLE_EQ(frame->device_time_s, t_s[i]);
      Frame as_received = *frame;
      as_received.device_frame_id = static_cast<std::int64_t>(ids[i]);
      ASSERT_TRUE(same(frame->image, expected_frame(as_received, format))) << format << " frame " << i;
    }
    EXPECT_FALSE(folder->next().has_value());
    const std::string summary = read_text(options.out_dir + "/recording.json");
    EXPECT_NE(summary.find("\"pixel_format\": \"" + format + "\""), std::string::npos) << summary;
    EXPECT_NE(summary.find("\"stop_reason\": \"frames\""), std::string::npos);
  }
}

// Writers slower than the camera (PNG level 9, one writer, room for one queued frame): frames are dropped
// before the queue, counted, and the next stored frame says how many went before it (status 4), so the
// counts add up and the file numbers keep the holes.
TEST_F(AravisTest, WritersThatCannotKeepUpDropCountedFrames) {
  const std::string dir = test_dir("host_drops");
  CameraSettings s = small("Mono8", 500);
  s.roi_px = cv::Rect(0, 0, 512, 512);
  auto source = open_source("aravis:127.0.0.1", s);
  RecordOptions options;
  options.out_dir = dir;
  options.format = ImageFormat::kPng;
  options.png_level = 9;
  options.writer_threads = 1;
  options.queue_bytes = 1;  // one frame waits at most
  options.max_frames = 200;
  std::int64_t progress_dropped = 0;
  options.on_progress = [&](const RecordProgress& p) { progress_dropped = p.frames_dropped_host; };
  const RecordReport report = record(*source, options);
  ASSERT_TRUE(report.ok()) << report.error;
  const RecordProgress& c = report.counts;
  EXPECT_EQ(c.frames_received, 200);
  EXPECT_GT(c.frames_dropped_host, 0) << "one PNG-9 writer kept up with 500 frames/s of 512x512";
  EXPECT_GT(progress_dropped, 0) << "the progress callback (the CLI's WARNING) never saw the drops";
  EXPECT_EQ(c.frames_received, c.frames_saved + c.frames_dropped_host + c.frames_incomplete);
  const CsvTable table = read_numeric_csv(dir + "/frames.csv");
  EXPECT_EQ(static_cast<std::int64_t>(table.rows()), c.frames_received - c.frames_dropped_host);
  double lost_sum = 0;
  std::int64_t overruns = 0;
  for (std::size_t i = 0; i < table.rows(); ++i) {
    lost_sum += table.column("frames_lost_before")[i];
    if (table.column("status")[i] == static_cast<int>(FrameStatus::kOverrun)) {
      ++overruns;
      EXPECT_GE(table.column("frames_lost_before")[i], 1);
    }
  }
  EXPECT_GT(overruns, 0);
  // Frames dropped after the last row have no later row to report them: only recording.json counts them.
  const auto& received = table.column("received");
  const double after_last_row =
      static_cast<double>(c.frames_received) - 1 - *std::max_element(received.begin(), received.end());
  EXPECT_EQ(lost_sum + after_last_row, static_cast<double>(c.frames_lost_device + c.frames_dropped_host));
  std::int64_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir + "/frames")) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, c.frames_saved);
  const std::string json = read_text(dir + "/recording.json");
  EXPECT_NE(json.find("\"frames_dropped_host\": " + std::to_string(c.frames_dropped_host) + ","),
            std::string::npos)
      << json;
}

// Disk full: a 1 MiB tmpfs (private to this test's mount namespace) fills after a few frames. The run stops
// cleanly; every frame listed in frames.csv is complete and readable.
TEST_F(AravisTest, DiskFullStopsCleanlyWithEarlierFramesReadable) {
  const std::string dir = test_dir("disk_full");
  fs::create_directories(dir);
  if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=1m") != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here: " << std::strerror(errno);
  struct Unmount {
    std::string dir;
    ~Unmount() { ::umount2(dir.c_str(), MNT_DETACH); }
  } unmount{dir};
  CameraSettings s = small("Mono8", 200);
  s.roi_px = cv::Rect(0, 0, 256, 256);  // 64 KiB frames as PGM: about 15 fit
  auto source = open_source("aravis:127.0.0.1", s);
  RecordOptions options;
  options.out_dir = dir + "/rec";
  options.format = ImageFormat::kPgm;
  options.max_frames = 100;
  const RecordReport report = record(*source, options);
  EXPECT_FALSE(report.ok());
  EXPECT_EQ(report.stop_reason, "write error");
  EXPECT_NE(report.error.find("No space left on device"), std::string::npos) << report.error;
  EXPECT_GT(report.counts.frames_saved, 3);
  EXPECT_LT(report.counts.frames_saved, 100);
  auto folder = open_source(options.out_dir);
  EXPECT_EQ(folder->frame_count(), report.counts.frames_saved);
  std::int64_t n = 0;
  while (std::optional<Frame> frame = folder->next()) {
    ASSERT_EQ(frame->status, FrameStatus::kOk) << "frame " << n;
    ASSERT_EQ(frame->image.cols, 256);
    ++n;
  }
  EXPECT_EQ(n, report.counts.frames_saved);
  for (const auto& entry : fs::directory_iterator(options.out_dir + "/frames"))
    EXPECT_EQ(entry.path().extension(), ".pgm") << "leftover partial file " << entry.path();
  // The full disk may also refuse recording.json: never silently.
  EXPECT_TRUE(fs::exists(options.out_dir + "/recording.json") ||
              report.error.find("no recording.json") != std::string::npos)
      << report.error;
}

// An unwritable folder (a read-only mount: root ignores permission bits) is refused before recording.
TEST_F(AravisTest, UnwritableFolderIsRefusedClearly) {
  const std::string dir = test_dir("read_only");
  fs::create_directories(dir);
  if (::mount("tmpfs", dir.c_str(), "tmpfs", MS_RDONLY, "size=1m") != 0)
    GTEST_SKIP() << "cannot mount a read-only tmpfs here: " << std::strerror(errno);
  struct Unmount {
    std::string dir;
    ~Unmount() { ::umount2(dir.c_str(), MNT_DETACH); }
  } unmount{dir};
  auto source = open_source("aravis:127.0.0.1", small("Mono8", 100));
  RecordOptions options;
  options.out_dir = dir + "/rec";
  options.max_frames = 5;
  const std::string message = error_of([&] { record(*source, options); });
  EXPECT_NE(message.find(dir + "/rec"), std::string::npos) << message;
  EXPECT_NE(message.find("--out"), std::string::npos) << message;
}

// ---- The arv-fake-gv-camera-0.8 process and the CLI ----

// Its default image is a diagonal ramp: (x + y + id) mod 255 at gain 0, exposure 10 ms.
bool is_fake_ramp(const Frame& frame) {
  const std::uint64_t id = raw_of(frame.device_frame_id);
  for (int y = 0; y < frame.image.rows; ++y)
    for (int x = 0; x < frame.image.cols; ++x)
      if (frame.image.at<std::uint8_t>(y, x) != (x + y + id) % 255) return false;
  return true;
}

class AravisProcessTest : public ::testing::Test {
 protected:
  void SetUp() override { TIRSTRAIN_REQUIRE_NETNS(); }
};

// -r drops packets (per thousand) and the fake camera never resends: such frames must come out
// incomplete, be counted, and never be stored as good frames.
// Records `frames` frames over a lossy link and checks every row, the counts and the frames read back.
void check_packet_loss_recording(const std::string& name, int frames, const std::string& buffers) {
  FakeCameraProcess camera(name, 5);
  ASSERT_TRUE(camera.ready());
  const std::string dir = test_dir(name);
  Child cli(
      {TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--out", dir, "--frames", std::to_string(frames), "--fps",
       "100", "--roi", "0,0,256,128", "--packet-size", "1400", "--format", "pgm", "--buffers", buffers},
      dir + ".log");
  const int code = cli.wait(90);
  const std::string log = cli.log();
  ASSERT_EQ(code, 0) << log;
  EXPECT_NE(log.find("incomplete frames (listed in frames.csv"), std::string::npos) << log;
  const CsvTable table = read_numeric_csv(dir + "/frames.csv");
  const auto& status = table.column("status");
  const auto& saved = table.column("saved");
  const auto& index = table.column("index");
  std::size_t incomplete = 0, good = 0;
  for (std::size_t i = 0; i < table.rows(); ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frames/%06d.pgm", static_cast<int>(index[i]));
    if (status[i] == 1) {
      ++incomplete;
      EXPECT_EQ(saved[i], 0);
      EXPECT_FALSE(fs::exists(dir + name)) << "incomplete frame stored as an image: " << name;
    } else {
      ++good;
      EXPECT_EQ(saved[i], 1);
      EXPECT_TRUE(fs::exists(dir + name));
    }
  }
  EXPECT_EQ(table.rows(), static_cast<std::size_t>(frames));
  EXPECT_GT(incomplete, 0u) << "0.5 % packet loss on ~25 packets per frame should spoil some frames";
  EXPECT_GT(good, 0u);
  EXPECT_NE(read_text(dir + "/recording.json").find("\"frames_incomplete\": " + std::to_string(incomplete)),
            std::string::npos);
  // A frame whose leader packet was lost comes out of Aravis with block id 0 and no timestamp: it must not be
  // taken for a wrap of the 16-bit counter (which would have made every later frame look "late"), it gets a
  // negative index of its own, and the losses must still add up: frames never received = the ids missing
  // from the identified range, minus the frames without an id that arrived inside that range (one that
  // arrived before the first or after the last identified frame lies outside it: CI once caught the 60th
  // frame without its leader).
  const auto& lost_before = table.column("frames_lost_before");
  const auto& device_ids = table.column("device_frame_id");
  const auto& t_s = table.column("t_s");
  double lost_sum = 0, first_id = 1e18, last_id = -1;
  std::size_t identified = 0, first_identified_row = table.rows(), last_identified_row = 0;
  std::set<double> places;
  for (std::size_t i = 0; i < table.rows(); ++i) {
    lost_sum += lost_before[i];
    EXPECT_TRUE(places.insert(index[i]).second) << "index " << index[i] << " used twice";
    if (device_ids[i] < 0) {
      EXPECT_EQ(status[i], 1);
      EXPECT_LT(index[i], 0);
      // No time of its own: the host's arrival time, within the run (not a number from another clock).
      EXPECT_GT(t_s[i], -1.0) << "row " << i;
      EXPECT_LT(t_s[i], 0.01 * frames + 30.0) << "row " << i;
      continue;
    }
    ++identified;
    first_identified_row = std::min(first_identified_row, i);
    last_identified_row = i;
    first_id = std::min(first_id, device_ids[i]);
    last_id = std::max(last_id, device_ids[i]);
  }
  std::size_t unidentified_inside = 0;
  for (std::size_t i = 0; i < table.rows(); ++i) {
    if (device_ids[i] >= 0) {
      EXPECT_EQ(index[i], device_ids[i] - first_id) << "row " << i;
    } else if (i > first_identified_row && i < last_identified_row) {
      ++unidentified_inside;
    }
  }
  EXPECT_EQ(lost_sum, last_id - first_id + 1 - static_cast<double>(identified + unidentified_inside))
      << "frames never received";
  EXPECT_NE(read_text(dir + "/recording.json")
                .find("\"frames_lost_device\": " + std::to_string(static_cast<long long>(lost_sum)) + ","),
            std::string::npos)
      << read_text(dir + "/recording.json");
  // Read back: only the good frames, each exactly the camera's image for its id; the holes are gaps.
  auto folder = open_source(dir);
  std::size_t n = 0;
  const auto& ids = table.column("device_frame_id");
  while (std::optional<Frame> frame = folder->next()) {
    ASSERT_NE(frame->status, FrameStatus::kCorrupt);
    std::size_t row = 0;
    while (row < table.rows() && static_cast<std::int64_t>(index[row]) != frame->device_frame_id) ++row;
    ASSERT_LT(row, table.rows());
    Frame as_received = *frame;
    as_received.device_frame_id = static_cast<std::int64_t>(ids[row]);
    EXPECT_TRUE(is_fake_ramp(as_received)) << "stored frame " << frame->device_frame_id << " is not intact";
    ++n;
  }
  EXPECT_EQ(n, good);
}

TEST_F(AravisProcessTest, PacketLossMarksFramesIncompleteAndNeverPassesThemOn) {
  check_packet_loss_recording("packet_loss", 60, "256");
}

// With few buffers Aravis reuses each one many times: a buffer whose leader packet is lost keeps the id and
// timestamp of its previous use, which once repeated an earlier frame's index (process then refused the
// recording) and added a false gap after it.
TEST_F(AravisProcessTest, PacketLossWithReusedBuffersKeepsEveryIndexDistinct) {
  check_packet_loss_recording("packet_loss_reused", 300, "8");
}

TEST_F(AravisProcessTest, CameraKilledMidStreamEndsRecordingCleanly) {
  FakeCameraProcess camera("killed", 0);
  ASSERT_TRUE(camera.ready());
  const std::string dir = test_dir("killed");
  Child cli({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--out", dir, "--seconds", "60", "--fps", "50",
             "--roi", "0,0,128,64", "--frame-timeout-s", "1"},
            dir + ".log");
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  auto saved_frames = [&] {
    std::error_code ec;
    std::size_t n = 0;
    for (auto it = fs::directory_iterator(dir + "/frames", ec); !ec && it != fs::directory_iterator(); ++it)
      ++n;
    return n;
  };
  while (saved_frames() < 20 && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GE(saved_frames(), 20u) << cli.log();
  camera.kill_now();
  const int code = cli.wait(30);
  const std::string log = cli.log();
  EXPECT_EQ(code, 1) << log;
  EXPECT_NE(log.find("recording stopped early: "), std::string::npos) << log;
  EXPECT_NE(log.find("lost contact with the camera after"), std::string::npos) << log;
  EXPECT_NE(log.find("frames before it are saved in " + dir), std::string::npos) << log;
  const CsvTable table = read_numeric_csv(dir + "/frames.csv");
  EXPECT_GE(table.rows(), 20u);
  auto folder = open_source(dir);
  std::size_t n = 0;
  while (std::optional<Frame> frame = folder->next()) {
    ASSERT_EQ(frame->status, FrameStatus::kOk);
    ++n;
  }
  EXPECT_EQ(n, table.rows());
  EXPECT_NE(read_text(dir + "/recording.json").find("\"stop_reason\": \"source error\""), std::string::npos);
}

TEST_F(AravisProcessTest, CamerasListsTheFakeCamera) {
  FakeCameraProcess camera("cameras", 0);
  ASSERT_TRUE(camera.ready());
  const std::string dir = test_dir("cameras");
  Child cli({TIRSTRAIN_CLI, "cameras", "--backend", "aravis"}, dir + ".log");
  ASSERT_EQ(cli.wait(30), 0) << cli.log();
  const std::string log = cli.log();
  EXPECT_NE(log.find("aravis: 1 camera"), std::string::npos) << log;
  EXPECT_NE(log.find("aravis:Aravis-Fake-GV01"), std::string::npos) << log;
  EXPECT_NE(log.find("127.0.0.1"), std::string::npos) << log;
}

TEST_F(AravisProcessTest, LiveHeadlessWithRecording) {
  FakeCameraProcess camera("live", 0);
  ASSERT_TRUE(camera.ready());
  const std::string dir = test_dir("live");
  Child cli({TIRSTRAIN_CLI, "live", "aravis:127.0.0.1", "--no-window", "--seconds", "2.5", "--fps", "40",
             "--roi", "0,0,128,64", "--record", dir},
            dir + ".log");
  const int code = cli.wait(60);
  const std::string log = cli.log();
  ASSERT_EQ(code, 0) << log;
  EXPECT_NE(log.find("fps received"), std::string::npos) << log;
  EXPECT_NE(log.find(" lost 0 "), std::string::npos) << log;
  const CsvTable table = read_numeric_csv(dir + "/frames.csv");
  EXPECT_GE(table.rows(), 40u);
  EXPECT_LE(table.rows(), 110u);
  EXPECT_NE(log.find("saved to " + dir), std::string::npos) << log;
  // The capture -> display latency summary: every frame shown measured, median <= p95 <= max, and plausible
  // (the display thread takes each frame as it comes at 40 Hz; seconds would mean frames queue up).
  for (const std::string what : {"host receive -> overlay ready ", "device timestamp -> overlay ready "}) {
    const std::size_t at = log.find(what);
    ASSERT_NE(at, std::string::npos) << what
                                     << " missing (the fake camera stamps frames with the host clock)\n"
                                     << log;
    double median = -1, p95 = -1, max = -1;
    long long frames = -1;
    ASSERT_EQ(std::sscanf(log.c_str() + at + what.size(), "%lf / %lf / %lf ms (%lld frames)", &median, &p95,
                          &max, &frames),
              4)
        << log.substr(at, 120);
    EXPECT_GE(frames, 40);
    EXPECT_GT(median, 0.0);
    EXPECT_LE(median, p95);
    EXPECT_LE(p95, max);
    EXPECT_LT(median, 500.0) << log.substr(at, 120);
  }
}

// Without a display `live` must say so (OpenCV's Qt backend would abort the process instead).
TEST_F(AravisProcessTest, LiveWithoutDisplayAsksForNoWindow) {
  const std::string dir = test_dir("live_no_display");
  Child cli({"env", "-u", "DISPLAY", "-u", "WAYLAND_DISPLAY", "-u", "QT_QPA_PLATFORM", TIRSTRAIN_CLI, "live",
             "aravis:127.0.0.1", "--frames", "3"},
            dir + ".log");
  EXPECT_EQ(cli.wait(30), 2) << cli.log();  // a usage error: the option to give is named
  EXPECT_NE(cli.log().find("use --no-window on headless machines"), std::string::npos) << cli.log();
}

TEST_F(AravisProcessTest, CliReportsBadUriAndBadOptions) {
  const std::string dir = test_dir("cli_errors");
  Child bad_roi({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--out", dir, "--roi", "1,2,3"},
                dir + ".1.log");
  EXPECT_EQ(bad_roi.wait(30), 2);  // a bad value on the command line
  EXPECT_NE(bad_roi.log().find("--roi"), std::string::npos) << bad_roi.log();
  Child unknown({TIRSTRAIN_CLI, "record", "aravis:Nope-1", "--out", dir, "--frames", "3"}, dir + ".2.log");
  EXPECT_EQ(unknown.wait(30), 1);
  EXPECT_NE(unknown.log().find("cannot open Aravis camera 'Nope-1'"), std::string::npos) << unknown.log();
  EXPECT_FALSE(fs::exists(dir + "/frames.csv"));
}

}  // namespace
}  // namespace tirstrain::capture

namespace tirstrain::capture {
namespace {

struct ServedTrial {
  std::vector<cv::Mat> frames;
  std::atomic<std::size_t> served{0};
};

// Serves the synthesised trial in order, one frame per camera frame, from the first frame streamed.
void fill_trial(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat) {
  auto* trial = static_cast<ServedTrial*>(data);
  size_t size = 0;
  auto* out = static_cast<unsigned char*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
  const cv::Mat& frame = trial->frames[trial->served.fetch_add(1) % trial->frames.size()];
  std::memcpy(out, frame.data, frame.total());
}

int run_cli(const std::vector<std::string>& args, const std::string& log, double timeout_s) {
  std::vector<std::string> argv = {TIRSTRAIN_CLI};
  argv.insert(argv.end(), args.begin(), args.end());
  Child child(argv, log);
  const int code = child.wait(timeout_s);
  if (code != 0) ADD_FAILURE() << "tirstrain " << args.front() << " exited " << code << ":\n" << child.log();
  return code;
}

// A synthesised trial served by the camera, recorded, then processed, gives the same per-frame results as
// processing the synthesised frames directly. Only the time axis differs (the camera's clock), and with it
// the plate's start: the plate tracker extrapolates its last velocity over each frame's real interval, so
// its converged answer may move in the last digits, far below its 0.02 px accuracy target.
TEST_F(AravisTest, EndToEndRecordThenProcessMatchesDirectProcessing) {
  const std::string dir = test_dir("end_to_end");
  fs::create_directories(dir);
  std::string scene = read_text(std::string(TIRSTRAIN_SOURCE_DIR) + "/samples/scenes/default.yaml");
  const std::size_t at = scene.find("frames: 60");
  ASSERT_NE(at, std::string::npos);
  scene.replace(at, 10, "frames: 12");

  std::ofstream(dir + "/scene.yaml") << scene;
  ASSERT_EQ(run_cli({"synth", "--scene", dir + "/scene.yaml", "--out", dir + "/synth", "--quiet"},
                    dir + "/synth.log", 300),
            0);

  ServedTrial trial;
  auto synth = open_source(dir + "/synth");
  while (std::optional<Frame> frame = synth->next()) trial.frames.push_back(frame->image.clone());
  ASSERT_EQ(trial.frames.size(), 12u);
  ASSERT_EQ(trial.frames.front().type(), CV_8UC1);
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_trial, &trial);

  CameraSettings s = small("Mono8", 100);
  s.roi_px = cv::Rect(0, 0, trial.frames.front().cols, trial.frames.front().rows);
  {
    auto camera = open_source("aravis:127.0.0.1", s);
    RecordOptions options;
    options.out_dir = dir + "/recording";
    options.max_frames = 12;
    const RecordReport report = record(*camera, options);
    ASSERT_TRUE(report.ok()) << report.error;
    ASSERT_EQ(report.counts.frames_saved, 12);
  }
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_pattern, nullptr);
  auto recorded = open_source(dir + "/recording");
  for (std::size_t i = 0; i < trial.frames.size(); ++i) {
    std::optional<Frame> frame = recorded->next();
    ASSERT_TRUE(frame.has_value());
    ASSERT_TRUE(same(frame->image, trial.frames[i])) << "recorded frame " << i << " differs from the trial";
  }

  // The reference first: if `process` cannot handle the synthesised frames themselves, the analysis
  // stages are at fault, not capture, and there is nothing to compare against.
  {
    Child direct({TIRSTRAIN_CLI, "process", dir + "/synth", "--scene", dir + "/synth/scene.yaml", "--out",
                  dir + "/processed-synth", "--overlay", "none", "--quiet"},
                 dir + "/process-synth.log");
    if (const int code = direct.wait(600); code != 0)
      GTEST_SKIP() << "`tirstrain process` fails on the synthesised frames themselves (exit " << code
                   << "), so the recording cannot be compared: " << direct.log().substr(0, 400);
  }
  ASSERT_EQ(run_cli({"process", dir + "/recording", "--scene", dir + "/synth/scene.yaml", "--out",
                     dir + "/processed-recording", "--overlay", "none", "--quiet"},
                    dir + "/process-recording.log", 600),
            0);
  const CsvTable direct = read_numeric_csv(dir + "/processed-synth/frames.csv", NaNCells::kNotMeasured);
  const CsvTable via_camera =
      read_numeric_csv(dir + "/processed-recording/frames.csv", NaNCells::kNotMeasured);
  ASSERT_EQ(direct.names, via_camera.names);
  ASSERT_EQ(direct.rows(), via_camera.rows());
  for (std::size_t j = 0; j < direct.names.size(); ++j) {
    const std::string& name = direct.names[j];
    if (name == "t_s") continue;  // the camera's clock, not the synthetic one
    const bool plate_position = name == "plate_dx_px" || name == "plate_dy_px";
    for (std::size_t i = 0; i < direct.rows(); ++i) {
      const double a = direct.columns[j][i], b = via_camera.columns[j][i];
      if (std::isnan(a) || std::isnan(b))  // not measured in that frame: in both runs alike
        EXPECT_EQ(std::isnan(a), std::isnan(b)) << name << " at frame " << i;
      else if (plate_position)
        EXPECT_NEAR(a, b, 1e-3) << name << " at frame " << i;
      else
        EXPECT_EQ(a, b) << name << " at frame " << i;
    }
  }
}

}  // namespace
}  // namespace tirstrain::capture

// ---- Camera settings from the scene file's camera: section ----

namespace tirstrain::capture {
namespace {

// What the fake camera's image generator was last handed: the device's own exposure, gain and image region
// (not what the client believes it wrote).
struct DeviceView {
  std::atomic<std::uint32_t> exposure_us{0}, gain{0}, frames{0};
  std::atomic<int> x{-1}, y{-1}, width{-1}, height{-1};
  std::atomic<std::uint32_t> format{0};
};

void fill_and_observe(ArvBuffer* buffer, void* data, guint32 exposure_us, guint32 gain,
                      ArvPixelFormat format) {
  auto* view = static_cast<DeviceView*>(data);
  fill_pattern(buffer, nullptr, exposure_us, gain, format);
  gint x = 0, y = 0, w = 0, h = 0;
  arv_buffer_get_image_region(buffer, &x, &y, &w, &h);
  view->exposure_us = exposure_us;
  view->gain = gain;
  view->x = x;
  view->y = y;
  view->width = w;
  view->height = h;
  view->format = format;
  view->frames.fetch_add(1);
}

// The value of "key": "value" in a JSON object written by the recorder (flat string values).
std::string json_value(const std::string& json, const std::string& key) {
  const std::string tag = "\"" + key + "\": \"";
  const std::size_t at = json.find(tag);
  if (at == std::string::npos) return "(missing " + key + ")";
  const std::size_t end = json.find('"', at + tag.size());
  return json.substr(at + tag.size(), end - at - tag.size());
}

double median_step(std::vector<double> t) {
  std::vector<double> steps;
  for (std::size_t i = 1; i < t.size(); ++i) steps.push_back(t[i] - t[i - 1]);
  std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
  return steps[steps.size() / 2];
}

constexpr const char* kRigScene = R"(calibration: {px_per_mm: 52}
camera:
  pixel_format: Mono16
  roi_px: [32, 16, 160, 96]
  exposure_us: 2500
  gain_dB: 3
  frame_rate_hz: 80
  trigger: free-run
  packet_size_bytes: 4000
  buffer_count: 12
)";

// `tirstrain record --scene`: the scene's exposure, gain, ROI, pixel format and frame rate reach the device
// (seen by its image generator and in its frame timing), and the values read back from it are in
// recording.json next to what was asked and where it came from.
TEST_F(AravisTest, SceneCameraSettingsReachTheDeviceAndTheRecording) {
  DeviceView view;
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_and_observe, &view);
  const std::string dir = test_dir("scene_settings");
  fs::create_directories(dir);
  const std::string scene = dir + "/rig.yaml";
  std::ofstream(scene) << kRigScene;
  Child cli({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--scene", scene, "--out", dir + "/rec", "--frames",
             "30", "--format", "pgm", "--quiet"},
            dir + "/record.log");
  const int code = cli.wait(60);
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_pattern, nullptr);
  ASSERT_EQ(code, 0) << cli.log();

  // On the device.
  EXPECT_GE(view.frames.load(), 30u);
  EXPECT_EQ(view.exposure_us.load(), 2500u);
  EXPECT_EQ(view.gain.load(), 3u);
  EXPECT_EQ(view.x.load(), 32);
  EXPECT_EQ(view.y.load(), 16);
  EXPECT_EQ(view.width.load(), 160);
  EXPECT_EQ(view.height.load(), 96);
  EXPECT_EQ(view.format.load(), static_cast<std::uint32_t>(ARV_PIXEL_FORMAT_MONO_16));
  guint32 period_us = 0;
  arv_fake_camera_read_register(camera_->fake(), ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US,
                                &period_us);
  EXPECT_EQ(period_us, 12500u);  // 80 Hz
  const CsvTable table = read_numeric_csv(dir + "/rec/frames.csv");
  ASSERT_EQ(table.rows(), 30u);
  EXPECT_NEAR(median_step(table.column("device_time_s")), 1.0 / 80, 1e-3);

  // Read back into the recording.
  const std::string json = read_text(dir + "/rec/recording.json");
  EXPECT_EQ(json_value(json, "pixel_format"), "Mono16") << json;
  EXPECT_EQ(json_value(json, "offset_x_px"), "32");
  EXPECT_EQ(json_value(json, "offset_y_px"), "16");
  EXPECT_EQ(json_value(json, "width_px"), "160");
  EXPECT_EQ(json_value(json, "height_px"), "96");
  EXPECT_EQ(json_value(json, "exposure_us"), "2500");
  EXPECT_EQ(json_value(json, "gain_dB"), "3");
  EXPECT_EQ(json_value(json, "frame_rate_hz"), "80");
  EXPECT_EQ(json_value(json, "trigger"), "free-run");
  EXPECT_EQ(json_value(json, "packet_size_bytes"), "4000");
  EXPECT_EQ(json_value(json, "stream_buffers"), "12");
  const std::size_t requested = json.find("\"requested_settings\": {");
  ASSERT_NE(requested, std::string::npos) << json;
  const std::string asked = json.substr(requested);
  EXPECT_EQ(json_value(asked, "exposure_us"), "2500 (scene " + scene + ")") << json;
  EXPECT_EQ(json_value(asked, "roi_px"), "32,16,160,96 (scene " + scene + ")");
  EXPECT_EQ(json_value(asked, "frame_rate_hz"), "80 (scene " + scene + ")");
  EXPECT_EQ(json_value(asked, "buffer_count"), "12 (scene " + scene + ")");

  // The frames themselves: the ROI's size, 16-bit, the camera's exact pixels.
  auto folder = open_source(dir + "/rec");
  const auto& ids = table.column("device_frame_id");
  for (std::size_t i = 0; i < 30; ++i) {
    std::optional<Frame> frame = folder->next();
    ASSERT_TRUE(frame.has_value());
    Frame as_received = *frame;
    as_received.device_frame_id = static_cast<std::int64_t>(ids[i]);
    ASSERT_TRUE(same(frame->image, expected_frame(as_received, "Mono16"))) << "frame " << i;
  }
}

// Flags given on the command line win over the scene, and the recording says which value came from where.
TEST_F(AravisTest, CommandLineFlagsOverrideTheScene) {
  DeviceView view;
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_and_observe, &view);
  const std::string dir = test_dir("scene_override");
  fs::create_directories(dir);
  const std::string scene = dir + "/rig.yaml";
  std::ofstream(scene) << kRigScene;
  Child cli({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--scene", scene, "--out", dir + "/rec", "--frames",
             "20", "--fps", "50", "--exposure-us", "4000", "--pixel-format", "Mono8", "--quiet"},
            dir + "/record.log");
  const int code = cli.wait(60);
  arv_fake_camera_set_fill_pattern(camera_->fake(), fill_pattern, nullptr);
  ASSERT_EQ(code, 0) << cli.log();
  EXPECT_EQ(view.exposure_us.load(), 4000u);
  EXPECT_EQ(view.width.load(), 160);  // still the scene's ROI
  EXPECT_EQ(view.format.load(), static_cast<std::uint32_t>(ARV_PIXEL_FORMAT_MONO_8));
  const CsvTable table = read_numeric_csv(dir + "/rec/frames.csv");
  ASSERT_EQ(table.rows(), 20u);
  EXPECT_NEAR(median_step(table.column("device_time_s")), 1.0 / 50, 1e-3);
  const std::string json = read_text(dir + "/rec/recording.json");
  EXPECT_EQ(json_value(json, "frame_rate_hz"), "50") << json;
  EXPECT_EQ(json_value(json, "exposure_us"), "4000");
  EXPECT_EQ(json_value(json, "pixel_format"), "Mono8");
  const std::string asked = json.substr(json.find("\"requested_settings\": {"));
  EXPECT_EQ(json_value(asked, "frame_rate_hz"), "50 (--fps)") << json;
  EXPECT_EQ(json_value(asked, "exposure_us"), "4000 (--exposure-us)");
  EXPECT_EQ(json_value(asked, "pixel_format"), "Mono8 (--pixel-format)");
  EXPECT_EQ(json_value(asked, "roi_px"), "32,16,160,96 (scene " + scene + ")");
}

// A value the scene allows but this camera does not: the message names the scene file and key, the value
// and the camera's range.
TEST_F(AravisTest, SceneValueTheCameraRefusesNamesTheSceneKey) {
  const std::string dir = test_dir("scene_refused");
  fs::create_directories(dir);
  const std::string scene = dir + "/rig.yaml";
  std::ofstream(scene) << "camera:\n  exposure_us: 50000000\n  roi_px: [0, 0, 128, 64]\n";
  const CameraSettings settings = parse_camera_settings(load_scene(scene));
  std::string message = error_of([&] { open_source("aravis:127.0.0.1", settings); });
  EXPECT_NE(message.find("'camera.exposure_us (scene " + scene + ")'"), std::string::npos) << message;
  EXPECT_NE(message.find("exposure 5e+07 us is outside this camera's range"), std::string::npos) << message;
  std::ofstream(scene) << "camera:\n  roi_px: [0, 0, 4096, 64]\n";
  message = error_of([&] { open_source("aravis:127.0.0.1", parse_camera_settings(load_scene(scene))); });
  EXPECT_NE(message.find("'camera.roi_px (scene " + scene + ")'"), std::string::npos) << message;
  EXPECT_NE(message.find("does not fit the sensor"), std::string::npos) << message;
  // Through the CLI: exit 1, nothing recorded.
  std::ofstream(scene) << "camera:\n  frame_rate_hz: 5000\n";
  Child cli(
      {TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--scene", scene, "--out", dir + "/rec", "--frames", "5"},
      dir + "/record.log");
  EXPECT_EQ(cli.wait(30), 1) << cli.log();
  EXPECT_NE(cli.log().find("'camera.frame_rate_hz (scene " + scene + ")': frame rate 5000 Hz is outside"),
            std::string::npos)
      << cli.log();
  EXPECT_FALSE(fs::exists(dir + "/rec/frames.csv"));
}

}  // namespace
}  // namespace tirstrain::capture
