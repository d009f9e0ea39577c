#include "flow/plate.hpp"

#include "core/archive.hpp"

#include <optional>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/error.hpp"
#include "core/median.hpp"
#include "flow/bicubic.hpp"
#include "flow/phase_correlation.hpp"

namespace tirstrain::flow {

void PlateTracker::archive(Archive& a) {
  a(settings_, roi_, smoothed_, band_mask_, band_, subsets_, hann_, band_correlation_, mosaic_sum_,
    mosaic_count_, mosaic_mean_, mosaic_mask_, mean_origin_, origin_x_, origin_y_, displacement_px_,
    velocity_px_per_s_, time_s_, interval_s_, status_, base_px_, base_time_s_, ok_, used_, base_u8_);
}

void PlateTracker::rebuild_previous_pyramid() {
  if (base_u8_.empty()) return;
  cv::buildOpticalFlowPyramid(base_u8_(roi_), previous_pyramid_,
                              cv::Size(settings_.window_px, settings_.window_px), settings_.pyramid_levels);
}
namespace {

// Zero-count margin kept around the mosaic's data: the bicubic sampler needs 2 px beyond a sample, and
// the band's footprint moves by up to a few pixels between the guess and the match.
constexpr int kPad = 16;

}  // namespace

const cv::Mat& PlateTracker::smoothed(const cv::Mat& image) {
  const double sigma = settings_.prefilter_sigma_px;
  if (sigma <= 0.0) return image;
  // Allocated, not cleared: only the band is ever read, and clearing the whole frame touched 1.3 MB of
  // fresh pages on a 640×512 trial (≈ 320 page faults at start, ≈ 4 ms on these machines).
  smoothed_.create(image.size(), CV_32F);
  cv::GaussianBlur(image(roi_), smoothed_(roi_), cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  return smoothed_;
}

void PlateTracker::start(const cv::Mat& image_in, const cv::Mat& image_u8, const RoiPx& roi,
                         const PlateOptions& settings, double t_s) {
  settings.check();
  settings_ = settings;
  roi_ = cv::Rect(roi.x, roi.y, roi.width, roi.height) & cv::Rect(0, 0, image_in.cols, image_in.rows);
  const cv::Mat& image = smoothed(image_in);
  // Larger subsets average more of the pattern's noise, with nothing gained beyond 22 px on the dot
  // patterns tried; a narrower band gets the largest radius it holds.
  constexpr int kAutomaticRadiusPx = 22;
  if (settings_.subset_radius_px <= 0)
    settings_.subset_radius_px =
        std::max(3, std::min(kAutomaticRadiusPx, (std::min(roi_.width, roi_.height) - 3) / 2));
  if (settings_.grid_step_px <= 0.0) settings_.grid_step_px = 2.0 * settings_.subset_radius_px + 1.0;
  if (roi_.width < 2 * settings_.subset_radius_px + 3 || roi_.height < 2 * settings_.subset_radius_px + 3)
    throw Error("the reference pattern band (" + std::to_string(roi.width) + "x" +
                    std::to_string(roi.height) + " px inside the image) is too small for a " +
                    std::to_string(2 * settings_.subset_radius_px + 1) + " px plate subset",
                {.key = "reference_pattern.roi_px"});
  band_mask_ = cv::Mat::ones(roi_.size(), CV_8U);
  displacement_px_ = {};
  velocity_px_per_s_ = {};
  base_px_ = {};
  time_s_ = base_time_s_ = std::isfinite(t_s) ? t_s : 0.0;
  interval_s_ = 1.0;
  status_ = PlateStatus::kMatched;
  build_subsets(image);
  if (subsets_.empty())
    throw Error("the reference pattern band shows no texture to track the plate with",
                {.key = "reference_pattern.roi_px"});
  mosaic_sum_.release();
  mosaic_count_.release();
  origin_x_ = roi_.x;
  origin_y_ = roi_.y;
  add_to_mosaic(image, {}, false);
  image_u8.copyTo(base_u8_);
  rebuild_previous_pyramid();
  cv::createHanningWindow(hann_, roi_.size(), CV_32F);
  band_correlation_.set_reference(image(roi_), hann_);
  ok_ = true;
}

// The band's shift since the previous frame by phase correlation (Hann-windowed), if its peak is clear.
std::optional<Vec2> PlateTracker::band_shift(const cv::Mat& band) {
  if (!band_correlation_.has_reference() || band_correlation_.reference_size() != band.size())
    return std::nullopt;
  double response = 0.0;
  const cv::Point2d s = band_correlation_.correlate(band, &response);
  if (!(response > settings_.min_shift_response) || !std::isfinite(s.x) || !std::isfinite(s.y))
    return std::nullopt;
  return Vec2{s.x, s.y};
}

void PlateTracker::build_subsets(const cv::Mat& image) {
  band_.assign(image(roi_), band_mask_);
  subsets_.clear();
  const int r = settings_.subset_radius_px;
  const double step = settings_.grid_step_px;
  // Centre the grid in the band so both ends keep the same margin.
  const int nx = std::max(1, static_cast<int>((roi_.width - 2 * r - 1) / step) + 1);
  const int ny = std::max(1, static_cast<int>((roi_.height - 2 * r - 1) / step) + 1);
  const double x0 = 0.5 * (roi_.width - 1 - (nx - 1) * step);
  const double y0 = 0.5 * (roi_.height - 1 - (ny - 1) * step);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const cv::Point c(static_cast<int>(std::lround(x0 + i * step)),
                        static_cast<int>(std::lround(y0 + j * step)));
      Subset s;
      if (!s.build(band_, c, r, 1, ShapeFunction::kTranslation, (2 * r + 1) * (2 * r + 1) / 2)) continue;
      subsets_.push_back(std::move(s));
    }
  }
}

void PlateTracker::cover(Vec2 d) {
  // Plate points the band shows at displacement d: image x minus d.
  const int x0 = static_cast<int>(std::floor(roi_.x - d.x)) - kPad;
  const int y0 = static_cast<int>(std::floor(roi_.y - d.y)) - kPad;
  const int x1 = static_cast<int>(std::ceil(roi_.x + roi_.width - 1 - d.x)) + kPad;
  const int y1 = static_cast<int>(std::ceil(roi_.y + roi_.height - 1 - d.y)) + kPad;
  if (mosaic_sum_.empty()) {
    origin_x_ = x0;
    origin_y_ = y0;
    mosaic_sum_ = cv::Mat::zeros(y1 - y0 + 1, x1 - x0 + 1, CV_32F);
    mosaic_count_ = cv::Mat::zeros(mosaic_sum_.size(), CV_16U);
    return;
  }
  const int left = std::max(0, origin_x_ - x0), top = std::max(0, origin_y_ - y0);
  const int right = std::max(0, x1 - (origin_x_ + mosaic_sum_.cols - 1));
  const int bottom = std::max(0, y1 - (origin_y_ + mosaic_sum_.rows - 1));
  if (left + top + right + bottom == 0) return;
  // Grow by an eighth of the mosaic's extent at a time (at least twice the margin), so a moving plate
  // copies it a few times, not every frame; the side across the motion, which grows only by sub-pixel
  // jitter, stays within an eighth of what it needs (growing it by a band's width tripled the mosaic).
  const auto grow = [](int need, int extent) {
    return need > 0 ? std::max({need, 2 * kPad, extent / 8}) : 0;
  };
  const int l = grow(left, mosaic_sum_.cols), t = grow(top, mosaic_sum_.rows),
            rr = grow(right, mosaic_sum_.cols), b = grow(bottom, mosaic_sum_.rows);
  cv::copyMakeBorder(mosaic_sum_, mosaic_sum_, t, b, l, rr, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::copyMakeBorder(mosaic_count_, mosaic_count_, t, b, l, rr, cv::BORDER_CONSTANT, cv::Scalar(0));
  origin_x_ -= l;
  origin_y_ -= t;
}

void PlateTracker::add_to_mosaic(const cv::Mat& image, Vec2 d, bool only_empty) {
  cover(d);
  // Every mosaic pixel whose image position lies in the band with the bicubic kernel's 4x4 support.
  const double lo_x = roi_.x + 1.0, hi_x = roi_.x + roi_.width - 3.0;
  const double lo_y = roi_.y + 1.0, hi_y = roi_.y + roi_.height - 3.0;
  const int i0 = std::max(0, static_cast<int>(std::ceil(lo_x - d.x)) - origin_x_);
  const int i1 = std::min(mosaic_sum_.cols - 1, static_cast<int>(std::floor(hi_x - d.x)) - origin_x_);
  const int j0 = std::max(0, static_cast<int>(std::ceil(lo_y - d.y)) - origin_y_);
  const int j1 = std::min(mosaic_sum_.rows - 1, static_cast<int>(std::floor(hi_y - d.y)) - origin_y_);
  if (i1 < i0 || j1 < j0) return;
  // The whole band moves by d: one set of bicubic weights for every pixel.
  detail::TranslatedSampler shifted(image, cv::Mat(), origin_x_ + i0 + d.x, origin_y_ + j0 + d.y, 0, i1 - i0);
  if (!shifted.ok()) return;  // so far off that no pixel lands in the image
  for (int j = j0; j <= j1; ++j) {
    float* sum = mosaic_sum_.ptr<float>(j);
    std::uint16_t* count = mosaic_count_.ptr<std::uint16_t>(j);
    for (int i = i0; i <= i1; ++i) {
      float v = 0.0f;
      // A pixel's mean stops at 65535 frames (a plate at rest for minutes): enough, and the count fits in
      // 16 bits, a quarter of the mosaic's memory.
      if ((only_empty && count[i] > 0) || count[i] == std::numeric_limits<std::uint16_t>::max()) continue;
      if (!shifted.sample(i - i0, j - j0, v)) continue;
      sum[i] += v;
      ++count[i];
    }
  }
}

void PlateTracker::prepare_mean(Vec2 d) {
  cover(d);
  // Only around the band's footprint: the rest of a long trial's mosaic is not sampled this frame (a long
  // trial's mosaic is many bands long, and a mean and mask of all of it would grow with the plate's travel).
  const cv::Rect near(static_cast<int>(std::floor(roi_.x - d.x)) - kPad - origin_x_,
                      static_cast<int>(std::floor(roi_.y - d.y)) - kPad - origin_y_,
                      roi_.width + 2 * kPad + 2, roi_.height + 2 * kPad + 2);
  const cv::Rect r = near & cv::Rect(0, 0, mosaic_sum_.cols, mosaic_sum_.rows);
  mean_origin_ = r.tl();
  mosaic_mean_.create(r.size(), CV_32F);
  mosaic_mean_.setTo(0);
  scratch_mask_.create(r.size(), CV_8U);
  scratch_mask_.setTo(0);
  for (int j = r.y; j < r.y + r.height; ++j) {
    const float* sum = mosaic_sum_.ptr<float>(j);
    const std::uint16_t* count = mosaic_count_.ptr<std::uint16_t>(j);
    float* mean = mosaic_mean_.ptr<float>(j - r.y);
    std::uint8_t* m = scratch_mask_.ptr<std::uint8_t>(j - r.y);
    for (int i = r.x; i < r.x + r.width; ++i)
      if (count[i] > 0) {
        mean[i - r.x] = sum[i] / static_cast<float>(count[i]);
        m[i - r.x] = 1;
      }
  }
  mosaic_mask_.create(r.size(), CV_8U);
  erode_for_matching(scratch_mask_, mosaic_mask_);
}

// The share of the band's pixels (sampled every 4 px) that land on mosaic data at displacement d.
double PlateTracker::mosaic_coverage(Vec2 d) const {
  if (mosaic_count_.empty()) return 0.0;
  int covered = 0, total = 0;
  for (int y = 0; y < roi_.height; y += 4)
    for (int x = 0; x < roi_.width; x += 4) {
      ++total;
      const int i = static_cast<int>(std::lround(roi_.x + x - d.x)) - origin_x_;
      const int j = static_cast<int>(std::lround(roi_.y + y - d.y)) - origin_y_;
      if (i >= 0 && j >= 0 && i < mosaic_count_.cols && j < mosaic_count_.rows &&
          mosaic_count_.at<std::uint16_t>(j, i) > 0)
        ++covered;
    }
  return total > 0 ? static_cast<double>(covered) / total : 0.0;
}

// LK from the previous frame on the grid points, started at `initial`: the median of the points' motion
// (`initial` itself when LK finds nothing).
Vec2 PlateTracker::lk_increment(Vec2 initial) {
  lk_from_.clear();
  lk_to_.clear();
  for (const Subset& s : subsets_) {
    const cv::Point2f p(static_cast<float>(s.centre().x), static_cast<float>(s.centre().y));
    lk_from_.push_back(p);
    lk_to_.emplace_back(p.x + static_cast<float>(initial.x), p.y + static_cast<float>(initial.y));
  }
  if (lk_from_.empty()) return initial;
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
  if (scratch_x_.empty()) return initial;
  return {tirstrain::median_in_place(scratch_x_), tirstrain::median_in_place(scratch_y_)};
}

// Every subset of this frame's band into the mosaic, from `guess`. Band point c is image point c + roi's
// corner, plate point that minus d, mosaic pixel that minus the origin: the warp's translation is corner -
// d - origin. Returns false when no subset matched; else sets displacement_px_.
bool PlateTracker::match_mosaic(Vec2 guess) {
  prepare_mean(guess);
  MatchOptions options;
  options.min_valid_fraction = settings_.min_valid_fraction;
  const double offset_x = roi_.x - origin_x_ - mean_origin_.x, offset_y = roi_.y - origin_y_ - mean_origin_.y;
  scratch_x_.clear();
  scratch_y_.clear();
  for (const Subset& s : subsets_) {
    Warp w;
    w.p[0] = offset_x - guess.x;
    w.p[1] = offset_y - guess.y;
    const MatchResult m = s.match(mosaic_mean_, mosaic_mask_, w, options);
    if (!m.converged || m.valid_fraction < settings_.min_valid_fraction || m.zncc < settings_.min_zncc)
      continue;
    scratch_x_.push_back(offset_x - w.p[0]);
    scratch_y_.push_back(offset_y - w.p[1]);
  }
  if (scratch_x_.empty()) return false;
  std::vector<double> xs = scratch_x_, ys = scratch_y_;
  const double mx = tirstrain::median_in_place(xs), my = tirstrain::median_in_place(ys);
  // Mean of the subsets that agree with the median: robust to a wrong subset, and as precise as a mean.
  double sx = 0, sy = 0;
  used_ = 0;
  for (std::size_t i = 0; i < scratch_x_.size(); ++i) {
    if (std::hypot(scratch_x_[i] - mx, scratch_y_[i] - my) > settings_.max_spread_px) continue;
    sx += scratch_x_[i];
    sy += scratch_y_[i];
    ++used_;
  }
  const Vec2 next = used_ > 0 ? Vec2{sx / used_, sy / used_} : Vec2{mx, my};
  if (used_ == 0) used_ = 1;
  // Most subsets must agree: a guess a dot spacing off matches a few subsets on the wrong dots.
  if (2 * used_ < static_cast<int>(subsets_.size()) && 2 * used_ < static_cast<int>(scratch_x_.size()))
    return false;
  displacement_px_ = next;
  return true;
}

Vec2 PlateTracker::track(const cv::Mat& image_in, const cv::Mat& image_u8, double t_s) {
  const cv::Mat& image = smoothed(image_in);
  cv::buildOpticalFlowPyramid(image_u8(roi_), current_pyramid_,
                              cv::Size(settings_.window_px, settings_.window_px), settings_.pyramid_levels);
  build_subsets(image);
  // Motion is extrapolated in time, not per frame: frame intervals jitter (0.2 ms at 100 frames/s on the
  // shipped trials is 0.2 px of plate travel at 20 mm/s). Without increasing times, one interval per frame.
  const double t = std::isfinite(t_s) && t_s > time_s_ ? t_s : time_s_ + interval_s_;
  interval_s_ = t - time_s_;
  // LK and the phase correlation run from the last frame that was not bridged (see below). The coarse step
  // is the last motion over the time since then, unless the band's phase correlation says the plate moved
  // by more than LK follows from there (a quarter of its window: it starts, stops or jumps by more than
  // that within a frame). On a pattern with dots every ~11 px, LK and the subsets started a dot spacing
  // off settle on a nearby dot configuration; the pattern is random, so the correlation's peak is unique
  // (hard_large_displacement: a start at 12.8 px per frame left the plate 83.5 px behind).
  used_ = 0;
  const Vec2 before = displacement_px_, velocity = velocity_px_per_s_;
  const double dt = t - time_s_, base_dt = t - base_time_s_;
  const Vec2 predicted{before.x + velocity.x * dt, before.y + velocity.y * dt};
  Vec2 coarse{velocity.x * base_dt, velocity.y * base_dt};
  if (const auto shift = band_shift(image(roi_)))
    if (std::hypot(shift->x - coarse.x, shift->y - coarse.y) > 0.25 * settings_.window_px) coarse = *shift;
  const Vec2 increment = lk_increment(coarse);
  ok_ = match_mosaic({base_px_.x + increment.x, base_px_.y + increment.y});
  // Then from the last motion alone, then from rest.
  if (!ok_) ok_ = match_mosaic(predicted);
  if (!ok_) {
    const Vec2 from_rest = lk_increment({0.0, 0.0});
    ok_ = match_mosaic({base_px_.x + from_rest.x, base_px_.y + from_rest.y});
  }
  time_s_ = t;
  const Vec2 flow_only{base_px_.x + increment.x, base_px_.y + increment.y};
  const bool loose = ok_ && 4 * used_ < 3 * static_cast<int>(subsets_.size());
  if (loose || (!ok_ && mosaic_coverage(flow_only) >= kCoveredToMatch)) {
    // Most subsets disagree (normally all agree), or none matched where the mosaic covers the band: the
    // band is motion blurred (or hidden), and a loose match is off along the motion (hard_motion_blur: 3.8
    // px, 11 of 25 subsets). It is neither stitched (that biased every later frame by 0.17 px) nor
    // trusted, nor the base of the next frame's LK (from a blurred frame LK is off by 0.7-2.4 px along a
    // 15.6 px streak): the plate is where its last motion takes it.
    displacement_px_ = predicted;
    ok_ = false;
    status_ = PlateStatus::kPredicted;
    return displacement_px_;
  }
  status_ = ok_ ? PlateStatus::kMatched : PlateStatus::kFlowOnly;
  if (ok_) {
    add_to_mosaic(image, displacement_px_, false);
  } else {
    // The band has left the mosaic (the plate moved faster than the band's overlap allows, or frames in
    // between were not stitched): placed by LK alone and stitched only where the mosaic has no data yet,
    // which would otherwise never match again; where it has data, a frame placed by LK would blur it.
    displacement_px_ = flow_only;
    add_to_mosaic(image, displacement_px_, true);
  }
  velocity_px_per_s_ = {(displacement_px_.x - before.x) / dt, (displacement_px_.y - before.y) / dt};
  std::swap(previous_pyramid_, current_pyramid_);
  image_u8.copyTo(base_u8_);
  // The band correlated above becomes the next frame's reference, its spectrum kept.
  if (!band_correlation_.adopt_last_as_reference()) band_correlation_.set_reference(image(roi_), hann_);
  base_px_ = displacement_px_;
  base_time_s_ = t;
  return displacement_px_;
}

void PlateOptions::check() const {
  const auto fail = [](const std::string& field, const std::string& message) {
    throw Error("plate options: " + field + " " + message);
  };
  if (subset_radius_px != 0 && subset_radius_px < 3) fail("subset_radius_px", "must be 0 or at least 3 px");
  if (!(grid_step_px >= 0.0)) fail("grid_step_px", "must not be negative");
  if (window_px < 3 || window_px % 2 == 0) fail("window_px", "must be odd and at least 3");
  if (pyramid_levels < 0 || pyramid_levels > 8) fail("pyramid_levels", "must lie in [0, 8]");
  if (!(max_spread_px > 0.0)) fail("max_spread_px", "must be positive");
  if (!(min_zncc >= -1.0 && min_zncc <= 1.0)) fail("min_zncc", "must lie in [-1, 1]");
  if (!(min_valid_fraction > 0.0 && min_valid_fraction <= 1.0))
    fail("min_valid_fraction", "must lie in (0, 1]");
  if (!(prefilter_sigma_px >= 0.0)) fail("prefilter_sigma_px", "must not be negative");
}

}  // namespace tirstrain::flow
