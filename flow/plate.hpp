#pragma once
// Plate motion from the random pattern printed on the glass. The pattern moves rigidly with the plate
// under a band of the image that stays fixed. Its reference is a mosaic of the pattern in plate
// coordinates (frame 0's image coordinates of each pattern point), stitched from every frame at its
// measured displacement and averaged where frames overlap: each frame's band is cut into subsets on a grid,
// each matched into the mosaic by translation-only IC-GN (masked to where the mosaic has data), seeded by
// the previous motion refined with pyramidal LK; the displacement is the mean of the subsets that agree
// with their median; then the frame joins the mosaic.
//
// Why a mosaic: the plate carries its pattern across the band in a few frames (56 px at 2.6 px/frame on
// the shipped scenes). Matching against one reference frame needs a new reference every time the pattern
// has left the band, and each such rebase carried that frame's noise and error into every later frame
// (0.022 px RMS on the default scene, 0.097 px with heavy noise, stepping at each rebase). In the mosaic
// every patch of pattern is the mean of all the frames that saw it, and each frame is registered against
// all of the pattern it shares with them, so the chain's steps are smaller and the noise averages out.
#include <opencv2/core.hpp>

#include <vector>

#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "flow/subset.hpp"

namespace tirstrain::flow {

struct PlateSettings {
  int subset_radius_px = 0;  // 0: automatic, the largest radius up to 22 px that fits the band
  double grid_step_px = 24.0;
  int window_px = 21;
  int pyramid_levels = 2;
  double max_spread_px = 0.5;  // subsets further than this from the median are left out of it
  double min_zncc = 0.6;
  // A subset counts when at least this share of it lands where the mosaic has data (the mask keeps the
  // bicubic kernel clear of the edge, so a partly covered subset is unbiased, only noisier).
  double min_valid_fraction = 0.6;
  // Both the band and the mosaic are smoothed by a Gaussian of this σ before matching (0: off). Pixel noise
  // resampled by the bicubic kernel varies with the sub-pixel phase and pulls the match; a σ of 0.7 px
  // takes most of it out and keeps the dots (measured 0 / 0.5 / 0.7 / 1.0 / 1.5 px: hard_heavy_noise
  // 0.0212 / 0.0189 / 0.0183 / 0.0188 / 0.0367 px RMS, default 0.0043 / 0.0042 / 0.0041 / - / - px).
  double prefilter_sigma_px = 0.7;
};

class PlateTracker {
 public:
  // `image` CV_32F (full scale 1), `image_u8` the same frame in 8 bits (for LK).
  void start(const cv::Mat& image, const cv::Mat& image_u8, const RoiPx& roi, const PlateSettings& settings);
  // Returns the displacement since the first frame; keeps the last value if no subset could be matched
  // (then ok() is false for this frame).
  Vec2 track(const cv::Mat& image, const cv::Mat& image_u8);
  Vec2 displacement_px() const { return displacement_px_; }
  bool ok() const { return ok_; }
  int subsets_used() const { return used_; }

 private:
  // Subsets on the grid over the band of `image` (band coordinates).
  void build_subsets(const cv::Mat& image);
  // `image`, or its band smoothed by prefilter_sigma_px (the rest of the returned image is undefined).
  const cv::Mat& smoothed(const cv::Mat& image);
  // Makes the mosaic cover the band's footprint at displacement `d` (plus a margin); grows it as needed.
  void cover(Vec2 d);
  void add_to_mosaic(const cv::Mat& image, Vec2 d);
  // The mosaic's mean and its matching mask, around the band's footprint at `d`.
  void prepare_mean(Vec2 d);
  Vec2 lk_increment(Vec2 initial);
  bool match_mosaic(Vec2 guess);

  PlateSettings settings_;
  cv::Rect roi_;
  cv::Mat smoothed_;
  cv::Mat band_mask_;  // ones over the band (AnchorImage trims its edge)
  AnchorImage band_;
  std::vector<Subset> subsets_;
  std::vector<double> scratch_x_, scratch_y_;
  std::vector<cv::Mat> previous_pyramid_, current_pyramid_;
  std::vector<cv::Point2f> lk_from_, lk_to_;
  std::vector<unsigned char> lk_status_;
  std::vector<float> lk_error_;
  // Mosaic pixel (i, j) holds plate point (origin_x_ + i, origin_y_ + j).
  cv::Mat mosaic_sum_, mosaic_count_, mosaic_mean_, mosaic_mask_, scratch_mask_;
  int origin_x_ = 0, origin_y_ = 0;
  Vec2 displacement_px_;  // since frame 0
  Vec2 velocity_px_;
  bool ok_ = false;
  int used_ = 0;
};

}  // namespace tirstrain::flow
