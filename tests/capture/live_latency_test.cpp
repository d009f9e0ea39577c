// The latency histogram behind `live`'s capture -> display summary: quantiles within its 1 % bins, exact max.
#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>

#include "capture/live.hpp"
#include "core/csv.hpp"

namespace tirstrain::capture {
namespace {

TEST(LatencyHistogramTest, QuantilesWithinOnePercentAndExactMax) {
  LatencyHistogram h;
  EXPECT_EQ(summarize(h).frames, 0);
  EXPECT_EQ(h.quantile_ms(0.5), 0.0);
  // 1..1000 ms, once each: median 500 ms, p95 950 ms, max 1000 ms.
  for (int i = 1; i <= 1000; ++i) h.add(i * 1e-3);
  const LatencySummary s = summarize(h);
  EXPECT_EQ(s.frames, 1000);
  EXPECT_NEAR(s.median_ms, 500.0, 5.0);
  EXPECT_NEAR(s.p95_ms, 950.0, 9.5);
  EXPECT_DOUBLE_EQ(s.max_ms, 1000.0);
  // A few slow frames do not move the median; they set the max.
  LatencyHistogram g;
  for (int i = 0; i < 99; ++i) g.add(2e-3);
  g.add(0.25);
  EXPECT_NEAR(g.quantile_ms(0.5), 2.0, 0.02);
  EXPECT_NEAR(g.quantile_ms(0.95), 2.0, 0.02);
  EXPECT_DOUBLE_EQ(g.max_ms(), 250.0);
  // Clock offsets can make a sample negative: counted in the lowest bin, never a crash.
  g.add(-1e-3);
  EXPECT_EQ(g.count(), 101);
}

// Five frames recorded 0.1 s apart, replayed at their recorded rate while `live --record` records them: the
// recording receives them as the camera did, over at least 0.4 s (a lower bound: sleeping is never shorter),
// not as fast as they are read.
TEST(LiveReplay, RecordedRateHoldsForTheRecordingToo) {
  class Timed final : public FrameSource {
   public:
    std::optional<Frame> next() override {
      if (at_ >= 5) return std::nullopt;
      Frame f;
      f.index = f.device_frame_id = at_;
      f.device_time_s = 0.1 * at_;
      f.image = cv::Mat(8, 8, CV_8UC1, cv::Scalar(10 * at_));
      ++at_;
      return f;
    }
    std::string describe() const override { return "timed"; }

   private:
    int at_ = 0;
  } source;
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "capture_live" / "paced";
  std::filesystem::remove_all(dir);
  LiveOptions options;
  options.window = false;
  options.record_dir = dir.string();
  options.record.format = ImageFormat::kPgm;
  options.play_at_recorded_rate = true;
  const LiveReport report = run_live(source, options);
  ASSERT_TRUE(report.error.empty()) << report.error;
  ASSERT_EQ(report.record.counts.frames_saved, 5);
  const CsvTable csv = read_numeric_csv((dir / "frames.csv").string());
  const std::vector<double>& host_s = csv.column("host_time_s");
  ASSERT_EQ(host_s.size(), 5u);
  EXPECT_GE(host_s.back() - host_s.front(), 0.4 - 1e-3);
}

}  // namespace
}  // namespace tirstrain::capture
