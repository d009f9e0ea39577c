// The feature tracker's public calls and each frame's preparation: input checks, the float and 8-bit
// images, the region of interest, the pyramids, key frames and subsets.
#include "flow/tracker.hpp"

#include <Eigen/Dense>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <numeric>
#include <string>

#include "core/error.hpp"
#include "core/full_scale.hpp"
#include "core/median.hpp"
#include "flow/detail/tracker_impl.hpp"
#include "flow/mask_erosion.hpp"
#include "flow/shi_tomasi.hpp"

namespace tirstrain::flow {

using namespace tracker_detail;

const char* to_string(TrackStatus status) {
  switch (status) {
    case TrackStatus::kTracked:
      return "tracked";
    case TrackStatus::kBorn:
      return "born";
    case TrackStatus::kRecovered:
      return "recovered";
    case TrackStatus::kUnchecked:
      return "unchecked";
    case TrackStatus::kLeftContact:
      return "left_contact";
    case TrackStatus::kForwardBackward:
      return "forward_backward";
    case TrackStatus::kPoorMatch:
      return "poor_match";
    case TrackStatus::kInconsistent:
      return "inconsistent";
    case TrackStatus::kLeftImage:
      return "left_image";
  }
  return "?";
}

void to_float_image(const cv::Mat& image, cv::Mat& out, double full_scale) {
  switch (image.depth()) {
    case CV_8U:
    case CV_16U:
      image.convertTo(out, CV_32F, 1.0 / full_scale);
      return;
    case CV_32F:
      image.copyTo(out);
      return;
    default:
      throw Error("unsupported image type (expected 8-bit, 16-bit or float grey)");
  }
}

cv::Mat to_float_image(const cv::Mat& image) {
  cv::Mat out;
  to_float_image(image, out, full_scale_of(image));
  return out;
}

void to_u8_image(const cv::Mat& image, cv::Mat& out, double full_scale) {
  switch (image.depth()) {
    case CV_8U:
      image.copyTo(out);
      return;
    case CV_16U:
      image.convertTo(out, CV_8U, 255.0 / full_scale);
      return;
    case CV_32F:
      image.convertTo(out, CV_8U, 255.0);
      return;
    default:
      throw Error("unsupported image type (expected 8-bit, 16-bit or float grey)");
  }
}

void FeatureTracker::Impl::check_input(const cv::Mat& image, const cv::Mat& contact_mask) const {
  if (image.empty()) throw Error("empty frame", {.frame = frame < 0 ? 0 : frame});
  if (image.channels() != 1)
    throw Error("expected a grey frame, got " + std::to_string(image.channels()) + " channels",
                {.frame = frame < 0 ? 0 : frame});
  if (frame >= 0 && image.size() != size)
    throw Error("frame size " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                    " differs from the first frame's " + std::to_string(size.width) + "x" +
                    std::to_string(size.height),
                {.frame = frame});
  if (!contact_mask.empty() && (contact_mask.size() != image.size() || contact_mask.type() != CV_8U))
    throw Error("the contact mask must be 8-bit and the size of the frame", {.frame = frame < 0 ? 0 : frame});
  if (plate_roi) {
    const cv::Rect band(plate_roi->x, plate_roi->y, plate_roi->width, plate_roi->height);
    if (band.width <= 0 || band.height <= 0 || (band & cv::Rect({0, 0}, image.size())) != band)
      throw Error("the pattern band [" + std::to_string(band.x) + ", " + std::to_string(band.y) + ", " +
                      std::to_string(band.width) + ", " + std::to_string(band.height) +
                      "] (x, y, width, height) does not lie inside the " + std::to_string(image.cols) +
                      " x " + std::to_string(image.rows) + " px frame",
                  {.frame = frame < 0 ? 0 : frame, .key = "reference_pattern.roi_px"});
  }
}

void FeatureTracker::Impl::prepare(const cv::Mat& image, const cv::Mat& contact_mask) {
  // Decided once, on the first frame, by the rule contact/ uses: a 10-bit camera's codes in 16-bit files
  // are fractions of 1023, not of 65535, and every later frame is scaled alike so that brightness stays
  // comparable between frames.
  if (full_scale <= 0.0) full_scale = full_scale_of(image);
  to_float_image(image, current_f, full_scale);
  to_u8_image(image, current_u8, full_scale);
  if (contact_mask.empty())
    mask = cv::Mat(image.size(), CV_8U, cv::Scalar(1));
  else
    cv::compare(contact_mask, 0, mask, cv::CMP_NE);
  if (settings.refine) {
    // Eroded only around the contact (its bounding box grown past both kernels' reach, where the mask is 0
    // as it is everywhere else), and the 0.6 P ellipse by erode_ellipse: the same mask, and cv::erode's
    // ellipse over the whole frame was 5-8 % of the tracker's instructions on the 640×512 goal trial.
    const int e = static_cast<int>(std::lround(settings.border.exclusion_px));
    cv::Rect box = cv::boundingRect(mask);
    const int reach = e + 3;
    box = cv::Rect(box.x - reach, box.y - reach, box.width + 2 * reach, box.height + 2 * reach) &
          cv::Rect(0, 0, mask.cols, mask.rows);
    match_mask.create(mask.size(), CV_8U);
    match_mask.setTo(0);
    if (box.area() > 0) {
      cv::Mat eroded = match_mask(box);
      erode_contact_for_matching(mask, box, e, erosion_scratch, eroded);
    }
  }
}

// Frame 0 decides how much model the subsets can afford (TrackerOptions::adapt_to_texture).
void FeatureTracker::Impl::adapt_to_texture(double expected_tracks) {
  texture = TextureQuality{};
  low_snr = false;
  if (!settings.refine) return;
  const double period =
      settings.ridge_period_px > 0.0 ? settings.ridge_period_px : settings.prediction.window_px;
  // The resampled rounds (step 7) carry a track where neighbours surround it; on a contact of a few hundred
  // grid points most tracks are border tracks, whose main match counts on its own, so there the main match
  // keeps the second-order subset on every pixel: there it sets the position, not just the rounds' seed.
  if (settings.texture.adapt && settings.rounds.resampled && expected_tracks < kFewTracks) {
    if (!settings.pinned.shape) settings.main_match.shape = ShapeFunction::kQuadratic;
    if (!settings.pinned.subset_stride) settings.main_match.subset_stride = 1;
    if (!settings.pinned.fixed_shape_stride) settings.rounds.subset_stride = 1;
    if (!settings.pinned.main_match_period) settings.main_match.period_frames = 1;
  }
  texture = measure_texture(current_f, mask, period);
  if (!settings.texture.adapt || texture.pixels == 0) return;
  // Without ridges (speckle, any isotropic texture) the smoothing and the low-SNR subsets below, sized from
  // the ridge period and tuned on ridges, do not apply: the subsets keep the preset's sizes. Unsmoothed,
  // neighbouring pixels carry independent noise, so a subset sampled on every s-th pixel would see s² times
  // the noise variance: every pixel is matched.
  if (!texture.ridges) {
    if (!settings.pinned.subset_stride) settings.main_match.subset_stride = 1;
    if (!settings.pinned.fixed_shape_stride) settings.rounds.subset_stride = 1;
    // The wide subset that sets the final positions grows (up to twice the preset's) until its
    // predicted noise reaches kTargetNoisePx: sqrt(2 σ_n² / (n ⟨g²⟩)) with n = (2r + 1)² pixels.
    if (!settings.pinned.subset_radius && texture.gradient_energy > 0.0) {
      const double side = std::sqrt(2.0 * texture.noise_sigma * texture.noise_sigma /
                                    (kTargetNoisePx * kTargetNoisePx * texture.gradient_energy));
      const int wide = std::max(settings.rounds.subset_radius_px, settings.main_match.subset_radius_px);
      settings.rounds.subset_radius_px =
          std::clamp(static_cast<int>(std::ceil(0.5 * (side - 1.0))), wide, 2 * wide);
    }
    return;
  }
  if (texture.snr >= settings.texture.min_unfiltered_snr) return;
  // Light smoothing keeps 97 % of the ridge contrast and takes most pixel noise out of the reference
  // gradients: faster convergence and a lower error on noisy frames (not on noise-free ones).
  const auto& pinned = settings.pinned;
  if (!pinned.prefilter)
    settings.main_match.prefilter_sigma_px =
        std::max(settings.main_match.prefilter_sigma_px, std::round(10.0 * period / 24.0) / 10.0);
  if (texture.snr >= settings.texture.min_quadratic_snr) return;
  low_snr = true;
  // Every track matched every frame: with tracks starting from their neighbours, the rounds left 2
  // track-frames 1.0-1.13 px off in hard_heavy_noise's first 20 frames (none with the main match, which the
  // neighbour check then weighs; Tracker.HeavyNoiseRoundsOverruleADisagreeingMainMatch).
  if (!pinned.main_match_period) settings.main_match.period_frames = 1;
  if (!pinned.shape && settings.main_match.shape == ShapeFunction::kQuadratic)
    settings.main_match.shape = ShapeFunction::kAffine;
  if (!pinned.prefilter)
    settings.main_match.prefilter_sigma_px =
        std::max(settings.main_match.prefilter_sigma_px, std::round(10.0 * period / 12.0) / 10.0);
  if (!pinned.subset_radius)
    settings.main_match.subset_radius_px =
        std::max(settings.main_match.subset_radius_px, static_cast<int>(std::lround(0.75 * period)));
  // Smoothed by σ ≥ 1.5 px, neighbouring pixels repeat each other: the Gaussian keeps 6 % (σ = 1.5) or less
  // (1 % at P/12 = 1.9 px) of the signal at the Nyquist frequency of every 2nd pixel, and the noise left is
  // correlated over ~2σ. A quarter of the samples then carries the same information, and the main match
  // is 4× cheaper. Below σ = 1.5 px the skipped pixels still carry independent noise.
  if (!pinned.subset_stride && settings.main_match.prefilter_sigma_px >= 1.5)
    settings.main_match.subset_stride = 2;
  // Along its ridges such a subset is pinned down only by the ridges' curvature: at this SNR that leaves
  // ~0.2 px of noise, which only neighbours further away (beyond the overlapping subsets) average out.
  // Fusing twice as wide, as strongly as the track's own information and until it settles, averages that
  // noise; the cost is a slightly rounded slip front (the stick radius' kink).
  if (!pinned.fusion) {
    settings.fusion.sigma_px = std::max(settings.fusion.sigma_px, 2.0 * settings.seeding.grid_step_px);
    settings.fusion.weight = std::max(settings.fusion.weight, 1.0);
    settings.fusion.sweeps = std::max(settings.fusion.sweeps, 16);
  }
}

// After update_roi: the smoothing covers the tracked region only, as the rest is never sampled.
void FeatureTracker::Impl::prepare_matching() {
  if (!settings.refine) return;
  if (settings.main_match.prefilter_sigma_px <= 0.0) {
    match_f = current_f;
  } else {
    // Zeros outside the region: anchors copy (and differentiate) the whole frame.
    if (match_f.size() != current_f.size() || match_f.data == current_f.data)
      match_f = cv::Mat::zeros(current_f.size(), CV_32F);
    cv::GaussianBlur(current_f(roi), match_f(roi), cv::Size(), settings.main_match.prefilter_sigma_px,
                     settings.main_match.prefilter_sigma_px, cv::BORDER_REPLICATE);
  }
  if (settings.main_match.solver.interpolation == Interpolation::kCubicBSpline)
    cubic_bspline_coefficients(match_f, roi, match_spline);
}

void FeatureTracker::Impl::update_roi(bool rebuild_previous) {
  cv::Rect box = cv::boundingRect(mask);
  if (box.area() == 0) box = cv::Rect(0, 0, size.width, size.height);
  const int margin = settings.prediction.window_px +
                     static_cast<int>(std::ceil(2.0 * settings.prediction.max_displacement_px)) + 8;
  box.x -= margin;
  box.y -= margin;
  box.width += 2 * margin;
  box.height += 2 * margin;
  box &= cv::Rect(0, 0, size.width, size.height);
  if (roi.area() > 0 && (box & roi) == box) return;
  roi = roi.area() > 0 ? (roi | box) : box;
  if (rebuild_previous && !previous_u8.empty()) {
    build_pyramid(previous_u8, previous_pyramid);
    if (settings.prediction.global_jump) {
      // The previous high-passed image must cover the new ROI too.
      cv::Mat previous_f;
      previous_u8.convertTo(previous_f, CV_32F, 1.0 / 255.0);
      high_pass(previous_f, jump.previous);
      jump.correlation.set_reference(jump.previous);
    }
  }
}

void FeatureTracker::Impl::build_pyramid(const cv::Mat& u8, std::vector<cv::Mat>& pyramid) const {
  cv::buildOpticalFlowPyramid(u8(roi), pyramid,
                              cv::Size(settings.prediction.window_px, settings.prediction.window_px),
                              settings.prediction.pyramid_levels);
}

// Ridges only, faded out towards the contact border: the border stays put while the skin moves, so its
// step would otherwise dominate the correlation and pull the global shift to zero. At half or quarter
// resolution, as long as the ridges stay at least 5 px apart there (high_pass_factor): the shift only has
// to reveal jumps of more than a quarter of the LK window, and at full resolution the filtering (a Gaussian
// of σ = P/2 over the ROI) costs ≈ 15 ms of a 640×512 frame.
void FeatureTracker::Impl::high_pass(const cv::Mat& image, cv::Mat& out) {
  const int factor = high_pass_factor();
  const double period = 4.0 * ridge_reach_px() / factor;
  cv::Mat view = image(roi);
  if (factor > 1) {
    cv::pyrDown(view, jump.small);
    if (factor == 4) {
      cv::pyrDown(jump.small, jump.quarter);
      std::swap(jump.small, jump.quarter);
    }
    view = jump.small;
    cv::resize(mask(roi), jump.mask, view.size(), 0.0, 0.0, cv::INTER_NEAREST);
  } else {
    jump.mask = mask(roi);
  }
  cv::GaussianBlur(view, jump.blur, cv::Size(0, 0), 0.5 * period);
  cv::subtract(view, jump.blur, out);
  jump.mask.convertTo(jump.weight, CV_32F);
  cv::erode(jump.weight, jump.weight, cv::Mat(), cv::Point(-1, -1), static_cast<int>(0.5 * period));
  cv::GaussianBlur(jump.weight, jump.weight, cv::Size(0, 0), 0.5 * period);
  cv::multiply(out, jump.weight, out);
}

int FeatureTracker::Impl::add_key_frame() {
  auto key = std::make_unique<KeyFrame>();
  key->frame = frame;
  if (settings.refine)
    key->anchor.assign(match_f, match_mask);
  else
    current_u8.copyTo(key->image_u8);
  // Reuse a released slot so the list does not grow over a long trial.
  for (std::size_t i = 0; i < keys.size(); ++i)
    if (!keys[i]) {
      keys[i] = std::move(key);
      return static_cast<int>(i);
    }
  keys.push_back(std::move(key));
  return static_cast<int>(keys.size() - 1);
}

void FeatureTracker::Impl::release_key(int key) {
  if (key < 0) return;
  KeyFrame& k = *keys[static_cast<std::size_t>(key)];
  if (--k.users == 0 && k.frame != frame) keys[static_cast<std::size_t>(key)].reset();
}

bool FeatureTracker::Impl::build_subsets(const AnchorImage& anchor, cv::Point centre, Subset& subset,
                                         Subset& wide) const {
  const int r = settings.main_match.subset_radius_px;
  const int side = 2 * (r / settings.main_match.subset_stride) + 1;
  if (!subset.build(anchor, centre, r, settings.main_match.subset_stride, settings.main_match.shape,
                    side * side / 3))
    return false;
  const int rw = std::max(r, settings.rounds.subset_radius_px);
  if (settings.rounds.enabled &&
      (rw > r || settings.rounds.subset_stride != settings.main_match.subset_stride)) {
    const int wside = 2 * (rw / settings.rounds.subset_stride) + 1;
    // On the image's lattice: the resampled rounds then resample and sum one pixel class only, whatever
    // the parity of the newborns' centres (PixelClasses).
    wide.build(anchor, centre, rw, settings.rounds.subset_stride, ShapeFunction::kTranslation,
               wside * wside / 3, Subset::Lattice::kImage);
  }
  return true;
}

FeatureTracker::FeatureTracker(TrackerOptions settings, std::optional<RoiPx> plate_roi)
    : impl_(std::make_unique<Impl>()) {
  settings.check();
  impl_->settings = std::move(settings);
  impl_->plate_roi = plate_roi;
}

FeatureTracker::~FeatureTracker() = default;

void FeatureTracker::start(const cv::Mat& image, const cv::Mat& contact_mask, double t_s) {
  start(image, contact_mask, t_s, {});
  impl_->points_mode = false;
}

void FeatureTracker::start(const cv::Mat& image, const cv::Mat& contact_mask, double t_s,
                           const std::vector<Vec2>& points_px) {
  Impl& m = *impl_;
  m.frame = -1;
  m.check_input(image, contact_mask);
  m.frame = 0;
  m.size = image.size();
  m.tracks.clear();
  m.states.clear();
  m.keys.clear();
  m.roi = cv::Rect();
  m.stats = FrameStats{};
  m.prepare(image, contact_mask);
  m.adapt_to_texture(!points_px.empty() ? static_cast<double>(points_px.size())
                                        : cv::countNonZero(m.mask) / (m.settings.seeding.grid_step_px *
                                                                      m.settings.seeding.grid_step_px));
  m.update_roi(false);
  m.prepare_matching();
  m.build_pyramid(m.current_u8, m.previous_pyramid);
  if (m.settings.prediction.global_jump) {
    m.high_pass(m.current_f, m.jump.previous);
    m.jump.correlation.set_reference(m.jump.previous);
  }
  m.add_key_frame();
  m.size_main_subsets_for_affine_test();
  // The measured outline moves by a pixel or two from frame to frame: only skin this far beyond where frame
  // 0 seeded counts as a contact that grew.
  constexpr int kGrowthTolerancePx = 4;
  const int margin =
      std::max(0, static_cast<int>(std::ceil(m.settings.seeding.border_margin_px)) - kGrowthTolerancePx);
  cv::erode(m.mask, m.first_seeded,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
  m.rest.count = 0;
  // Noise-free frames gain nothing from a mean anchor, and would only risk the blur of a slow creep.
  const bool noisy = !m.settings.texture.adapt || m.texture.snr < m.settings.texture.min_unfiltered_snr;
  m.rest.active = m.settings.refine && m.settings.rest.average_frames > 1 && noisy;
  if (m.rest.active) {
    m.rest.sum = m.match_f.clone();
    m.rest.mask = m.match_mask.clone();
    m.rest.count = 1;
  }
  m.points_mode = !points_px.empty();
  if (m.points_mode) {
    for (const Vec2& p : points_px) {
      if (!(std::isfinite(p.x) && std::isfinite(p.y)) || p.x < 0 || p.y < 0 || p.x > m.size.width - 1 ||
          p.y > m.size.height - 1)
        throw Error("point (" + std::to_string(p.x) + ", " + std::to_string(p.y) + ") lies outside the " +
                    std::to_string(m.size.width) + "x" + std::to_string(m.size.height) + " frame");
      m.create_track(p, p, Mat2d::Identity(), {}, 0, TrackStatus::kTracked);
    }
  } else {
    m.seed_grid();
  }
  for (std::size_t i = 0; i < m.states.size(); ++i) {
    m.states[i].candidate = m.tracks[i].position_px;
    m.states[i].previous = m.tracks[i].position_px;
  }
  if (m.plate_roi) {
    PlateOptions ps;
    ps.subset_radius_px = m.settings.plate.subset_radius_px;
    ps.grid_step_px = m.settings.plate.grid_step_px;
    ps.prefilter_sigma_px = m.settings.plate.prefilter_sigma_px;
    m.plate.emplace();
    m.plate->start(m.current_f, m.current_u8, *m.plate_roi, ps, t_s);
  }
  if (m.keys[0]->users == 0 && !m.settings.births.enabled) m.keys[0].reset();
  std::swap(m.previous_u8, m.current_u8);
  m.stats.frame = 0;
  m.stats.alive = static_cast<int>(
      std::count_if(m.tracks.begin(), m.tracks.end(), [](const Track& t) { return is_alive(t.status); }));
  m.stats.born = m.stats.alive;
}

const FrameStats& FeatureTracker::track(const cv::Mat& image, const cv::Mat& contact_mask, double t_s) {
  Impl& m = *impl_;
  if (m.frame < 0) throw Error("FeatureTracker::track called before start");
  m.check_input(image, contact_mask);
  m.begin_frame(image, contact_mask);
  m.predict_and_match();
  m.refine_matches();
  m.retire_lost();
  m.finish_frame();
  m.follow_rest();
  m.report_local_fits();
  m.report_affine_fit();
  if (!m.points_mode && m.settings.births.enabled && m.frame % m.settings.births.interval_frames == 0)
    m.births();
  if (m.plate) m.plate->track(m.current_f, m.current_u8, t_s);
  m.end_frame();
  return m.stats;
}

void FeatureTracker::Impl::begin_frame(const cv::Mat& image, const cv::Mat& contact_mask) {
  ++frame;
  stats = FrameStats{};
  stats.frame = frame;
  prepare(image, contact_mask);
  update_roi(true);
  prepare_matching();
  build_pyramid(current_u8, current_pyramid);
  for (Track& t : tracks)
    if (t.status == TrackStatus::kBorn || t.status == TrackStatus::kRecovered ||
        t.status == TrackStatus::kUnchecked)
      t.status = TrackStatus::kTracked;
}

// After the main match: the neighbour check, the shape rounds (resampled, then subset by subset), the
// tracks' own matches recorded, fusion where it is within the match noise; unrefined tracks re-anchored.
void FeatureTracker::Impl::refine_matches() {
  if (settings.refine && settings.neighbours.enabled) check_neighbours();
  field.done.clear();
  if (settings.refine && settings.rounds.enabled && settings.rounds.resampled) resampled_shape_pass();
  if (!schedule.skipped.empty()) match_unconfirmed_skipped();
  if (settings.refine && settings.rounds.enabled)
    for (int k = 0; k < settings.rounds.iterations; ++k)
      fixed_shape_pass(k + 1 == settings.rounds.iterations);
  if (settings.refine) record_own_matches();
  if (settings.refine && settings.fusion.sigma_px > 0.0) {
    fuse();
    decline_fusion_beyond_noise();
  }
  if (!settings.refine && settings.reanchor.interval_frames > 0 &&
      frame % settings.reanchor.interval_frames == 0)
    reanchor();
}

// Tracks whose match failed, that left the image or left the contact, retired with the reason.
void FeatureTracker::Impl::retire_lost() {
  for (int i : alive) {
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status)) continue;
    TrackState& st = states[static_cast<std::size_t>(i)];
    if (st.suspect) {
      if (!settings.refine)
        retire(i, TrackStatus::kForwardBackward);
      else
        retire(i, st.match.valid_fraction < settings.main_match.solver.min_valid_fraction
                      ? TrackStatus::kLeftContact
                      : TrackStatus::kPoorMatch);
      continue;
    }
    const Vec2 p = st.candidate;
    if (p.x < 0 || p.y < 0 || p.x > size.width - 1 || p.y > size.height - 1) {
      retire(i, TrackStatus::kLeftImage);
      continue;
    }
    if (!points_mode && !inside_mask(mask, p)) retire(i, TrackStatus::kLeftContact);
  }
}

// Key frames nobody anchors to any more are dropped; this frame becomes the previous one.
void FeatureTracker::Impl::end_frame() {
  for (auto& k : keys)
    if (k && k->users == 0) k.reset();
  std::swap(previous_pyramid, current_pyramid);
  std::swap(previous_u8, current_u8);
  std::swap(jump.previous, jump.current);
  // The high-passed frame correlated this frame is the next reference (its spectrum kept); otherwise the
  // reference follows whatever jump.previous now holds.
  if (!jump.correlation.adopt_last_as_reference() && !jump.previous.empty())
    jump.correlation.set_reference(jump.previous);
  stats.alive = static_cast<int>(
      std::count_if(tracks.begin(), tracks.end(), [](const Track& t) { return is_alive(t.status); }));
}

int FeatureTracker::frame_index() const {
  return impl_->frame;
}
const std::vector<Track>& FeatureTracker::tracks() const {
  return impl_->tracks;
}
const FrameStats& FeatureTracker::stats() const {
  return impl_->stats;
}
const TrackerOptions& FeatureTracker::settings() const {
  return impl_->settings;
}
const TextureQuality& FeatureTracker::texture() const {
  return impl_->texture;
}
bool FeatureTracker::low_snr_texture() const {
  return impl_->low_snr;
}

const MainSubsetSizing& FeatureTracker::main_subset_sizing() const {
  return impl_->sizing;
}

std::optional<Vec2> FeatureTracker::plate_displacement_px() const {
  if (!impl_->plate) return std::nullopt;
  return impl_->plate->displacement_px();
}

std::optional<std::int8_t> FeatureTracker::plate_status() const {
  if (!impl_->plate) return std::nullopt;
  return static_cast<std::int8_t>(impl_->plate->status());
}

}  // namespace tirstrain::flow
