// `record --overwrite` into a folder that holds a recording: the earlier recording stays whole while the new
// one is captured (beside it, in DIR.partial) and is replaced only when the new one ends; a leftover
// DIR.partial from a killed run is never deleted. The frames come from a scripted FrameSource that looks at
// the disk while the recorder runs.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>

#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

class WatchedSource final : public FrameSource {
 public:
  WatchedSource(int frames, int level, std::function<void(int)> before_frame = {})
      : frames_(frames), level_(level), before_frame_(std::move(before_frame)) {}
  std::optional<Frame> next() override {
    if (at_ >= frames_) return std::nullopt;
    if (before_frame_) before_frame_(at_);
    Frame f;
    f.index = at_;
    f.device_frame_id = at_;
    f.device_time_s = 0.01 * at_;
    f.host_time_s = 0.01 * at_;
    f.image = cv::Mat(8, 8, CV_8UC1, cv::Scalar(level_));
    ++at_;
    return f;
  }
  std::string describe() const override { return "watched"; }

 private:
  int frames_, level_;
  std::function<void(int)> before_frame_;
  int at_ = 0;
};

std::size_t rows_of(const fs::path& dir) {
  return read_numeric_csv((dir / "frames.csv").string()).rows();
}

RecordOptions options_for(const fs::path& dir, bool overwrite) {
  RecordOptions options;
  options.out_dir = dir.string();
  options.format = ImageFormat::kPgm;
  options.overwrite = overwrite;
  return options;
}

TEST(RecorderOverwrite, EarlierRecordingStaysWholeUntilTheNewOneEnds) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "capture_recorder" / "overwrite";
  fs::remove_all(dir);
  fs::remove_all(dir.string() + ".partial");
  WatchedSource first(5, 10);
  ASSERT_TRUE(record(first, options_for(dir, false)).ok());
  ASSERT_EQ(rows_of(dir), 5u);

  std::size_t earlier_rows_seen = 0;
  bool staging_seen = false;
  WatchedSource second(3, 20, [&](int frame) {
    if (frame != 2) return;
    earlier_rows_seen = rows_of(dir);  // mid-recording: the earlier recording, untouched
    staging_seen = fs::exists(dir.string() + ".partial/frames.csv");
  });
  const RecordReport report = record(second, options_for(dir, true));
  ASSERT_TRUE(report.ok()) << report.error;
  EXPECT_EQ(earlier_rows_seen, 5u);
  EXPECT_TRUE(staging_seen);
  EXPECT_EQ(rows_of(dir), 3u);
  EXPECT_TRUE(fs::exists(dir / "recording.json"));
  EXPECT_FALSE(fs::exists(dir.string() + ".partial"));
}

// A --overwrite run that stops on an error keeps both recordings, and says the new frames are in DIR.partial.
TEST(RecorderOverwrite, AFailedRunSaysWhereItsFramesAre) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "capture_recorder" / "overwrite_failed";
  fs::remove_all(dir);
  fs::remove_all(dir.string() + ".partial");
  WatchedSource first(5, 10);
  ASSERT_TRUE(record(first, options_for(dir, false)).ok());
  class FailingSource final : public FrameSource {  // frame 2 cannot be read: the run stops there
   public:
    std::optional<Frame> next() override {
      if (at_ == 2) throw Error("frame 2 cannot be read");
      Frame f;
      f.index = f.device_frame_id = at_;
      f.device_time_s = f.host_time_s = 0.01 * at_;
      f.image = cv::Mat(8, 8, CV_8UC1, cv::Scalar(30));
      ++at_;
      return f;
    }
    std::string describe() const override { return "failing"; }

   private:
    int at_ = 0;
  } second;
  const RecordReport report = record(second, options_for(dir, true));
  EXPECT_FALSE(report.ok());
  EXPECT_EQ(report.folder, dir.string() + ".partial");
  EXPECT_EQ(rows_of(dir), 5u);
  EXPECT_TRUE(fs::exists(dir.string() + ".partial/frames.csv"));
}

TEST(RecorderOverwrite, UnfinishedRecordingOfAnEarlierRunIsNeverDeleted) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "capture_recorder" / "overwrite_leftover";
  const fs::path leftover = dir.string() + ".partial";
  fs::remove_all(dir);
  fs::remove_all(leftover);
  WatchedSource first(4, 10);
  ASSERT_TRUE(record(first, options_for(dir, false)).ok());
  WatchedSource killed(2, 30);  // what a killed --overwrite run leaves: its frames in DIR.partial
  ASSERT_TRUE(record(killed, options_for(leftover, false)).ok());

  WatchedSource third(3, 20);
  try {
    record(third, options_for(dir, true));
    FAIL() << "a leftover DIR.partial was not refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("unfinished recording of an earlier run"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(leftover.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(rows_of(dir), 4u);
  EXPECT_EQ(rows_of(leftover), 2u);
}

}  // namespace
}  // namespace tirstrain::capture
