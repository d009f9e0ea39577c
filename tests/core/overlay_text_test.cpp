// Status text on video frames: sized to the frame, on a dark backdrop, and away from a band kept clear.
#include <gtest/gtest.h>

#include "core/overlay_text.hpp"

namespace tirstrain {
namespace {

TEST(OverlayText, StatusBlockLeavesTheTopWhenABandIsThere) {
  const cv::Size size(640, 512);
  EXPECT_EQ(OverlayText(size).status_block(6).y, 0);
  const cv::Rect band_top(0, 0, 640, 56), band_bottom(0, 456, 640, 56);
  const cv::Rect moved = OverlayText(size, band_top).status_block(6);
  EXPECT_EQ(moved.y + moved.height, 512) << "at the bottom edge";
  EXPECT_EQ((moved & band_top).area(), 0);
  EXPECT_EQ(OverlayText(size, band_bottom).status_block(6).y, 0)
      << "a band at the bottom leaves the top free";
}

TEST(OverlayText, FontGrowsWithTheFrameAndTextSitsOnABackdrop) {
  EXPECT_DOUBLE_EQ(OverlayText({640, 512}).font_scale(), 0.5);
  EXPECT_DOUBLE_EQ(OverlayText({1280, 1024}).font_scale(), 1.0);
  EXPECT_GT(OverlayText({1280, 1024}).line_height_px(), 1.9 * OverlayText({640, 512}).line_height_px());
  cv::Mat bright(512, 640, CV_8UC3, cv::Scalar(230, 230, 230));
  const OverlayText text(bright.size());
  text.label(bright, {100, 100}, "frame 12");
  // The box's top-left corner is darkened to 230 × 0.35 ≈ 80, the glyphs inside are white, and the frame
  // beside the box is left as it was.
  const cv::Mat box = bright(cv::Rect(96, 80, 60, 26));
  double lowest = 0, highest = 0;
  cv::minMaxLoc(box.reshape(1), &lowest, &highest);
  EXPECT_NEAR(bright.at<cv::Vec3b>(86, 99)[0], 80, 2);
  EXPECT_GT(highest, 240);
  EXPECT_EQ(bright.at<cv::Vec3b>(100, 90)[0], 230);
  EXPECT_EQ(bright.at<cv::Vec3b>(120, 120)[0], 230);
}

}  // namespace
}  // namespace tirstrain
