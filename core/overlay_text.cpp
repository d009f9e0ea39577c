#include "core/overlay_text.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace tirstrain {
namespace {

// Status lines the block is sized for when deciding where it goes (frame, contact, tracks, strain,
// channels, and a note).
constexpr int kBlockSlots = 6;

}  // namespace

OverlayText::OverlayText(cv::Size frame_size, std::optional<cv::Rect> keep_clear) : frame_size_(frame_size) {
  // 0.5 at 640 px wide: about 1/58 of the width per character height, as at every other width; never so
  // small that a downscaled view loses it.
  font_scale_ = std::max(0.45, 0.5 * frame_size.width / 640.0);
  thickness_ = std::max(1, static_cast<int>(std::lround(font_scale_ * 2.0)));
  int baseline = 0;
  const cv::Size glyph = cv::getTextSize("Ag", cv::FONT_HERSHEY_SIMPLEX, font_scale_, thickness_, &baseline);
  line_height_px_ = glyph.height + baseline + static_cast<int>(std::lround(8 * font_scale_));
  if (keep_clear) block_at_bottom_ = (status_block(kBlockSlots) & *keep_clear).area() > 0;
}

cv::Rect OverlayText::status_block(int slots) const {
  const int height = std::min(frame_size_.height, slots * line_height_px_ + line_height_px_ / 2);
  const int y = block_at_bottom_ ? frame_size_.height - height : 0;
  return {0, y, frame_size_.width, height};
}

void OverlayText::label(cv::Mat& bgr, cv::Point origin, const std::string& text, cv::Scalar colour) const {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, font_scale_, thickness_, &baseline);
  const int pad = std::max(2, static_cast<int>(std::lround(4 * font_scale_)));
  origin.x = std::clamp(origin.x, pad, std::max(pad, bgr.cols - size.width - pad));
  origin.y = std::clamp(origin.y, size.height + pad, std::max(size.height + pad, bgr.rows - baseline - pad));
  const cv::Rect box = cv::Rect(origin.x - pad, origin.y - size.height - pad, size.width + 2 * pad,
                                size.height + baseline + 2 * pad) &
                       cv::Rect(0, 0, bgr.cols, bgr.rows);
  if (box.area() > 0) {
    // Darken what lies under the text to 35 %: light text then reads over bright ridges and dots alike.
    cv::Mat under = bgr(box);
    under.convertTo(under, -1, 0.35, 0.0);
  }
  cv::putText(bgr, text, origin, cv::FONT_HERSHEY_SIMPLEX, font_scale_, colour, thickness_, cv::LINE_AA);
}

void OverlayText::status_line(cv::Mat& bgr, int slot, const std::string& text, cv::Scalar colour) const {
  const cv::Rect block = status_block(kBlockSlots);
  const int y = block.y + (slot + 1) * line_height_px_ - line_height_px_ / 4;
  label(bgr, {static_cast<int>(std::lround(8 * font_scale_ * 2)), y}, text, colour);
}

}  // namespace tirstrain
