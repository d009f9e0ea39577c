// The latency histogram behind `live`'s capture -> display summary: quantiles within its 1 % bins, exact max.
#include <gtest/gtest.h>

#include "capture/live.hpp"

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

}  // namespace
}  // namespace tirstrain::capture
