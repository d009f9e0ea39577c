// File frame sources: image folders, patterns and videos; time from timestamps; bad input reported with
// the file and frame.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "core/error.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  return testing::scratch_dir("capture", name);
}

cv::Mat frame_image(int i, cv::Size size = {64, 48}, int type = CV_8UC1) {
  cv::Mat m(size, type, cv::Scalar(10 * i + 5));
  return m;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

using testing::error_of;

std::vector<Frame> read_all(FrameSource& source) {
  std::vector<Frame> frames;
  while (auto f = source.next()) frames.push_back(std::move(*f));
  return frames;
}

// An MPEG-4 clip of `frames` grey frames (frame_image(2i)) at 25 fps written by OpenCV into scratch(name);
// the path, or empty when the writer would not open.
std::string mp4v_clip(const std::string& name, int frames) {
  const std::string path = (scratch(name) / "clip.mp4").string();
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 25.0, {64, 48}, false);
  if (!writer.isOpened()) return {};
  for (int i = 0; i < frames; ++i) writer.write(frame_image(i * 2));
  return path;
}

bool has_ffmpeg() {
  return std::system("ffmpeg -version > /dev/null 2>&1") == 0;
}

// ffmpeg's test pattern (`pattern`: its size and rate) for `seconds`, encoded with `codec` options into
// scratch(name)/file; the path, or empty when ffmpeg failed (its command printed).
std::string ffmpeg_test_video(const std::string& name, const std::string& file, const std::string& pattern,
                              double seconds, const std::string& codec) {
  const std::string path = (scratch(name) / file).string();
  const std::string make = "ffmpeg -hide_banner -loglevel error -y -f lavfi -i testsrc=" + pattern + " -t " +
                           std::to_string(seconds) + " " + codec + " " + path;
  if (std::system(make.c_str()) == 0) return path;
  std::printf("failed: %s\n", make.c_str());
  return {};
}

TEST(ImageFolder, ReadsFramesAndTimestampsInOrder) {
  const fs::path dir = scratch("folder");
  fs::create_directories(dir / "frames");
  for (int i = 0; i < 5; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::imwrite((dir / "frames" / name).string(), frame_image(i));
  }
  write_text(dir / "frames.csv", "index,t_s\n0,0.0\n1,0.004\n2,0.0085\n3,0.0125\n4,0.0171\n");
  auto source = open_source(dir.string());
  EXPECT_EQ(source->frame_count(), 5);
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 5u);
  const double expected_t[] = {0.0, 0.004, 0.0085, 0.0125, 0.0171};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(frames[i].index, i);
    EXPECT_DOUBLE_EQ(frames[i].device_time_s, expected_t[i]);
    EXPECT_EQ(frames[i].status, FrameStatus::kOk);
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_EQ(frames[i].image.at<std::uint8_t>(0, 0), 10 * i + 5);
  }
  EXPECT_EQ(source->settings().at("time_measured"), "true");
  // The same through "file:" and through a printf pattern inside frames/.
  EXPECT_EQ(read_all(*open_source("file:" + dir.string())).size(), 5u);
  auto pattern = open_source((dir / "frames" / "%06d.png").string());
  const auto by_pattern = read_all(*pattern);
  ASSERT_EQ(by_pattern.size(), 5u);
  EXPECT_DOUBLE_EQ(by_pattern[3].device_time_s, 0.0125);
}

// A folder copied by macOS to a foreign disk holds "._NAME.png" metadata beside each image: not frames (they
// once became corrupt frames with the real ones' numbers, and "timestamps go backwards").
TEST(ImageFolder, HiddenFilesAreNotFrames) {
  const fs::path dir = scratch("hidden");
  fs::create_directories(dir);
  for (int i = 0; i < 3; ++i) {
    cv::imwrite((dir / (std::to_string(i) + ".png")).string(), frame_image(i));
    write_text(dir / ("._" + std::to_string(i) + ".png"), std::string("\x00\x05\x16\x07", 4) + "Mac OS X");
  }
  write_text(dir / "frames.csv", "index,t_s\n0,0.0\n1,0.01\n2,0.02\n");
  for (const std::string& input : {dir.string(), (dir / "*.png").string()}) {
    auto source = open_source(input);
    const auto frames = read_all(*source);
    ASSERT_EQ(frames.size(), 3u) << input;
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(frames[i].status, FrameStatus::kOk) << input;
      EXPECT_DOUBLE_EQ(frames[i].device_time_s, 0.01 * i) << input;
    }
  }
}

TEST(ImageFolder, SixteenBitTiffWithoutTimestampsSaysSo) {
  const fs::path dir = scratch("tiff16");
  for (int i = 0; i < 3; ++i)
    cv::imwrite((dir / ("f" + std::to_string(i) + ".tif")).string(),
                frame_image(1000 * i + 1, {32, 24}, CV_16UC1));
  auto source = open_source(dir.string());
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].image.type(), CV_16UC1);
  EXPECT_EQ(frames[2].image.at<std::uint16_t>(0, 0), 10 * 2001 + 5);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 2.0);
  EXPECT_EQ(source->settings().at("time_measured"), "false");
  EXPECT_NE(source->describe().find("no frames.csv"), std::string::npos);
}

TEST(ImagePattern, GlobAndNaturalOrder) {
  const fs::path dir = scratch("glob");
  for (int i : {1, 2, 10, 11})
    cv::imwrite((dir / ("img" + std::to_string(i) + ".png")).string(), frame_image(i));
  cv::imwrite((dir / "other.png").string(), frame_image(0));
  auto source = open_source((dir / "img*.png").string());
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[2].image.at<std::uint8_t>(0, 0), 105);  // img10 after img2
  EXPECT_EQ(frames[2].device_frame_id, 10);
  EXPECT_TRUE(natural_less("a2.png", "a10.png"));
  EXPECT_FALSE(natural_less("a10.png", "a2.png"));
  EXPECT_NE(error_of([&] { open_source((dir / "nothing_*.png").string()); }).find("no files match"),
            std::string::npos);
}

TEST(ImageFolder, MissingFileBecomesGapWithFrameNumbers) {
  const fs::path dir = scratch("gap");
  for (int i : {0, 1, 3})
    cv::imwrite((dir / ("frame_" + std::to_string(i) + ".png")).string(), frame_image(i));
  write_text(dir / "frames.csv", "index,t_s\n0,0\n1,0.01\n2,0.02\n3,0.03\n");
  const auto frames = read_all(*open_source(dir.string()));
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].status, FrameStatus::kGapBefore);
  EXPECT_EQ(frames[2].frames_lost_before, 1);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.03);
}

// Names counted from 1 while frames.csv's index counts from 0 (a common camera export), with one file
// lost: rows are matched through the names' origin, so the lost file is a gap and the later frames keep
// their own times. Numbers that match no origin are matched by position only with one row per image.
TEST(ImageFolder, NamesFromAnotherOriginKeepTheirTimesAcrossALostFile) {
  const fs::path dir = scratch("origin");
  for (int i : {1, 2, 4, 5})
    cv::imwrite((dir / ("img" + std::to_string(i) + ".png")).string(), frame_image(i));
  write_text(dir / "frames.csv", "index,t_s\n0,0\n1,0.01\n2,0.02\n3,0.03\n4,0.04\n");
  const auto frames = read_all(*open_source(dir.string()));
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_DOUBLE_EQ(frames[1].device_time_s, 0.01);
  EXPECT_EQ(frames[2].status, FrameStatus::kGapBefore);
  EXPECT_EQ(frames[2].frames_lost_before, 1);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.03);
  EXPECT_DOUBLE_EQ(frames[3].device_time_s, 0.04);

  write_text(dir / "frames.csv", "index,t_s\n10,0\n12,0.01\n14,0.02\n16,0.03\n18,0.04\n");
  EXPECT_NE(error_of([&] { open_source(dir.string()); }).find("not one per image"), std::string::npos);
}

// Without a frames.csv, --frame-rate-Hz times an image sequence; with one, it is refused (one clock). A
// trial's frames/ folder given itself finds the frames.csv beside it.
TEST(ImageFolder, FrameRateTimesASequenceWithoutFramesCsv) {
  const fs::path trial = scratch("rate");
  fs::create_directories(trial / "frames");
  for (int i = 0; i < 3; ++i)
    cv::imwrite((trial / "frames" / ("f" + std::to_string(i) + ".png")).string(), frame_image(i));
  const FileSourceOptions at_500{.frame_rate_Hz = 500.0};
  auto frames = read_all(*open_file_source((trial / "frames").string(), at_500));
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 2.0 / 500.0);

  write_text(trial / "frames.csv", "index,t_s\n0,0\n1,0.011\n2,0.023\n");
  frames = read_all(*open_file_source((trial / "frames").string()));
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.023);
  EXPECT_NE(error_of([&] { open_file_source((trial / "frames").string(), at_500); }).find("one clock"),
            std::string::npos);
}

// A row lost from frames.csv (or an image added to the folder) is named, not the whole numbering blamed.
TEST(ImageFolder, AnImageWithoutARowIsNamed) {
  const fs::path dir = scratch("row_lost");
  for (int i = 0; i < 8; ++i)
    cv::imwrite((dir / ("frame_" + std::to_string(i) + ".png")).string(), frame_image(i));
  write_text(dir / "frames.csv", "index,t_s\n0,0\n1,0.01\n2,0.02\n4,0.04\n5,0.05\n6,0.06\n7,0.07\n");
  const std::string why = error_of([&] { open_source(dir.string()); });
  EXPECT_NE(why.find("has no row for 1 of the 8 images: frame_3.png"), std::string::npos) << why;
  // Rows for the first 3 images only: the other 5 are named, not the numbering called unmatched.
  write_text(dir / "frames.csv", "index,t_s\n0,0\n1,0.01\n2,0.02\n");
  const std::string short_csv = error_of([&] { open_source(dir.string()); });
  EXPECT_NE(short_csv.find("has no row for 5 of the 8 images: frame_3.png, frame_4.png"), std::string::npos)
      << short_csv;
}

// A recording `tirstrain record` made from a source without a clock keeps the frame number in t_s and says
// so in recording.json: its times are not taken for measured ones, and --frame-rate-Hz may time it.
TEST(ImageFolder, ARecordingOfASourceWithoutAClockIsNotTimed) {
  const fs::path rec = scratch("clockless");
  fs::create_directories(rec / "frames");
  for (int i = 0; i < 3; ++i)
    cv::imwrite((rec / "frames" / ("00000" + std::to_string(i) + ".tif")).string(), frame_image(i));
  write_text(rec / "frames.csv", "index,t_s\n0,0\n1,1\n2,2\n");
  write_text(rec / "recording.json",
             R"({"format": "tirstrain-recording", "settings": {"time_measured": "false"}})");
  auto source = open_file_source(rec.string());
  EXPECT_EQ(source->settings().at("time_measured"), "false");
  EXPECT_NE(source->describe().find("the recorded source had no clock"), std::string::npos)
      << source->describe();
  source = open_file_source(rec.string(), FileSourceOptions{.frame_rate_Hz = 100.0});
  EXPECT_EQ(source->settings().at("time_measured"), "true");
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.02);
}

TEST(ImageFolder, CorruptMiddleFrameIsMarkedNotFatal) {
  const fs::path dir = scratch("corrupt");
  for (int i = 0; i < 4; ++i)
    cv::imwrite((dir / ("f" + std::to_string(i) + ".png")).string(), frame_image(i));
  write_text(dir / "f2.png", "this is not a PNG");
  const auto frames = read_all(*open_source(dir.string()));
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[1].status, FrameStatus::kOk);
  EXPECT_EQ(frames[2].status, FrameStatus::kCorrupt);
  EXPECT_TRUE(frames[2].image.empty());
  EXPECT_NE(frames[2].origin.find("f2.png"), std::string::npos);
  EXPECT_EQ(frames[3].status, FrameStatus::kOk);
}

// libjpeg decodes a JPEG cut short (grey rows for what is missing) and only prints a warning: a file
// without its end-of-image marker is a corrupt frame, a whole one with bytes after the marker is not.
TEST(ImageFolder, JpegCutShortIsACorruptFrame) {
  const fs::path dir = scratch("jpeg_cut");
  for (int i = 0; i < 3; ++i)
    cv::imwrite((dir / ("f" + std::to_string(i) + ".jpg")).string(), frame_image(i));
  const fs::path cut = dir / "f1.jpg";
  fs::resize_file(cut, fs::file_size(cut) * 6 / 10);
  std::ofstream(dir / "f2.jpg", std::ios::app | std::ios::binary) << "trailer";
  const auto frames = read_all(*open_source(dir.string()));
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].status, FrameStatus::kOk);
  EXPECT_EQ(frames[1].status, FrameStatus::kCorrupt);
  EXPECT_TRUE(frames[1].image.empty());
  EXPECT_EQ(frames[2].status, FrameStatus::kOk);
  EXPECT_EQ(frames[2].image.cols, 64);
}

// Found by fuzz_image_sequence (tests/fuzz/corpus): a TIFF header 0 pixels wide makes OpenCV throw out of
// imread instead of returning nothing; it is a corrupt frame like any other undecodable file.
TEST(ImageFolder, TiffZeroPixelsWideIsACorruptFrame) {
  const fs::path dir = scratch("tiff_width_0");
  fs::copy_file(
      fs::path(TIRSTRAIN_SOURCE_DIR) / "tests/fuzz/corpus/fuzz_image_sequence/regression-tiff-width-0.tif",
      dir / "000000.tif");
  cv::imwrite((dir / "000001.tif").string(), frame_image(1));
  auto source = open_source(dir.string());
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].status, FrameStatus::kCorrupt);
  EXPECT_TRUE(frames[0].image.empty());
  EXPECT_EQ(frames[1].status, FrameStatus::kOk);
  EXPECT_EQ(frames[1].image.cols, 64);
}

TEST(ImageFolder, DifferentFrameSizeNamesFileAndFrame) {
  const fs::path dir = scratch("sizes");
  cv::imwrite((dir / "f0.png").string(), frame_image(0));
  cv::imwrite((dir / "f1.png").string(), frame_image(1));
  cv::imwrite((dir / "f2.png").string(), frame_image(2, {80, 48}));
  auto source = open_source(dir.string());
  source->next();
  source->next();
  const std::string message = error_of([&] { source->next(); });
  EXPECT_NE(message.find("f2.png"), std::string::npos) << message;
  EXPECT_NE(message.find("frame 2"), std::string::npos) << message;
  EXPECT_NE(message.find("80x48"), std::string::npos) << message;
}

TEST(ImageFolder, BackwardTimestampsNameFileAndFrame) {
  const fs::path dir = scratch("backwards");
  for (int i = 0; i < 3; ++i)
    cv::imwrite((dir / ("f" + std::to_string(i) + ".png")).string(), frame_image(i));
  write_text(dir / "frames.csv", "index,t_s\n0,0.0\n1,0.02\n2,0.01\n");
  const std::string message = error_of([&] { open_source(dir.string()); });
  EXPECT_NE(message.find("frames.csv"), std::string::npos) << message;
  EXPECT_NE(message.find("frame 2"), std::string::npos) << message;
  EXPECT_NE(message.find("backwards"), std::string::npos) << message;
  EXPECT_NE(message.find("f2.png"), std::string::npos) << message;
  write_text(dir / "frames.csv", "index,t_s\n0,0.0\n1,0.01\n2,0.01\n");
  const std::string equal = error_of([&] { open_source(dir.string()); });
  EXPECT_NE(equal.find("two frames have the same timestamp"), std::string::npos) << equal;
}

TEST(OpenSource, MissingInputAndCameraSchemes) {
  const std::string missing = (fs::path(TIRSTRAIN_TEST_TMP) / "capture" / "does_not_exist").string();
  const std::string message = error_of([&] { open_source(missing); });
  EXPECT_NE(message.find("does_not_exist"), std::string::npos) << message;
  EXPECT_NE(message.find("no such file"), std::string::npos) << message;
  // Camera schemes reach their backends (tests/capture_v4l2, tests/vm): a missing camera is a clear error.
  EXPECT_NE(error_of([] { open_source("libcamera:cam0"); }).find("libcamera:cam0"), std::string::npos);
  EXPECT_NE(error_of([] { open_source("v4l2:/dev/video97"); }).find("cannot open V4L2 device"),
            std::string::npos);
  const fs::path empty = scratch("empty");
  EXPECT_NE(error_of([&] { open_source(empty.string()); }).find("no image files"), std::string::npos);
  // A mistyped scheme is named, with the schemes that exist.
  const std::string scheme = error_of([] { open_source("aravsi:Fake"); });
  EXPECT_NE(scheme.find("unknown source scheme 'aravsi:'"), std::string::npos) << scheme;
  for (const char* known : {"aravis:", "v4l2:", "libcamera:", "file:"})
    EXPECT_NE(scheme.find(known), std::string::npos) << scheme;
}

TEST(VideoFile, ReadsFramesWithContainerTimestamps) {
  const std::string path = mp4v_clip("video", 10);
  ASSERT_FALSE(path.empty());
  auto source = open_source(path);
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 10u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_NEAR(frames[i].device_time_s, i / 25.0, 1e-3);
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
  }
  EXPECT_NEAR(frames[5].image.at<std::uint8_t>(20, 20), 105, 4);
}

// H.264 with B-frames as ffmpeg writes it by default: OpenCV's position reads 0 for the frames drained
// from the decoder at the end, so time goes on from the frame rate there, and the source says so.
TEST(VideoFile, BFramesH264KeepsTimeIncreasing) {
  if (!has_ffmpeg()) GTEST_SKIP() << "ffmpeg is not installed";
  const std::string path = ffmpeg_test_video("bframes", "bframes.mp4", "size=160x120:rate=20", 1.0,
                                             "-c:v libx264 -bf 2 -pix_fmt yuv420p");
  ASSERT_FALSE(path.empty());
  auto source = open_source(path);
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 20u);
  for (std::size_t i = 0; i < frames.size(); ++i)
    EXPECT_NEAR(frames[i].device_time_s, static_cast<double>(i) / 20.0, 1e-6) << "frame " << i;
  const std::string time_source = source->settings().at("time_source");
  EXPECT_NE(time_source.find("then frame index / nominal 20 fps"), std::string::npos) << time_source;
}

// A high-speed camera's export plays back at another rate than it recorded: the rate given replaces the
// container's times, and the source says so.
TEST(VideoFile, AGivenFrameRateReplacesTheContainersTimes) {
  const std::string path = mp4v_clip("video_rate", 6);
  ASSERT_FALSE(path.empty());
  auto source = open_file_source(path, FileSourceOptions{.frame_rate_Hz = 1000.0});
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 6u);
  for (std::size_t i = 0; i < frames.size(); ++i)
    EXPECT_NEAR(frames[i].device_time_s, static_cast<double>(i) / 1000.0, 1e-12) << "frame " << i;
  const std::string time_source = source->settings().at("time_source");
  EXPECT_NE(time_source.find("frame index / 1000 Hz (--frame-rate-Hz, in place of the container's timestamps "
                             "at a nominal 25 fps)"),
            std::string::npos)
      << time_source;
}

// The video reader decodes to 8 bits: a 16-bit video (a 10-bit camera's codes in gray16le) would lose the
// camera's low bits, so it is refused with the way round it.
TEST(VideoFile, SixteenBitVideoIsRefusedWithTheWayRoundIt) {
  if (!has_ffmpeg()) GTEST_SKIP() << "ffmpeg is not installed";
  const std::string path =
      ffmpeg_test_video("video16", "gray16.mkv", "size=64x48:rate=20", 0.2, "-c:v ffv1 -pix_fmt gray16le");
  ASSERT_FALSE(path.empty());
  const std::string message = error_of([&] { open_source(path); });
  EXPECT_NE(
      message.find("gray16.mkv: the video stores 16-bit samples, which the video reader here decodes to 8 "
                   "bits"),
      std::string::npos)
      << message;
  EXPECT_NE(message.find("-pix_fmt gray16le frames/%06d.png"), std::string::npos) << message;
}

TEST(VideoFile, UndecodableVideoIsAnError) {
  const fs::path dir = scratch("badvideo");
  write_text(dir / "broken.mp4", std::string(4096, 'x'));
  const std::string message = error_of([&] { open_source((dir / "broken.mp4").string()); });
  EXPECT_NE(message.find("broken.mp4"), std::string::npos) << message;
  EXPECT_NE(message.find("video"), std::string::npos) << message;
}

}  // namespace
}  // namespace tirstrain::capture
