// The Aravis backend against real GigE Vision peers (Aravis' in-process ArvGvFakeCamera serving our own
// images, and the arv-fake-gv-camera-0.8 process), all inside a loopback-only network namespace (see
// netns_main.cpp). Each test starts its own fresh camera.
#include <arv.h>
#include <gtest/gtest.h>
#include <sys/mount.h>

#include <opencv2/imgproc.hpp>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>

#include "capture/aravis_source.hpp"
#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "tests/capture_aravis/netns.hpp"

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

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

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
  EXPECT_EQ(u.unwrap(65535), 65535 + 65535);
  EXPECT_EQ(u.unwrap(3), 65535 + 65535 + 3);  // wrap with a loss (ids 1, 2 lost)
  FrameIdUnwrapper wide;
  EXPECT_EQ(wide.unwrap(70000), 70000);  // above 16 bits: taken as is
  EXPECT_EQ(wide.unwrap(70001), 70001);
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
TEST_F(AravisProcessTest, PacketLossMarksFramesIncompleteAndNeverPassesThemOn) {
  FakeCameraProcess camera("packet_loss", 5);
  ASSERT_TRUE(camera.ready());
  const std::string dir = test_dir("packet_loss");
  Child cli({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--out", dir, "--frames", "60", "--fps", "100",
             "--roi", "0,0,256,128", "--packet-size", "1400", "--format", "pgm"},
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
  EXPECT_EQ(table.rows(), 60u);
  EXPECT_GT(incomplete, 0u) << "0.5 % packet loss on ~25 packets per frame should spoil some frames";
  EXPECT_GT(good, 0u);
  EXPECT_NE(read_text(dir + "/recording.json").find("\"frames_incomplete\": " + std::to_string(incomplete)),
            std::string::npos);
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
}

// Without a display `live` must say so (OpenCV's Qt backend would abort the process instead).
TEST_F(AravisProcessTest, LiveWithoutDisplayAsksForNoWindow) {
  const std::string dir = test_dir("live_no_display");
  Child cli({"env", "-u", "DISPLAY", "-u", "WAYLAND_DISPLAY", "-u", "QT_QPA_PLATFORM", TIRSTRAIN_CLI, "live",
             "aravis:127.0.0.1", "--frames", "3"},
            dir + ".log");
  EXPECT_EQ(cli.wait(30), 1) << cli.log();
  EXPECT_NE(cli.log().find("use --no-window on headless machines"), std::string::npos) << cli.log();
}

TEST_F(AravisProcessTest, CliReportsBadUriAndBadOptions) {
  const std::string dir = test_dir("cli_errors");
  Child bad_roi({TIRSTRAIN_CLI, "record", "aravis:127.0.0.1", "--out", dir, "--roi", "1,2,3"},
                dir + ".1.log");
  EXPECT_EQ(bad_roi.wait(30), 1);
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
// processing the synthesised frames directly (only the time axis differs: the camera's clock).
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
  const CsvTable direct = read_numeric_csv(dir + "/processed-synth/frames.csv");
  const CsvTable via_camera = read_numeric_csv(dir + "/processed-recording/frames.csv");
  ASSERT_EQ(direct.names, via_camera.names);
  ASSERT_EQ(direct.rows(), via_camera.rows());
  for (std::size_t j = 0; j < direct.names.size(); ++j) {
    if (direct.names[j] == "t_s") continue;  // the camera's clock, not the synthetic one
    for (std::size_t i = 0; i < direct.rows(); ++i)
      EXPECT_EQ(direct.columns[j][i], via_camera.columns[j][i]) << direct.names[j] << " at frame " << i;
  }
}

}  // namespace
}  // namespace tirstrain::capture
