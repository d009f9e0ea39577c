#pragma once
// Text on video frames that stays readable over any image: a font sized to the frame (the same share of
// its width at every resolution), each line on a dark translucent backdrop, and the status lines stacked in
// a block along the top edge, or along the bottom when a region to keep clear (the printed pattern band)
// lies at the top.
#include <opencv2/core.hpp>

#include <optional>
#include <string>

namespace tirstrain {

class OverlayText {
 public:
  // `keep_clear`: a rectangle of the frame the status block must not cover (e.g. the pattern band).
  OverlayText(cv::Size frame_size, std::optional<cv::Rect> keep_clear = std::nullopt);

  // Status line `slot` (0 = the first line of the block), in `colour` (BGR).
  void status_line(cv::Mat& bgr, int slot, const std::string& text,
                   cv::Scalar colour = {255, 255, 255}) const;
  // A label with its baseline's left end at `origin`, kept inside the frame.
  void label(cv::Mat& bgr, cv::Point origin, const std::string& text,
             cv::Scalar colour = {255, 255, 255}) const;

  double font_scale() const { return font_scale_; }
  int thickness() const { return thickness_; }
  int line_height_px() const { return line_height_px_; }
  // Rows the status block may take (`slots` lines), top and bottom: where other drawings should not go.
  cv::Rect status_block(int slots) const;

 private:
  cv::Size frame_size_;
  bool block_at_bottom_ = false;
  double font_scale_ = 0.5;
  int thickness_ = 1;
  int line_height_px_ = 20;
};

}  // namespace tirstrain
