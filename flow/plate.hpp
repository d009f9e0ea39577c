#pragma once
// Plate motion from the random pattern printed on the glass. The pattern moves rigidly with the plate
// under a band of the image that stays fixed, so: subsets on a grid inside the band, each matched against
// the reference frame by translation-only IC-GN with both frames masked to the band, seeded by the previous
// motion refined with pyramidal LK; the displacement is the median over subsets. When the plate has
// carried most subsets out of the band, the current frame becomes the new reference (its displacement is
// carried over), which costs one matching error per rebase instead of one per frame.
#include <opencv2/core.hpp>

#include <vector>

#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "flow/subset.hpp"

namespace tirstrain::flow {

struct PlateSettings {
  int subset_radius_px = 15;
  double grid_step_px = 24.0;
  int window_px = 21;
  int pyramid_levels = 2;
  double max_spread_px = 0.5;  // subsets further than this from the median are left out of it
  double min_zncc = 0.6;
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
  void rebase(const cv::Mat& image, const cv::Mat& image_u8);

  PlateSettings settings_;
  cv::Rect roi_;
  cv::Mat roi_mask_;
  AnchorImage anchor_;
  std::vector<Subset> subsets_;
  std::vector<Warp> warps_;
  std::vector<double> scratch_x_, scratch_y_;
  std::vector<cv::Mat> previous_pyramid_, current_pyramid_;
  std::vector<cv::Point2f> lk_from_, lk_to_;
  std::vector<unsigned char> lk_status_;
  std::vector<float> lk_error_;
  Vec2 base_px_;          // displacement of the current reference frame since frame 0
  Vec2 displacement_px_;  // since frame 0
  Vec2 velocity_px_;
  std::size_t initial_subsets_ = 0;
  bool ok_ = false;
  int used_ = 0;
};

}  // namespace tirstrain::flow
