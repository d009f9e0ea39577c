#pragma once
// Plate motion from the random pattern printed on the glass. The pattern moves rigidly with the plate
// under a band of the image that stays fixed. Its reference is a mosaic of the pattern in plate
// coordinates (frame 0's image coordinates of each pattern point), stitched from every frame at its
// measured displacement and averaged where frames overlap: each frame's band is cut into subsets on a grid,
// each matched into the mosaic by translation-only IC-GN (masked to where the mosaic has data), seeded by
// the previous motion (or the band's phase correlation with the previous band, where the plate started,
// stopped or jumped) refined with pyramidal LK; the displacement is the mean of the subsets that agree
// with their median; then the frame joins the mosaic.
//
// Why a mosaic: the plate carries its pattern across the band in a few frames (56 px at 2.6 px/frame on
// the shipped scenes). Matching against one reference frame needs a new reference every time the pattern
// has left the band, and each such rebase carries that frame's noise and error into every later frame,
// a step at each rebase. In the mosaic
// every patch of pattern is the mean of all the frames that saw it, and each frame is registered against
// all of the pattern it shares with them, so the chain's steps are smaller and the noise averages out.
#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "flow/phase_correlation.hpp"
#include "flow/subset.hpp"

namespace tirstrain {
class Archive;
}

namespace tirstrain::flow {

// How a frame's plate displacement was obtained; written per frame as /plate/status.
enum class PlateStatus : std::int8_t {
  kMatched = 0,    // matched into the mosaic, most subsets agreeing (the frame joins the mosaic)
  kPredicted = 1,  // most subsets disagree, or none matched where the mosaic covers the band (a motion-
                   // blurred band): the last motion carried over
  kFlowOnly = 2,   // nothing matched, the band having left the mosaic: placed by LK alone
};

struct PlateOptions {
  int subset_radius_px = 0;  // subset half-side, px; 0 = the largest up to 22 px that fits the band
  // Subset spacing, px; 0 = side by side (2 radius + 1): overlapping subsets add work, not information.
  double grid_step_px = 0.0;
  int window_px = 21;          // LK window side of the band's coarse motion (odd), px; default 21
  int pyramid_levels = 2;      // LK pyramid levels; default 2
  double max_spread_px = 0.5;  // subsets further than this from the median are left out of it, px; 0.5
  double min_zncc = 0.6;       // subsets matched with less correlation are left out; default 0.6
  // A subset counts when at least this share of it lands where the mosaic has data (the mask keeps the
  // bicubic kernel clear of the edge, so a partly covered subset is unbiased, only noisier); 0.4, so that
  // the frame after an unstitched (motion-blurred) one still overlaps a narrow band's mosaic enough.
  double min_valid_fraction = 0.4;
  // Band and mosaic smoothed by a Gaussian of this σ before matching, px (0: off); default 0.7. Pixel noise
  // resampled by the bicubic kernel varies with the sub-pixel phase and pulls the match; 0.7 px takes most
  // of it out and keeps the dots.
  double prefilter_sigma_px = 0.7;
  // The band's phase correlation with the previous frame's replaces the last motion as LK's start when its
  // peak is at least this strong and further than a quarter of the LK window from that motion; default 0.7
  // (sharp frames peak near 1, a motion-blurred band's box spectrum moves a weaker peak off).
  double min_shift_response = 0.7;
  // Throws Error naming the first value out of range.
  void check() const;
};

class PlateTracker {
 public:
  // `image` CV_32F (full scale 1), `image_u8` the same frame in 8 bits (for LK).
  // `t_s`: the frame's time (s); the plate's motion is extrapolated in time. NaN, or times that do not
  // increase: one unit per frame.
  void start(const cv::Mat& image, const cv::Mat& image_u8, const RoiPx& roi, const PlateOptions& settings,
             double t_s = std::numeric_limits<double>::quiet_NaN());
  // Returns the displacement since the first frame. Where no subset matched, the previous frame's LK
  // motion is added; where most subsets disagree (a motion-blurred band), the last motion is; either way
  // ok() is false for this frame and the frame does not join the mosaic.
  Vec2 track(const cv::Mat& image, const cv::Mat& image_u8,
             double t_s = std::numeric_limits<double>::quiet_NaN());
  Vec2 displacement_px() const { return displacement_px_; }
  bool ok() const { return ok_; }
  PlateStatus status() const { return status_; }
  int subsets_used() const { return used_; }
  // Its state in a checkpoint (core/archive.hpp). The LK pyramid of the frame LK runs from is not in it:
  // LK reads past a pyramid level's edge into the frame it was cut from, so it is built again from that
  // frame, which the plate keeps (the last frame not bridged over: not always the previous one).
  void archive(Archive& a);
  void rebuild_previous_pyramid();

 private:
  // Subsets on the grid over the band of `image` (band coordinates).
  void build_subsets(const cv::Mat& image);
  // `image`, or its band smoothed by prefilter_sigma_px (the rest of the returned image is undefined).
  const cv::Mat& smoothed(const cv::Mat& image);
  // Makes the mosaic cover the band's footprint at displacement `d` (plus a margin); grows it as needed.
  void cover(Vec2 d);
  // `only_empty`: into mosaic pixels that have no data yet.
  void add_to_mosaic(const cv::Mat& image, Vec2 d, bool only_empty);
  // The mosaic's mean and its matching mask, around the band's footprint at `d`.
  void prepare_mean(Vec2 d);
  Vec2 lk_increment(Vec2 initial);
  double mosaic_coverage(Vec2 d) const;
  // A band at least this much on mosaic data should match it (the subsets need min_valid_fraction of
  // theirs); when none does, the frame's content is at fault (motion blur), not the mosaic's extent.
  static constexpr double kCoveredToMatch = 0.6;
  std::optional<Vec2> band_shift(const cv::Mat& band);
  bool match_mosaic(Vec2 guess);

  PlateOptions settings_;
  cv::Rect roi_;
  cv::Mat smoothed_;
  cv::Mat band_mask_;  // ones over the band (AnchorImage trims its edge)
  AnchorImage band_;
  std::vector<Subset> subsets_;
  std::vector<double> scratch_x_, scratch_y_;
  std::vector<cv::Mat> previous_pyramid_, current_pyramid_;
  cv::Mat base_u8_;  // the 8-bit frame previous_pyramid_ was built from
  std::vector<cv::Point2f> lk_from_, lk_to_;
  std::vector<unsigned char> lk_status_;
  std::vector<float> lk_error_;
  cv::Mat hann_;                      // the band correlation's window
  PhaseCorrelator band_correlation_;  // against the previous frame's (smoothed) band
  // Mosaic pixel (i, j) holds plate point (origin_x_ + i, origin_y_ + j).
  cv::Mat mosaic_sum_, mosaic_count_, mosaic_mean_, mosaic_mask_, scratch_mask_;  // count: CV_16U
  cv::Point mean_origin_;  // mosaic_mean_ and mosaic_mask_'s top-left corner in the mosaic
  int origin_x_ = 0, origin_y_ = 0;
  Vec2 displacement_px_;    // since frame 0
  Vec2 velocity_px_per_s_;  // over the last interval (px per `t_s` unit)
  double time_s_ = 0.0, interval_s_ = 1.0;
  PlateStatus status_ = PlateStatus::kMatched;
  // The displacement and time of the frame the previous pyramid and band are from.
  Vec2 base_px_;
  double base_time_s_ = 0.0;
  bool ok_ = false;
  int used_ = 0;
};

}  // namespace tirstrain::flow
