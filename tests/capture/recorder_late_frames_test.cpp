// The recorder with frames that a camera delivers out of order (Aravis hands over a frame that was stuck in
// its buffers after newer ones; the source marks it frames_lost_before = -1): it must land at its own place
// in the device sequence, and the loss counts must still add up. The frames come from a scripted FrameSource
// because no real camera can be made to deliver late on demand; the Aravis source's side (marking late
// frames, unwrapping their ids) is tested against the fake camera in tests/capture_aravis.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"
#include "core/csv.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

class ScriptedSource final : public FrameSource {
 public:
  explicit ScriptedSource(std::vector<Frame> frames) : frames_(std::move(frames)) {}
  std::optional<Frame> next() override {
    if (at_ >= frames_.size()) return std::nullopt;
    return frames_[at_++];
  }
  std::string describe() const override { return "scripted"; }

 private:
  std::vector<Frame> frames_;
  std::size_t at_ = 0;
};

Frame frame(std::int64_t index, std::int64_t id, std::int64_t lost_before, FrameStatus status) {
  Frame f;
  f.index = index;
  f.device_frame_id = id;
  f.device_time_s = 0.01 * static_cast<double>(id);
  f.host_time_s = 0.01 * static_cast<double>(index);
  f.frames_lost_before = lost_before;
  f.status = status;
  f.image = cv::Mat(8, 8, CV_8UC1, cv::Scalar(static_cast<double>(id % 200)));
  return f;
}

TEST(RecorderLateFramesTest, LateFrameTakesItsOwnPlaceAndLossesAddUp) {
  // Device ids 100..107: 103 and 104 come after 105 (one complete, one incomplete), 106 never comes.
  std::vector<Frame> frames = {
      frame(0, 100, 0, FrameStatus::kOk),        frame(1, 101, 0, FrameStatus::kOk),
      frame(2, 102, 0, FrameStatus::kOk),        frame(3, 105, 2, FrameStatus::kGapBefore),
      frame(4, 103, -1, FrameStatus::kOk),       frame(5, 104, -1, FrameStatus::kIncomplete),
      frame(6, 107, 1, FrameStatus::kGapBefore),
  };
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "capture_recorder" / "late";
  fs::remove_all(dir);
  ScriptedSource source(frames);
  RecordOptions options;
  options.out_dir = dir.string();
  options.format = ImageFormat::kPgm;
  const RecordReport report = record(source, options);
  ASSERT_TRUE(report.ok()) << report.error;
  EXPECT_EQ(report.counts.frames_received, 7);
  EXPECT_EQ(report.counts.frames_saved, 6);
  EXPECT_EQ(report.counts.frames_incomplete, 1);
  EXPECT_EQ(report.counts.frames_lost_device, 1);  // only 106 was never received
  const CsvTable table = read_numeric_csv((dir / "frames.csv").string());
  ASSERT_EQ(table.rows(), 7u);
  const std::vector<double> expected_index = {0, 1, 2, 5, 3, 4, 7};
  EXPECT_EQ(table.column("index"), expected_index);
  for (const int position : {0, 1, 2, 3, 5, 7}) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.pgm", position);
    EXPECT_TRUE(fs::exists(dir / "frames" / name)) << name;
  }
  EXPECT_FALSE(fs::exists(dir / "frames" / "000004.pgm"));  // incomplete: no image
  EXPECT_FALSE(fs::exists(dir / "frames" / "000006.pgm"));  // never received
  // Read back as a folder: in device order, the late frame in its place, the holes reported as gaps.
  auto folder = open_source(dir.string());
  std::vector<std::int64_t> ids;
  while (std::optional<Frame> f = folder->next()) {
    ids.push_back(f->device_frame_id);
    EXPECT_EQ(f->image.at<std::uint8_t>(0, 0), static_cast<std::uint8_t>((100 + f->device_frame_id) % 200));
  }
  EXPECT_EQ(ids, (std::vector<std::int64_t>{0, 1, 2, 3, 5, 7}));
}

}  // namespace
}  // namespace tirstrain::capture
