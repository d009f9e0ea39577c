#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "contact/segmenter.hpp"
#include "core/error.hpp"

namespace tirstrain::contact {
namespace {

// The message of the Error that `options` raise when a segmenter is made with them ("" if none).
std::string rejection(const SegmenterOptions& options) {
  try {
    ContactSegmenter segmenter(options);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SegmenterOptions, DefaultsAndPresetsPass) {
  EXPECT_NO_THROW(SegmenterOptions{}.check());
  for (const auto preset :
       {SegmentationPreset::fast, SegmentationPreset::balanced, SegmentationPreset::accurate})
    EXPECT_NO_THROW(with_preset({}, preset).check());
}

TEST(SegmenterOptions, OutOfRangeValuesAreNamedWhenApplied) {
  SegmenterOptions options;
  options.crest_edge_level = 1.5;
  EXPECT_NE(rejection(options).find("crest_edge_level = 1.5"), std::string::npos) << rejection(options);
  options = {};
  options.px_per_mm = 0.0;
  EXPECT_NE(rejection(options).find("px_per_mm"), std::string::npos);
  options = {};
  options.ridge_period_px = -3.0;
  EXPECT_NE(rejection(options).find("ridge_period_px"), std::string::npos);
  options = {};
  options.max_period_mm = 0.2;  // below min_period_mm
  EXPECT_NE(rejection(options).find("max_period_mm"), std::string::npos);
  options = {};
  options.polarity = 2;
  EXPECT_NE(rejection(options).find("polarity"), std::string::npos);
  options = {};
  options.spike_periods = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(rejection(options).find("spike_periods"), std::string::npos);
  options = {};
  options.full_frame_every = 0;
  EXPECT_NE(rejection(options).find("full_frame_every"), std::string::npos);
  options = {};
  options.exclude_px = cv::Rect(10, 10, -5, 20);
  EXPECT_NE(rejection(options).find("exclude_px"), std::string::npos);
  // The edge of each range is inside it.
  options = {};
  options.crest_edge_level = 1.0;
  options.border_average_snr = 0.0;
  options.downsample = 0;
  EXPECT_EQ(rejection(options), "");
}

}  // namespace
}  // namespace tirstrain::contact
