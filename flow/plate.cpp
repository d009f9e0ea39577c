#include "flow/plate.hpp"

#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace tirstrain::flow {
namespace {

constexpr double kWhole = 0.98;  // fraction of a subset's pixels in the band for it to count

double median_of(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

}  // namespace

void PlateTracker::start(const cv::Mat& image, const cv::Mat& image_u8, const RoiPx& roi,
                         const PlateSettings& settings) {
  settings_ = settings;
  roi_ = cv::Rect(roi.x, roi.y, roi.width, roi.height) & cv::Rect(0, 0, image.cols, image.rows);
  if (roi_.width < 2 * settings.subset_radius_px + 3 || roi_.height < 2 * settings.subset_radius_px + 3)
    throw Error("the reference pattern band (" + std::to_string(roi.width) + "x" +
                    std::to_string(roi.height) + " px inside the image) is too small for a " +
                    std::to_string(2 * settings.subset_radius_px + 1) + " px plate subset",
                {.key = "reference_pattern.roi_px"});
  roi_mask_ = cv::Mat::zeros(image.size(), CV_8U);
  roi_mask_(roi_).setTo(1);
  base_px_ = {};
  displacement_px_ = {};
  velocity_px_ = {};
  rebase(image, image_u8);
  initial_subsets_ = subsets_.size();
  if (subsets_.empty())
    throw Error("the reference pattern band shows no texture to track the plate with",
                {.key = "reference_pattern.roi_px"});
  ok_ = true;
}

void PlateTracker::rebase(const cv::Mat& image, const cv::Mat& image_u8) {
  anchor_.assign(image, roi_mask_);
  subsets_.clear();
  warps_.clear();
  const int r = settings_.subset_radius_px;
  const double step = settings_.grid_step_px;
  // Centre the grid in the band so both ends keep the same margin.
  const int nx = std::max(1, static_cast<int>((roi_.width - 2 * r - 1) / step) + 1);
  const int ny = std::max(1, static_cast<int>((roi_.height - 2 * r - 1) / step) + 1);
  const double x0 = roi_.x + 0.5 * (roi_.width - 1 - (nx - 1) * step);
  const double y0 = roi_.y + 0.5 * (roi_.height - 1 - (ny - 1) * step);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const cv::Point c(static_cast<int>(std::lround(x0 + i * step)),
                        static_cast<int>(std::lround(y0 + j * step)));
      Subset s;
      if (!s.build(anchor_, c, r, 1, ShapeFunction::kTranslation, (2 * r + 1) * (2 * r + 1) / 2)) continue;
      subsets_.push_back(std::move(s));
      warps_.emplace_back();
    }
  }
  cv::buildOpticalFlowPyramid(image_u8(roi_), previous_pyramid_,
                              cv::Size(settings_.window_px, settings_.window_px), settings_.pyramid_levels);
}

Vec2 PlateTracker::track(const cv::Mat& image, const cv::Mat& image_u8) {
  cv::buildOpticalFlowPyramid(image_u8(roi_), current_pyramid_,
                              cv::Size(settings_.window_px, settings_.window_px), settings_.pyramid_levels);
  // Coarse step: LK from the previous frame, starting from the previous motion.
  const Vec2 local{displacement_px_.x - base_px_.x, displacement_px_.y - base_px_.y};
  lk_from_.clear();
  lk_to_.clear();
  for (const Subset& s : subsets_) {
    const cv::Point2f p(static_cast<float>(s.centre().x + local.x - roi_.x),
                        static_cast<float>(s.centre().y + local.y - roi_.y));
    lk_from_.push_back(p);
    lk_to_.emplace_back(p.x + static_cast<float>(velocity_px_.x), p.y + static_cast<float>(velocity_px_.y));
  }
  Vec2 increment = velocity_px_;
  if (!lk_from_.empty()) {
    cv::calcOpticalFlowPyrLK(previous_pyramid_, current_pyramid_, lk_from_, lk_to_, lk_status_, lk_error_,
                             cv::Size(settings_.window_px, settings_.window_px), settings_.pyramid_levels,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    scratch_x_.clear();
    scratch_y_.clear();
    for (std::size_t i = 0; i < lk_from_.size(); ++i) {
      if (!lk_status_[i]) continue;
      scratch_x_.push_back(lk_to_[i].x - lk_from_[i].x);
      scratch_y_.push_back(lk_to_[i].y - lk_from_[i].y);
    }
    if (!scratch_x_.empty()) increment = {median_of(scratch_x_), median_of(scratch_y_)};
  }
  std::swap(previous_pyramid_, current_pyramid_);

  // Fine step: every subset against the reference frame.
  const Vec2 guess{local.x + increment.x, local.y + increment.y};
  MatchOptions options;
  options.min_valid_fraction = 0.5;
  scratch_x_.clear();
  scratch_y_.clear();
  std::size_t usable = 0;
  for (std::size_t i = 0; i < subsets_.size(); ++i) {
    Warp& w = warps_[i];
    w.p.fill(0.0);
    w.p[0] = guess.x;
    w.p[1] = guess.y;
    const MatchResult m = subsets_[i].match(image, roi_mask_, w, options);
    // Only subsets still wholly in the band count: one cut by the band's edge loses part of its dots and
    // its match is biased (0.5 px was seen on a trial whose plate moved across a 56 px band).
    if (m.valid_fraction < kWhole) continue;
    ++usable;
    if (!m.converged || m.zncc < settings_.min_zncc) continue;
    scratch_x_.push_back(w.p[0]);
    scratch_y_.push_back(w.p[1]);
  }
  ok_ = !scratch_x_.empty();
  used_ = 0;
  if (ok_) {
    std::vector<double> xs = scratch_x_, ys = scratch_y_;
    const double mx = median_of(xs), my = median_of(ys);
    // Mean of the subsets that agree with the median: robust to a wrong subset, and as precise as a mean.
    double sx = 0, sy = 0;
    for (std::size_t i = 0; i < scratch_x_.size(); ++i) {
      if (std::hypot(scratch_x_[i] - mx, scratch_y_[i] - my) > settings_.max_spread_px) continue;
      sx += scratch_x_[i];
      sy += scratch_y_[i];
      ++used_;
    }
    const Vec2 next = used_ > 0 ? Vec2{base_px_.x + sx / used_, base_px_.y + sy / used_}
                                : Vec2{base_px_.x + mx, base_px_.y + my};
    if (used_ == 0) used_ = 1;
    velocity_px_ = {next.x - displacement_px_.x, next.y - displacement_px_.y};
    displacement_px_ = next;
  } else {
    displacement_px_ = {displacement_px_.x + increment.x, displacement_px_.y + increment.y};
    velocity_px_ = increment;
  }
  // Half the subsets are no longer wholly in the band: this frame becomes the reference while its estimate
  // still rests on whole subsets.
  if (usable * 2 < initial_subsets_) {
    base_px_ = displacement_px_;
    rebase(image, image_u8);
  }
  return displacement_px_;
}

}  // namespace tirstrain::flow
