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
#include <deque>
#include <numbers>
#include <numeric>
#include <string>

#include "core/error.hpp"
#include "flow/mask_erosion.hpp"
#include "flow/phase_correlation.hpp"
#include "flow/plate.hpp"
#include "flow/shape_field.hpp"
#include "flow/shi_tomasi.hpp"

namespace tirstrain::flow {
namespace {

using Mat2d = Eigen::Matrix2d;

struct KeyFrame {
  int frame = 0;
  AnchorImage anchor;
  cv::Mat image_u8;  // for re-anchoring unrefined tracks by LK
  int users = 0;
};

struct TrackState {
  int key = -1;
  Subset subset;
  Subset wide;  // the fixed-shape pass's subset when it is larger than `subset`
  Warp warp;
  Vec2 offset;                            // track point minus subset centre, in the anchor frame
  Mat2d birth = Mat2d::Identity();        // d(anchor position)/dX: identity for frame-0 tracks
  Mat2d deformation = Mat2d::Identity();  // F = dx/dX now
  Vec2 velocity;                          // motion over the last frame
  Vec2 previous;                          // position in the previous frame
  Vec2 guess;                             // where this frame's match started
  Vec2 candidate;                         // this frame's match
  Vec2 anchor_point;                      // the track's position in its anchor frame
  bool lk_ok = false;
  bool matched = false;
  bool suspect = false;
  bool fixed_shape = false;
  bool exact_reference = false;  // anchored to frame 0 without a birth map: X is a matched frame-0 pixel
  // The information of the subset the fixed-shape pass matched this frame for its translation.
  Eigen::Matrix2d fixed_information = Eigen::Matrix2d::Zero();
  MatchResult match;
  // This frame's main subset match (match_track), when the track took one: the rest test's evidence, as
  // its subset alone decides it (the later rounds blend in the neighbours' field).
  int main_frame = -1;
  OwnMatch main;
  // This frame's own match before any model (record_own_matches): what a model must stay within.
  bool own_valid = false;
  OwnMatch own;
  TrackModel model = TrackModel::kOwnMatch;
  double model_mahalanobis2 = std::numeric_limits<double>::quiet_NaN();
};

// A contact with fewer grid points than this is small enough to be mostly border (adapt_to_texture).
constexpr double kFewTracks = 300.0;
// Texture without ridges: the noise the final (fixed-shape) subset is sized for, px.
constexpr double kTargetNoisePx = 0.01;

bool inside_mask(const cv::Mat& mask, Vec2 p) {
  const long ix = std::lround(p.x), iy = std::lround(p.y);
  if (ix < 0 || iy < 0 || ix >= mask.cols || iy >= mask.rows) return false;
  return mask.ptr<std::uint8_t>(static_cast<int>(iy))[ix] != 0;
}

double median_in_place(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

Mat2d to_matrix(const Gradient2& g) {
  Mat2d m;
  m << g.xx, g.xy, g.yx, g.yy;
  return m;
}

}  // namespace

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

void to_float_image(const cv::Mat& image, cv::Mat& out) {
  switch (image.depth()) {
    case CV_8U:
      image.convertTo(out, CV_32F, 1.0 / 255.0);
      return;
    case CV_16U:
      image.convertTo(out, CV_32F, 1.0 / 65535.0);
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
  to_float_image(image, out);
  return out;
}

void to_u8_image(const cv::Mat& image, cv::Mat& out) {
  switch (image.depth()) {
    case CV_8U:
      image.copyTo(out);
      return;
    case CV_16U:
      image.convertTo(out, CV_8U, 1.0 / 257.0);
      return;
    case CV_32F:
      image.convertTo(out, CV_8U, 255.0);
      return;
    default:
      throw Error("unsupported image type (expected 8-bit, 16-bit or float grey)");
  }
}

struct FeatureTracker::Impl {
  TrackerSettings settings;
  std::optional<RoiPx> plate_roi;
  std::optional<PlateTracker> plate;

  std::vector<Track> tracks;
  // A deque: a track's state is ~5.6 kB, and a vector's growth copied all of them into fresh memory at
  // every birth that passed its capacity. On the goal trial that birth frame's 3400 page faults made it
  // take 4× a normal frame; the deque touches only the newborns' memory.
  std::deque<TrackState> states;
  std::vector<std::unique_ptr<KeyFrame>> keys;
  FrameStats stats;
  int frame = -1;
  bool points_mode = false;
  cv::Size size;
  double eigen_threshold = 0.0;

  // Where frame 0 seeded tracks, with a tolerance for the outline's jitter: its contact eroded by a little
  // less than border_margin_px (start()).
  cv::Mat first_seeded;
  cv::Mat current_f, current_u8, previous_u8, mask, match_mask, birth_mask, eigen, eigen_scratch;
  cv::Mat erosion_scratch;
  cv::Mat match_f;  // what subsets are matched in: current_f, smoothed by prefilter_sigma_px
  TextureQuality texture;
  bool low_snr = false;
  cv::Rect roi;
  std::vector<cv::Mat> previous_pyramid, current_pyramid;
  cv::Mat previous_hp, current_hp, hp_blur, hp_weight, hp_small, hp_quarter, hp_mask;
  PhaseCorrelator global_correlation;  // current_hp against previous_hp
  // Until the skin first moves (resting), frame 0's anchor is averaged over the frames so far (rest_count
  // of them, up to rest_average_frames; 0: averaging over or off) and tracks report the fitted rest motion.
  bool resting = false;
  cv::Mat rest_sum, rest_mask;
  int rest_count = 0;

  // Per-frame scratch, reused.
  std::vector<int> alive;
  std::vector<cv::Point2f> lk_from, lk_to, lk_back;
  std::vector<unsigned char> lk_status, lk_back_status, lk_check_status;
  std::vector<int> lk_check;
  std::vector<cv::Point2f> lk_back_from, lk_back_to;
  std::vector<float> lk_error;
  std::vector<double> scratch_x, scratch_y;
  std::vector<int> retry;
  // fuse(): per alive track, what its sweeps need besides the neighbours' current positions.
  struct FusionTerm {
    bool active = false;
    Eigen::Matrix2d solve = Eigen::Matrix2d::Zero();  // (own information + alpha I)^-1
    Eigen::Vector2d constant = Eigen::Vector2d::Zero();
    double scale = 0.0;  // alpha / sum of the neighbours' weights
  };
  std::vector<Vec2> fused;
  std::vector<FusionTerm> fusion_terms;
  std::vector<std::vector<std::pair<int, double>>> fusion_neighbours;
  std::vector<Warp> shapes;
  std::vector<Mat2d> smoothed;
  // Spatial hash of live tracks by current position.
  int hash_cols = 0, hash_rows = 0;
  double hash_cell = 1.0;
  std::vector<int> hash_start, hash_items, hash_fill;
  std::vector<std::uint8_t> lattice_taken;
  std::vector<int> neighbours, exact;
  std::vector<cv::Mat> anchor_pyramid;
  ShapeField shape_field;
  cv::Mat resampled, resampled_valid;
  WindowSums window_sums;  // of each round's resampled frame, for the subsets' translation steps
  std::vector<Vec2> field_anchor, field_displacement;
  std::vector<std::uint8_t> resampled_done;
  std::vector<Vec2> resampled_position;
  std::vector<MatchResult> resampled_match;
  std::vector<double> resampled_moved;
  std::vector<int> eligible, others;
  // Tracks that skip this frame's main match (main_match_period_frames), and the tracks that take it.
  std::vector<std::uint8_t> skip_match;
  std::vector<int> to_match, skipped;

  void check_input(const cv::Mat& image, const cv::Mat& contact_mask) const;
  void prepare(const cv::Mat& image, const cv::Mat& contact_mask);
  void update_roi(bool rebuild_previous);
  void prepare_matching();
  // `expected_tracks`: the points given, or the grid points the contact holds.
  void adapt_to_texture(double expected_tracks);
  void build_pyramid(const cv::Mat& u8, std::vector<cv::Mat>& pyramid) const;
  void high_pass(const cv::Mat& image, cv::Mat& out);
  int add_key_frame();
  void release_key(int key);
  bool create_track(Vec2 position, Vec2 reference, const Mat2d& birth, Vec2 velocity, int key,
                    TrackStatus status);
  void seed_grid();
  void predict_and_match();
  bool skips_main_match(int index) const;
  void start_skipped_from_neighbours();
  void match_unconfirmed_skipped();
  void match_from_guesses(const std::vector<int>& indices);
  void match_track(int index, Vec2 guess, const Warp* initial);
  void build_hash(bool matched_only);
  void gather_neighbours(Vec2 p, double radius, int self);
  bool predict_from_neighbours(int index, Vec2& predicted, Mat2d& deformation);
  void check_neighbours();
  // `last`: the final round, which converges to match.convergence_px (the others stop at
  // fixed_shape_convergence_px).
  void fixed_shape_pass(bool last);
  void resampled_shape_pass();
  void reanchor();
  void fuse();
  void retire(int index, TrackStatus why);
  void births();
  enum class FirstFrameBirth { kBorn, kFailed, kNotSeen };
  FirstFrameBirth birth_from_first_frame(Vec2 x, Vec2 reference, const Mat2d& dX_dx, Vec2 velocity);
  void finish_frame();
  bool build_subsets(const AnchorImage& anchor, cv::Point centre, Subset& subset, Subset& wide) const;
  // The wide subset of a frame-0 track is matched through the resampled rounds' box sums, which read the
  // reference from the anchor: its per-pixel copy is dropped (Subset::release_pixels) and built again only
  // if the subset-by-subset pass needs it.
  void release_wide_pixels(TrackState& st) const {
    if (st.key == 0 && st.exact_reference && settings.refine && settings.fixed_shape_pass &&
        settings.fixed_shape_resampled)
      st.wide.release_pixels();
  }
  void record_own_matches();
  void decline_fusion_beyond_noise();
  RestTestOptions rest_test_options() const;
  void follow_rest();
  double ridge_reach_px() const { return 0.25 * settings.window_px; }
  // The global shift's images are reduced by 2 or 4 while the ridges stay at least 5 px apart there.
  int high_pass_factor() const {
    const double period = settings.ridge_period_px > 0.0 ? settings.ridge_period_px : settings.window_px;
    int factor = 1;
    while (factor < 4 && period / (2 * factor) >= 5.0) factor *= 2;
    return factor;
  }
};

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
}

void FeatureTracker::Impl::prepare(const cv::Mat& image, const cv::Mat& contact_mask) {
  to_float_image(image, current_f);
  to_u8_image(image, current_u8);
  if (contact_mask.empty())
    mask = cv::Mat(image.size(), CV_8U, cv::Scalar(1));
  else
    cv::compare(contact_mask, 0, mask, cv::CMP_NE);
  if (settings.refine) {
    // Eroded only around the contact (its bounding box grown past both kernels' reach, where the mask is 0
    // as it is everywhere else), and the 0.6 P ellipse by erode_ellipse: the same mask, and cv::erode's
    // ellipse over the whole frame was 5-8 % of the tracker's instructions on the 640×512 goal trial.
    const int e = static_cast<int>(std::lround(settings.border_exclusion_px));
    cv::Rect box = cv::boundingRect(mask);
    const int reach = e + 3;
    box = cv::Rect(box.x - reach, box.y - reach, box.width + 2 * reach, box.height + 2 * reach) &
          cv::Rect(0, 0, mask.cols, mask.rows);
    match_mask.create(mask.size(), CV_8U);
    match_mask.setTo(0);
    if (box.area() > 0) {
      cv::Mat eroded = match_mask(box);
      erode_for_matching(mask(box), erosion_scratch);
      erode_ellipse(erosion_scratch, std::max(0, e), eroded);
    }
  }
}

// Frame 0 decides how much model the subsets can afford (TrackerSettings::adapt_to_texture).
void FeatureTracker::Impl::adapt_to_texture(double expected_tracks) {
  texture = TextureQuality{};
  low_snr = false;
  if (!settings.refine) return;
  const double period = settings.ridge_period_px > 0.0 ? settings.ridge_period_px : settings.window_px;
  // The resampled rounds (step 7) carry a track where neighbours surround it; on a contact of a few hundred
  // grid points most tracks are border tracks, whose main match counts on its own, so there the main match
  // keeps the second-order subset on every pixel (hard_tiny_contact, 31 tracks: 0.149 px, against 0.186
  // with the affine seed on every 2nd pixel).
  if (settings.adapt_to_texture && settings.fixed_shape_resampled && expected_tracks < kFewTracks) {
    if (!settings.pinned.shape) settings.shape = ShapeFunction::kQuadratic;
    if (!settings.pinned.subset_stride) settings.subset_stride = 1;
    if (!settings.pinned.fixed_shape_stride) settings.fixed_shape_stride = 1;
    if (!settings.pinned.main_match_period) settings.main_match_period_frames = 1;
  }
  texture = measure_texture(current_f, mask, period);
  if (!settings.adapt_to_texture || texture.pixels == 0) return;
  // Without ridges (speckle, any isotropic texture) the smoothing and the low-SNR subsets below, sized from
  // the ridge period and tuned on ridges, do not apply: the subsets keep the preset's sizes. Unsmoothed,
  // neighbouring pixels carry independent noise, so a subset sampled on every s-th pixel would see s² times
  // the noise variance: every pixel is matched.
  if (!texture.ridges) {
    if (!settings.pinned.subset_stride) settings.subset_stride = 1;
    if (!settings.pinned.fixed_shape_stride) settings.fixed_shape_stride = 1;
    // The wide subset that sets the final positions grows (up to twice the preset's) until its
    // predicted noise reaches kTargetNoisePx: sqrt(2 σ_n² / (n ⟨g²⟩)) with n = (2r + 1)² pixels.
    if (!settings.pinned.subset_radius && texture.gradient_energy > 0.0) {
      const double side = std::sqrt(2.0 * texture.noise_sigma * texture.noise_sigma /
                                    (kTargetNoisePx * kTargetNoisePx * texture.gradient_energy));
      const int wide = std::max(settings.fixed_shape_radius_px, settings.subset_radius_px);
      settings.fixed_shape_radius_px =
          std::clamp(static_cast<int>(std::ceil(0.5 * (side - 1.0))), wide, 2 * wide);
    }
    return;
  }
  if (texture.snr >= settings.min_unfiltered_snr) return;
  // Light smoothing keeps 97 % of the ridge contrast and takes most pixel noise out of the reference
  // gradients: faster convergence and a lower error on noisy frames (not on noise-free ones).
  const auto& pinned = settings.pinned;
  if (!pinned.prefilter)
    settings.prefilter_sigma_px =
        std::max(settings.prefilter_sigma_px, std::round(10.0 * period / 24.0) / 10.0);
  if (texture.snr >= settings.min_quadratic_snr) return;
  low_snr = true;
  // Every track matched every frame: with tracks starting from their neighbours, the rounds left 2
  // track-frames 1.0-1.13 px off in hard_heavy_noise's first 20 frames (none with the main match, which the
  // neighbour check then weighs; Tracker.HeavyNoiseRoundsOverruleADisagreeingMainMatch).
  if (!pinned.main_match_period) settings.main_match_period_frames = 1;
  if (!pinned.shape && settings.shape == ShapeFunction::kQuadratic) settings.shape = ShapeFunction::kAffine;
  if (!pinned.prefilter)
    settings.prefilter_sigma_px =
        std::max(settings.prefilter_sigma_px, std::round(10.0 * period / 12.0) / 10.0);
  if (!pinned.subset_radius)
    settings.subset_radius_px =
        std::max(settings.subset_radius_px, static_cast<int>(std::lround(0.75 * period)));
  // Smoothed by σ ≥ 1.5 px, neighbouring pixels repeat each other: the Gaussian keeps 6 % (σ = 1.5) or less
  // (1 % at P/12 = 1.9 px) of the signal at the Nyquist frequency of every 2nd pixel, and the noise left is
  // correlated over ~2σ. A quarter of the samples then carries the same information; the main match is
  // 4× cheaper (hard_heavy_noise 0.1396 → 0.1369 px, hard_low_contrast 0.1550 → 0.1522 px, +25 % frames/s
  // tracking only; on the default scene's σ = 1 px it would cost 1 % of accuracy, so not there).
  if (!pinned.subset_stride && settings.prefilter_sigma_px >= 1.5) settings.subset_stride = 2;
  // Along its ridges such a subset is pinned down only by the ridges' curvature: at this SNR that leaves
  // ~0.2 px of noise, which only neighbours further away (beyond the overlapping subsets) average out.
  // Fusing twice as wide, as strongly as the track's own information and until it settles, halves the
  // strain noise (hard_heavy_noise: E_yy 0.013 → 0.009, U 5.9 → 4.3 %; the stick radius, whose slip
  // profile has a kink that the smoothing rounds, 8 → 12 %).
  if (!pinned.fusion) {
    settings.fusion_sigma_px = std::max(settings.fusion_sigma_px, 2.0 * settings.grid_step_px);
    settings.fusion_weight = std::max(settings.fusion_weight, 1.0);
    settings.fusion_sweeps = std::max(settings.fusion_sweeps, 16);
  }
}

// After update_roi: the smoothing covers the tracked region only, as the rest is never sampled.
void FeatureTracker::Impl::prepare_matching() {
  if (!settings.refine) return;
  if (settings.prefilter_sigma_px <= 0.0) {
    match_f = current_f;
    return;
  }
  // Zeros outside the region: anchors copy (and differentiate) the whole frame.
  if (match_f.size() != current_f.size() || match_f.data == current_f.data)
    match_f = cv::Mat::zeros(current_f.size(), CV_32F);
  cv::GaussianBlur(current_f(roi), match_f(roi), cv::Size(), settings.prefilter_sigma_px,
                   settings.prefilter_sigma_px, cv::BORDER_REPLICATE);
}

void FeatureTracker::Impl::update_roi(bool rebuild_previous) {
  cv::Rect box = cv::boundingRect(mask);
  if (box.area() == 0) box = cv::Rect(0, 0, size.width, size.height);
  const int margin = settings.window_px + static_cast<int>(std::ceil(2.0 * settings.max_displacement_px)) + 8;
  box.x -= margin;
  box.y -= margin;
  box.width += 2 * margin;
  box.height += 2 * margin;
  box &= cv::Rect(0, 0, size.width, size.height);
  if (roi.area() > 0 && (box & roi) == box) return;
  roi = roi.area() > 0 ? (roi | box) : box;
  if (rebuild_previous && !previous_u8.empty()) {
    build_pyramid(previous_u8, previous_pyramid);
    if (settings.global_prediction) {
      // The previous high-passed image must cover the new ROI too.
      cv::Mat previous_f;
      previous_u8.convertTo(previous_f, CV_32F, 1.0 / 255.0);
      high_pass(previous_f, previous_hp);
      global_correlation.set_reference(previous_hp);
    }
  }
}

void FeatureTracker::Impl::build_pyramid(const cv::Mat& u8, std::vector<cv::Mat>& pyramid) const {
  cv::buildOpticalFlowPyramid(u8(roi), pyramid, cv::Size(settings.window_px, settings.window_px),
                              settings.pyramid_levels);
}

// Ridges only, faded out towards the contact border: the border stays put while the skin moves, so its
// step would otherwise dominate the correlation and pull the global shift to zero. At half or quarter
// resolution, as long as the ridges stay at least 5 px apart there (high_pass_factor): the shift only has
// to reveal jumps of more than a quarter of the LK window, and the full-resolution filtering (a Gaussian of
// σ = P/2 over the ROI) took ≈ 15 ms of a 640×512 frame; at half resolution the correlation's DFTs were
// still 8 % of the tracker's instructions on the goal trial (quarter resolution since session 16).
void FeatureTracker::Impl::high_pass(const cv::Mat& image, cv::Mat& out) {
  const int factor = high_pass_factor();
  const double period = 4.0 * ridge_reach_px() / factor;
  cv::Mat view = image(roi);
  if (factor > 1) {
    cv::pyrDown(view, hp_small);
    if (factor == 4) {
      cv::pyrDown(hp_small, hp_quarter);
      std::swap(hp_small, hp_quarter);
    }
    view = hp_small;
    cv::resize(mask(roi), hp_mask, view.size(), 0.0, 0.0, cv::INTER_NEAREST);
  } else {
    hp_mask = mask(roi);
  }
  cv::GaussianBlur(view, hp_blur, cv::Size(0, 0), 0.5 * period);
  cv::subtract(view, hp_blur, out);
  hp_mask.convertTo(hp_weight, CV_32F);
  cv::erode(hp_weight, hp_weight, cv::Mat(), cv::Point(-1, -1), static_cast<int>(0.5 * period));
  cv::GaussianBlur(hp_weight, hp_weight, cv::Size(0, 0), 0.5 * period);
  cv::multiply(out, hp_weight, out);
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
  const int r = settings.subset_radius_px;
  const int side = 2 * (r / settings.subset_stride) + 1;
  if (!subset.build(anchor, centre, r, settings.subset_stride, settings.shape, side * side / 3)) return false;
  const int rw = std::max(r, settings.fixed_shape_radius_px);
  if (settings.fixed_shape_pass && (rw > r || settings.fixed_shape_stride != settings.subset_stride)) {
    const int wside = 2 * (rw / settings.fixed_shape_stride) + 1;
    // On the image's lattice: the resampled rounds then resample and sum one pixel class only, whatever
    // the parity of the newborns' centres (PixelClasses).
    wide.build(anchor, centre, rw, settings.fixed_shape_stride, ShapeFunction::kTranslation,
               wside * wside / 3, Subset::Lattice::kImage);
  }
  return true;
}

// Each matched track's own position and its predicted noise, before any model (the fusion, the rest fit)
// may stand in for it: the evidence those models are tested against.
void FeatureTracker::Impl::record_own_matches() {
  for (int i : alive) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    st.model = TrackModel::kOwnMatch;
    st.model_mahalanobis2 = std::numeric_limits<double>::quiet_NaN();
    st.own_valid = is_alive(tracks[static_cast<std::size_t>(i)].status) && st.matched && !st.suspect;
    if (!st.own_valid) continue;
    const Subset& matched = st.fixed_shape && !st.wide.empty() ? st.wide : st.subset;
    const Eigen::Matrix2d& information =
        st.fixed_shape ? st.fixed_information : st.subset.translation_information();
    st.own.reference_px = tracks[static_cast<std::size_t>(i)].reference_px;
    st.own.position_px = st.candidate;
    st.own.covariance_px2 =
        predicted_match_covariance(st.match.zncc, matched.pixel_count(), information,
                                   correlated_pixels(settings.prefilter_sigma_px, matched.stride()));
  }
}

// The fusion decides the directions a subset's texture leaves open (along its ridges); where it moves a
// track further than that track's own match allows, it speaks for a motion the match does not show (a
// sharp local feature, a short wavelength), and the own match stands.
void FeatureTracker::Impl::decline_fusion_beyond_noise() {
  for (int i : alive) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    if (!st.own_valid) continue;
    const Vec2 shift{st.candidate.x - st.own.position_px.x, st.candidate.y - st.own.position_px.y};
    if (shift.x == 0.0 && shift.y == 0.0) continue;
    const double d2 = mahalanobis2(shift, st.own.covariance_px2);
    if (d2 <= kModelShiftChi2) {
      st.model = TrackModel::kFused;
      st.model_mahalanobis2 = d2;
      ++stats.fused;
    } else {
      st.candidate = st.own.position_px;
      ++stats.fusion_declined;
    }
  }
}

// Two tracks' main matches are independent when no pixel of one's subset (smoothed by the prefilter) enters
// the other's.
RestTestOptions FeatureTracker::Impl::rest_test_options() const {
  RestTestOptions o;
  o.max_chi2_per_dof = settings.rest_max_chi2_per_dof;
  o.max_correlation_z = settings.rest_max_correlation_z;
  const double reach = settings.subset_radius_px + 2.0 * settings.prefilter_sigma_px;
  o.independence_px = 2.0 * reach + 1.0;
  o.pair_band_px = 2.0 * settings.grid_step_px;
  o.tolerance_px = settings.rest_tolerance_px;
  o.max_motion_chi2 = settings.rest_max_motion_chi2;
  o.correlated_tracks = std::numbers::pi * std::pow(reach / settings.grid_step_px, 2);
  return o;
}

// While nothing has moved since frame 0, frame 0's anchor becomes the mean of the frames so far (see
// TrackerSettings::rest_average_frames): every later match then sees the anchor's pixel noise divided by
// the square root of their number; and the tracks report the fitted rest motion rather than their own
// noise. Rest is a test of an affine fit of the frame-0 tracks' own matches against their predicted
// noise (test_affine_model).
void FeatureTracker::Impl::follow_rest() {
  if (!resting) return;
  const auto end_averaging = [this] {
    rest_count = 0;
    rest_sum.release();
    rest_mask.release();
  };
  const auto stop = [&] {
    resting = false;
    end_averaging();
  };
  if (keys.empty() || !keys[0] || keys[0]->frame != 0) return stop();
  // Tested on the tracks whose own subset matched them this frame; reported on every frame-0 track.
  std::vector<int> members;
  std::vector<OwnMatch> tested;
  for (int i : alive) {
    const Track& t = tracks[static_cast<std::size_t>(i)];
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(t.status) || st.key != 0 || !st.exact_reference || !st.own_valid) continue;
    members.push_back(i);
    if (st.main_frame == frame) tested.push_back(st.main);
  }
  const RestTest test = test_affine_model(tested, rest_test_options());
  stats.rest_tested = true;
  stats.rest_chi2_per_dof = test.chi2_per_dof;
  stats.rest_correlation_z = test.correlation_z;
  stats.rest_pairs = test.pairs;
  stats.rest_motion_px = test.motion_rms_px;
  if (!test.accepted) return stop();
  // At rest each track's own position carries the pixel noise of its subset (≈ 0.3 px along the ridges near
  // the border of a noisy contact), while the motion is the fit: each track reports the fit where it lies
  // within its own match's noise, and keeps its match where not.
  stats.at_rest = true;
  const Gradient2 gradient = test.gradient();
  for (int i : members) {
    Track& t = tracks[static_cast<std::size_t>(i)];
    const OwnMatch& own = states[static_cast<std::size_t>(i)].own;
    const Vec2 d = test.displacement_px(t.reference_px);
    const Vec2 on_fit{t.reference_px.x + d.x, t.reference_px.y + d.y};
    const double d2 =
        mahalanobis2({on_fit.x - own.position_px.x, on_fit.y - own.position_px.y}, own.covariance_px2);
    if (!(d2 <= kModelShiftChi2)) continue;  // a motion of its own: it keeps what it reports
    t.position_px = on_fit;
    t.gradient = gradient;
    t.model = TrackModel::kRestFit;
    t.model_mahalanobis2 = d2;
    ++stats.on_rest_fit;
  }
  stats.fused = static_cast<int>(std::count_if(tracks.begin(), tracks.end(), [](const Track& t) {
    return is_alive(t.status) && t.model == TrackModel::kFused;
  }));
  if (rest_count < 1 || rest_count >= settings.rest_average_frames) return end_averaging();
  rest_sum += match_f;
  ++rest_count;
  KeyFrame& key = *keys[0];
  key.anchor.assign(rest_sum * (1.0 / rest_count), rest_mask);
  for (int i : members) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    Subset subset, wide;
    if (!build_subsets(key.anchor, st.subset.centre(), subset, wide)) continue;
    st.subset = std::move(subset);
    st.wide = std::move(wide);
    release_wide_pixels(st);
  }
  ++stats.rest_frames_averaged;
}

bool FeatureTracker::Impl::create_track(Vec2 position, Vec2 reference, const Mat2d& birth, Vec2 velocity,
                                        int key, TrackStatus status) {
  TrackState st;
  st.key = key;
  const cv::Point centre(static_cast<int>(std::lround(position.x)),
                         static_cast<int>(std::lround(position.y)));
  st.offset = {position.x - centre.x, position.y - centre.y};
  st.birth = birth;
  st.exact_reference = keys[static_cast<std::size_t>(key)]->frame == 0 && birth.isIdentity();
  st.deformation = birth.inverse();
  st.velocity = velocity;
  st.previous = position;
  st.anchor_point = position;
  Track t;
  t.id = static_cast<std::int64_t>(tracks.size());
  t.reference_px = reference;
  t.position_px = position;
  t.status = status;
  t.born_frame = frame;
  t.zncc = 1.0;
  if (settings.refine) {
    const bool ok = build_subsets(keys[static_cast<std::size_t>(key)]->anchor, centre, st.subset, st.wide);
    if (!ok) {
      if (!points_mode) return false;
      // A point the user asked for is kept in the output, retired at once.
      t.status = TrackStatus::kPoorMatch;
      t.retired_frame = frame;
      tracks.push_back(t);
      st.key = -1;
      states.push_back(std::move(st));
      return true;
    }
  }
  ++keys[static_cast<std::size_t>(key)]->users;
  release_wide_pixels(st);
  tracks.push_back(t);
  states.push_back(std::move(st));
  return true;
}

void FeatureTracker::Impl::seed_grid() {
  const int margin = static_cast<int>(std::ceil(settings.border_margin_px));
  cv::erode(mask, birth_mask,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
  min_eigenvalue_map(current_f(roi), settings.eigen_block_px, eigen, eigen_scratch);
  double largest = 0.0;
  cv::minMaxLoc(eigen, nullptr, &largest, nullptr, nullptr, birth_mask(roi));
  eigen_threshold = settings.min_eigen_quality * largest;
  struct Candidate {
    float strength;
    cv::Point p;
  };
  std::vector<Candidate> candidates;
  const double step = settings.grid_step_px;
  const int i0 = static_cast<int>(std::ceil(roi.x / step)),
            i1 = static_cast<int>((roi.x + roi.width - 1) / step);
  const int j0 = static_cast<int>(std::ceil(roi.y / step)),
            j1 = static_cast<int>((roi.y + roi.height - 1) / step);
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      const cv::Point p(static_cast<int>(std::lround(i * step)), static_cast<int>(std::lround(j * step)));
      if (!roi.contains(p) || !birth_mask.at<std::uint8_t>(p)) continue;
      const float strength = eigen.at<float>(p - roi.tl());
      if (strength >= eigen_threshold && strength > 0.0f) candidates.push_back({strength, p});
    }
  if (static_cast<int>(candidates.size()) > settings.max_features) {
    std::nth_element(candidates.begin(), candidates.begin() + settings.max_features, candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.strength > b.strength; });
    candidates.resize(static_cast<std::size_t>(settings.max_features));
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return a.p.y != b.p.y ? a.p.y < b.p.y : a.p.x < b.p.x;
    });
  }
  tracks.reserve(tracks.size() + candidates.size());
  for (const Candidate& c : candidates) {
    const Vec2 p{static_cast<double>(c.p.x), static_cast<double>(c.p.y)};
    create_track(p, p, Mat2d::Identity(), {}, 0, TrackStatus::kTracked);
  }
}

void FeatureTracker::Impl::match_track(int index, Vec2 guess, const Warp* initial) {
  TrackState& st = states[static_cast<std::size_t>(index)];
  if (initial) st.warp = *initial;
  const cv::Point c = st.subset.centre();
  st.warp.set_displacement_at(st.offset.x, st.offset.y,
                              {guess.x - c.x - st.offset.x, guess.y - c.y - st.offset.y});
  st.guess = guess;
  st.fixed_shape = false;
  st.match = st.subset.match(match_f, match_mask, st.warp, settings.match);
  const Vec2 u = st.warp.displacement_px(st.offset.x, st.offset.y);
  st.candidate = {c.x + st.offset.x + u.x, c.y + st.offset.y + u.y};
  st.matched = st.match.converged && st.match.zncc >= settings.min_zncc;
  const double moved = std::hypot(st.candidate.x - guess.x, st.candidate.y - guess.y);
  st.suspect = !st.matched || moved > settings.max_correction_px;
  if (st.matched) {
    const Mat2d a = Mat2d::Identity() + to_matrix(st.warp.gradient(st.offset.x, st.offset.y));
    st.deformation = a * st.birth;
    st.main_frame = frame;
    st.main.reference_px = tracks[static_cast<std::size_t>(index)].reference_px;
    st.main.position_px = st.candidate;
    st.main.covariance_px2 = predicted_match_covariance(
        st.match.zncc, st.subset.pixel_count(), st.subset.translation_information(),
        correlated_pixels(settings.prefilter_sigma_px, st.subset.stride()));
  }
}

void FeatureTracker::Impl::predict_and_match() {
  alive.clear();
  for (std::size_t i = 0; i < tracks.size(); ++i)
    if (is_alive(tracks[i].status)) alive.push_back(static_cast<int>(i));
  stats.global_jump = false;
  stats.global_shift_px = {};

  // Prediction: each track's own last motion, unless the whole contact jumped.
  Vec2 shift{0.0, 0.0};
  if (settings.global_prediction && !alive.empty()) {
    high_pass(current_f, current_hp);
    if (global_correlation.has_reference() && global_correlation.reference_size() == current_hp.size()) {
      double response = 0.0;
      const cv::Point2d s =
          global_correlation.correlate(current_hp, &response) * static_cast<double>(high_pass_factor());
      stats.global_shift_px = {s.x, s.y};
      scratch_x.clear();
      scratch_y.clear();
      for (int i : alive) {
        scratch_x.push_back(states[static_cast<std::size_t>(i)].velocity.x);
        scratch_y.push_back(states[static_cast<std::size_t>(i)].velocity.y);
      }
      const double vx = median_in_place(scratch_x), vy = median_in_place(scratch_y);
      if (response > 0.05 && std::hypot(s.x - vx, s.y - vy) > ridge_reach_px()) {
        stats.global_jump = true;
        shift = {s.x, s.y};
      }
    }
  }
  to_match.clear();
  skipped.clear();
  skip_match.assign(states.size(), 0);
  for (int i : alive) {
    if (!stats.global_jump && skips_main_match(i)) {
      skip_match[static_cast<std::size_t>(i)] = 1;
      skipped.push_back(i);
    } else {
      to_match.push_back(i);
    }
  }
  const int n = static_cast<int>(to_match.size());
  lk_from.resize(static_cast<std::size_t>(n));
  lk_to.resize(static_cast<std::size_t>(n));
  const cv::Point2f tl(static_cast<float>(roi.x), static_cast<float>(roi.y));
  for (int k = 0; k < n; ++k) {
    const TrackState& st = states[static_cast<std::size_t>(to_match[static_cast<std::size_t>(k)])];
    const Vec2 motion = stats.global_jump ? shift : st.velocity;
    lk_from[static_cast<std::size_t>(k)] =
        cv::Point2f(static_cast<float>(st.previous.x), static_cast<float>(st.previous.y)) - tl;
    lk_to[static_cast<std::size_t>(k)] = cv::Point2f(static_cast<float>(st.previous.x + motion.x),
                                                     static_cast<float>(st.previous.y + motion.y)) -
                                         tl;
  }
  const cv::Size window(settings.window_px, settings.window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, settings.lk_max_iterations,
                              settings.lk_epsilon);
  if (n > 0) {
    cv::calcOpticalFlowPyrLK(previous_pyramid, current_pyramid, lk_from, lk_to, lk_status, lk_error, window,
                             settings.pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    lk_back = lk_from;
    if (!settings.refine) {
      cv::calcOpticalFlowPyrLK(current_pyramid, previous_pyramid, lk_to, lk_back, lk_back_status, lk_error,
                               window, settings.pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    } else {
      // With refinement the backward pass checks only the forward answers that the track's own motion (or
      // the global shift) does not corroborate: within forward_backward_px of that prediction, two
      // independent estimates agree, and the subset match and the neighbour check follow anyway. The full
      // backward pass was an eighth of the tracker's time on the 640×512 goal trial.
      lk_back_status.assign(static_cast<std::size_t>(n), 1);
      lk_check.clear();
      lk_back_from.clear();
      lk_back_to.clear();
      for (int k = 0; k < n; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if (!lk_status[kk]) continue;
        const TrackState& st = states[static_cast<std::size_t>(to_match[kk])];
        const Vec2 motion = stats.global_jump ? shift : st.velocity;
        const double dx = lk_to[kk].x + tl.x - (st.previous.x + motion.x);
        const double dy = lk_to[kk].y + tl.y - (st.previous.y + motion.y);
        if (std::hypot(dx, dy) <= settings.forward_backward_px) continue;
        lk_check.push_back(k);
        lk_back_from.push_back(lk_to[kk]);
        lk_back_to.push_back(lk_from[kk]);
      }
      if (!lk_check.empty()) {
        cv::calcOpticalFlowPyrLK(current_pyramid, previous_pyramid, lk_back_from, lk_back_to, lk_check_status,
                                 lk_error, window, settings.pyramid_levels, term,
                                 cv::OPTFLOW_USE_INITIAL_FLOW);
        for (std::size_t j = 0; j < lk_check.size(); ++j) {
          const auto kk = static_cast<std::size_t>(lk_check[j]);
          lk_back[kk] = lk_back_to[j];
          lk_back_status[kk] = lk_check_status[j];
        }
      }
    }
  }
  for (int k = 0; k < n; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    TrackState& st = states[static_cast<std::size_t>(to_match[kk])];
    const double fb = std::hypot(lk_back[kk].x - lk_from[kk].x, lk_back[kk].y - lk_from[kk].y);
    st.lk_ok = lk_status[kk] && lk_back_status[kk] && fb <= settings.forward_backward_px;
    const Vec2 motion = stats.global_jump ? shift : st.velocity;
    st.guess = st.lk_ok ? Vec2{lk_to[kk].x + tl.x, lk_to[kk].y + tl.y}
                        : Vec2{st.previous.x + motion.x, st.previous.y + motion.y};
    st.candidate = st.guess;
    st.matched = st.lk_ok;
    st.suspect = false;
    if (!settings.refine && !st.lk_ok) st.suspect = true;  // retired below with the reason
  }
  stats.main_matched = n;
  if (!settings.refine) return;
  cv::parallel_for_(cv::Range(0, n), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int index = to_match[static_cast<std::size_t>(k)];
      TrackState& st = states[static_cast<std::size_t>(index)];
      const Vec2 first = st.guess;
      match_track(index, first, nullptr);
      // A failed LK guess is not the only start: the track's own motion may still be right.
      if (st.suspect && st.lk_ok) {
        const Vec2 motion = stats.global_jump ? shift : st.velocity;
        const Vec2 second{st.previous.x + motion.x, st.previous.y + motion.y};
        if (std::hypot(second.x - first.x, second.y - first.y) > 0.5) {
          const Warp kept = st.warp;
          const MatchResult kept_match = st.match;
          const Vec2 kept_candidate = st.candidate;
          match_track(index, second, nullptr);
          if (st.suspect) {
            st.warp = kept;
            st.match = kept_match;
            st.candidate = kept_candidate;
            st.guess = first;
          }
        }
      }
    }
  });
  if (!skipped.empty()) start_skipped_from_neighbours();
}

// A frame-0 track skips the main match in the frames where its class on the seeding lattice is not due
// (main_match_period_frames), once it has been matched at least once; tracks anchored later always match.
bool FeatureTracker::Impl::skips_main_match(int index) const {
  const int period = settings.main_match_period_frames;
  if (!settings.refine || !settings.fixed_shape_pass || !settings.fixed_shape_resampled || period <= 1)
    return false;
  const TrackState& st = states[static_cast<std::size_t>(index)];
  const Track& t = tracks[static_cast<std::size_t>(index)];
  if (st.key != 0 || !st.exact_reference || t.born_frame + 1 >= frame) return false;
  // Border tracks (their last match had pixels outside the contact) always match: their neighbours lie on
  // one side, and started from them the rounds left more frame-to-frame jitter there (a noise-free 24-frame
  // trial smoothed in time: largest move 0.21 px, against 0.13 px matching every track and 0.15 px so).
  if (st.match.valid_fraction < 0.999) return false;
  const long ix = std::lround(t.reference_px.x / settings.grid_step_px);
  const long iy = std::lround(t.reference_px.y / settings.grid_step_px);
  const long lattice_class = period == 2 ? ((ix + iy) & 1) : ((ix & 1) + 2 * (iy & 1));
  return lattice_class != frame % period;
}

// Where a track that skipped the main match starts its rounds: the median of where its matched neighbours
// put it, each carrying its own position over by its deformation gradient (as the neighbour check does).
// Measured against the alternative of its own motion corrected by the neighbours' median correction (a
// piecewise-constant interpolation of the change of motion): default scene end to end 0.0461 -> 0.0443 px,
// U error 3.7 -> 3.3 % (period 2). Too few matched neighbours: it takes the main match after all.
void FeatureTracker::Impl::start_skipped_from_neighbours() {
  for (int i : skipped) states[static_cast<std::size_t>(i)].matched = false;
  build_hash(true);
  retry.clear();
  for (int i : skipped) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    // (No track skips on a frame with a global jump: its own motion is the prediction here.)
    const Vec2 own{st.previous.x + st.velocity.x, st.previous.y + st.velocity.y};
    gather_neighbours(own, settings.neighbour_radius_px, i);
    if (static_cast<int>(neighbours.size()) < settings.min_neighbours) {
      skip_match[static_cast<std::size_t>(i)] = 0;
      st.guess = own;
      retry.push_back(i);
      continue;
    }
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    scratch_x.clear();
    scratch_y.clear();
    for (int j : neighbours) {
      const TrackState& nb = states[static_cast<std::size_t>(j)];
      const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
      const Eigen::Vector2d d = nb.deformation * Eigen::Vector2d(X.x - Xj.x, X.y - Xj.y);
      scratch_x.push_back(nb.candidate.x + d.x());
      scratch_y.push_back(nb.candidate.y + d.y());
    }
    st.guess = {median_in_place(scratch_x), median_in_place(scratch_y)};
    st.candidate = st.guess;
    st.lk_ok = false;
    st.matched = true;
    st.suspect = false;
  }
  match_from_guesses(retry);
  stats.main_matched += static_cast<int>(retry.size());
}

// The main match of each listed track, from its `guess`.
void FeatureTracker::Impl::match_from_guesses(const std::vector<int>& indices) {
  cv::parallel_for_(cv::Range(0, static_cast<int>(indices.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = indices[static_cast<std::size_t>(k)];
      match_track(i, states[static_cast<std::size_t>(i)].guess, nullptr);
    }
  });
}

// After the resampled rounds: a track that skipped the main match and that the rounds did not carry is
// matched from where it started, then checked like any other (retired if that match fails).
void FeatureTracker::Impl::match_unconfirmed_skipped() {
  retry.clear();
  for (int i : skipped) {
    const std::size_t ii = static_cast<std::size_t>(i);
    if (!skip_match[ii] || (!resampled_done.empty() && resampled_done[ii])) continue;
    if (!is_alive(tracks[ii].status)) continue;
    skip_match[ii] = 0;
    retry.push_back(i);
  }
  stats.main_matched += static_cast<int>(retry.size());
  match_from_guesses(retry);
}

void FeatureTracker::Impl::build_hash(bool matched_only) {
  hash_cell = std::max(4.0, settings.neighbour_radius_px);
  hash_cols = static_cast<int>(size.width / hash_cell) + 1;
  hash_rows = static_cast<int>(size.height / hash_cell) + 1;
  const std::size_t cells = static_cast<std::size_t>(hash_cols) * static_cast<std::size_t>(hash_rows);
  hash_start.assign(cells + 1, 0);
  hash_items.clear();
  const auto cell_of = [&](Vec2 p) {
    const int cx = std::clamp(static_cast<int>(p.x / hash_cell), 0, hash_cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y / hash_cell), 0, hash_rows - 1);
    return static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash_cols) + static_cast<std::size_t>(cx);
  };
  const auto usable = [&](int i) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    return is_alive(tracks[static_cast<std::size_t>(i)].status) &&
           (!matched_only || (st.matched && !st.suspect));
  };
  for (int i : alive)
    if (usable(i)) ++hash_start[cell_of(states[static_cast<std::size_t>(i)].candidate) + 1];
  for (std::size_t c = 0; c < cells; ++c) hash_start[c + 1] += hash_start[c];
  hash_items.resize(static_cast<std::size_t>(hash_start[cells]));
  hash_fill.assign(hash_start.begin(), hash_start.end() - 1);
  for (int i : alive)
    if (usable(i))
      hash_items[static_cast<std::size_t>(
          hash_fill[cell_of(states[static_cast<std::size_t>(i)].candidate)]++)] = i;
}

void FeatureTracker::Impl::gather_neighbours(Vec2 p, double radius, int self) {
  neighbours.clear();
  const int cx0 = std::max(0, static_cast<int>((p.x - radius) / hash_cell));
  const int cx1 = std::min(hash_cols - 1, static_cast<int>((p.x + radius) / hash_cell));
  const int cy0 = std::max(0, static_cast<int>((p.y - radius) / hash_cell));
  const int cy1 = std::min(hash_rows - 1, static_cast<int>((p.y + radius) / hash_cell));
  const double r2 = radius * radius;
  for (int cy = cy0; cy <= cy1; ++cy)
    for (int cx = cx0; cx <= cx1; ++cx) {
      const std::size_t c =
          static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash_cols) + static_cast<std::size_t>(cx);
      for (int k = hash_start[c]; k < hash_start[c + 1]; ++k) {
        const int j = hash_items[static_cast<std::size_t>(k)];
        if (j == self) continue;
        const Vec2 q = states[static_cast<std::size_t>(j)].candidate;
        const double dx = q.x - p.x, dy = q.y - p.y;
        if (dx * dx + dy * dy <= r2) neighbours.push_back(j);
      }
    }
}

// Where the neighbours put track `index`: each carries its own position over to the track's reference
// position by the mean of its and (if trusted) the track's deformation gradient — the trapezoid rule,
// exact for a quadratic field. The median over neighbours ignores a minority of wrong ones.
bool FeatureTracker::Impl::predict_from_neighbours(int index, Vec2& predicted, Mat2d& deformation) {
  const TrackState& st = states[static_cast<std::size_t>(index)];
  const Vec2 X = tracks[static_cast<std::size_t>(index)].reference_px;
  gather_neighbours(st.candidate, settings.neighbour_radius_px, index);
  if (static_cast<int>(neighbours.size()) < settings.min_neighbours) return false;
  scratch_x.clear();
  scratch_y.clear();
  Mat2d sum = Mat2d::Zero();
  const bool own = st.matched && !st.suspect;
  for (int j : neighbours) {
    const TrackState& nb = states[static_cast<std::size_t>(j)];
    const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
    const Mat2d f = own ? Mat2d(0.5 * (nb.deformation + st.deformation)) : nb.deformation;
    const Eigen::Vector2d d = f * Eigen::Vector2d(X.x - Xj.x, X.y - Xj.y);
    scratch_x.push_back(nb.candidate.x + d.x());
    scratch_y.push_back(nb.candidate.y + d.y());
    sum += nb.deformation;
  }
  predicted = {median_in_place(scratch_x), median_in_place(scratch_y)};
  deformation = sum / static_cast<double>(neighbours.size());
  return true;
}

void FeatureTracker::Impl::check_neighbours() {
  build_hash(true);
  retry.clear();
  for (int i : alive) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    // Placed by its neighbours' corrections: nothing of its own to check yet.
    if (!skip_match.empty() && skip_match[static_cast<std::size_t>(i)]) continue;
    Vec2 predicted;
    Mat2d deformation;
    if (!predict_from_neighbours(i, predicted, deformation)) {
      if (st.suspect)
        retire(i, st.match.valid_fraction < settings.match.min_valid_fraction ? TrackStatus::kLeftContact
                                                                              : TrackStatus::kPoorMatch);
      else
        tracks[static_cast<std::size_t>(i)].status = TrackStatus::kUnchecked;
      continue;
    }
    const double deviation = std::hypot(st.candidate.x - predicted.x, st.candidate.y - predicted.y);
    if (!st.suspect && deviation <= settings.neighbour_tolerance_px) continue;
    if (st.match.valid_fraction < settings.match.min_valid_fraction) {
      retire(i, TrackStatus::kLeftContact);
      continue;
    }
    // Re-match from the neighbours' prediction, with their deformation as the subset's first-order terms.
    Warp w;
    const Mat2d a = deformation * st.birth.inverse() - Mat2d::Identity();
    w.p[2] = a(0, 0);
    w.p[3] = a(0, 1);
    w.p[4] = a(1, 0);
    w.p[5] = a(1, 1);
    if (settings.shape == ShapeFunction::kTranslation) w.p[2] = w.p[3] = w.p[4] = w.p[5] = 0.0;
    st.warp = w;
    st.guess = predicted;
    retry.push_back(i);
  }
  cv::parallel_for_(cv::Range(0, static_cast<int>(retry.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = retry[static_cast<std::size_t>(k)];
      TrackState& st = states[static_cast<std::size_t>(i)];
      const Warp w = st.warp;
      match_track(i, st.guess, &w);
    }
  });
  for (int i : retry) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    const double deviation = std::hypot(st.candidate.x - st.guess.x, st.candidate.y - st.guess.y);
    if (st.matched && deviation <= settings.neighbour_tolerance_px) {
      st.suspect = false;
      tracks[static_cast<std::size_t>(i)].status = TrackStatus::kRecovered;
      ++stats.recovered;
    } else {
      retire(i, st.matched ? TrackStatus::kInconsistent
                           : (st.match.valid_fraction < settings.match.min_valid_fraction
                                  ? TrackStatus::kLeftContact
                                  : TrackStatus::kPoorMatch));
    }
  }
}

// Every trusted track is matched again for its translation alone, its subset's shape set to the smoothed
// shape of its neighbourhood: the deformation gradient F averaged over the neighbours (Gaussian weights,
// σ = one grid step) and carried into the track's anchor frame, the curvature averaged over the neighbours
// anchored in the same frame. Both are smooth fields that the neighbourhood pins down far better than one
// subset; with them fixed, the subset's noise no longer leaks into the along-ridge translation.
void FeatureTracker::Impl::fixed_shape_pass(bool last) {
  build_hash(true);
  retry.clear();
  const double sigma = settings.fixed_shape_sigma_grid * settings.grid_step_px;
  const double radius = 2.0 * sigma;
  shapes.resize(states.size());
  smoothed.resize(states.size());
  Eigen::Matrix<double, 6, 6> normal;
  Eigen::Matrix<double, 6, 2> rhs;
  for (int i : alive) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
    if (!resampled_done.empty() && resampled_done[static_cast<std::size_t>(i)]) continue;
    // A track whose reference position is extrapolated keeps its own match: the rounds fit the field in
    // reference coordinates, where its extrapolation error would pull it (and, through the fits, its
    // newborn neighbours) a little further each frame, compounding from one generation of births to the next.
    if (tracks[static_cast<std::size_t>(i)].reference_extrapolated) continue;
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    gather_neighbours(st.candidate, radius, -1);  // includes the track itself
    if (neighbours.size() < 6) continue;
    // Weighted least-squares fit of the displacement u(X) = x − X of the neighbourhood, in reference
    // coordinates scaled by the radius: quadratic when the neighbours are many and on two sides of the track
    // or more, affine otherwise or where the quadratic fit is ill-posed. Two sides include a track on the
    // border, whose neighbours fill a half-plane: its subset then follows the field's curvature across the
    // slip annulus too (default scene 0.0479 → 0.0460 px end to end, outer 0.5 mm 0.106 → 0.099 px, U error
    // 3.0 → 2.8 %, stick radius 4.0 → 3.5 %; the hard scenes within 1 %).
    int quadrants = 0;
    for (int j : neighbours) {
      const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
      if (Xj.x != X.x || Xj.y != X.y) quadrants |= 1 << ((Xj.x >= X.x ? 1 : 0) + (Xj.y >= X.y ? 2 : 0));
    }
    const int bits =
        (quadrants & 1) + ((quadrants >> 1) & 1) + ((quadrants >> 2) & 1) + ((quadrants >> 3) & 1);
    int m = neighbours.size() >= 10 && bits >= 2 ? 6 : 3;
    normal.setZero();
    rhs.setZero();
    for (int j : neighbours) {
      const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
      const Vec2 xj = states[static_cast<std::size_t>(j)].candidate;
      const double dx = (Xj.x - X.x) / radius, dy = (Xj.y - X.y) / radius;
      const double w = std::exp(-0.5 * (dx * dx + dy * dy) * (radius * radius) / (sigma * sigma));
      const double basis[6] = {1.0, dx, dy, dx * dx, dx * dy, dy * dy};
      for (int r = 0; r < m; ++r) {
        for (int c = 0; c < m; ++c) normal(r, c) += w * basis[r] * basis[c];
        rhs(r, 0) += w * basis[r] * (xj.x - Xj.x);
        rhs(r, 1) += w * basis[r] * (xj.y - Xj.y);
      }
    }
    const auto well_posed = [](const Eigen::LDLT<Eigen::MatrixXd>& f) {
      return f.info() == Eigen::Success && f.isPositive() && f.rcond() >= 1e-8;
    };
    Eigen::LDLT<Eigen::MatrixXd> ldlt(normal.topLeftCorner(m, m));
    if (!well_posed(ldlt) && m == 6) {  // e.g. neighbours along one line: the affine block may still hold
      m = 3;
      ldlt.compute(normal.topLeftCorner(m, m));
    }
    if (!well_posed(ldlt)) continue;
    const Eigen::MatrixXd coef = ldlt.solve(Eigen::MatrixXd(rhs.topRows(m)));
    if (!coef.allFinite()) continue;
    // du/dX in frame 0's coordinates; the subset's shape is in its anchor's: F_anchor = F · birth⁻¹ … the
    // birth map is identity for frame-0 tracks, and for the others it carries the gradient over.
    const double s1 = 1.0 / radius, s2 = 1.0 / (radius * radius);
    Mat2d f;
    f << 1.0 + coef(1, 0) * s1, coef(2, 0) * s1, coef(1, 1) * s1, 1.0 + coef(2, 1) * s1;
    const Mat2d h = f * st.birth.inverse() - Mat2d::Identity();
    Warp w = st.warp;
    if (m == 6 && st.exact_reference) {
      w.p[6] = 2.0 * coef(3, 0) * s2;
      w.p[7] = coef(4, 0) * s2;
      w.p[8] = 2.0 * coef(5, 0) * s2;
      w.p[9] = 2.0 * coef(3, 1) * s2;
      w.p[10] = coef(4, 1) * s2;
      w.p[11] = 2.0 * coef(5, 1) * s2;
    } else if (m != 6) {
      for (std::size_t c = 6; c < 12; ++c) w.p[c] = 0.0;
    }
    const double ox = st.offset.x, oy = st.offset.y;
    // Gradient at the track point = h.
    w.p[2] = h(0, 0) - (w.p[6] * ox + w.p[7] * oy);
    w.p[3] = h(0, 1) - (w.p[7] * ox + w.p[8] * oy);
    w.p[4] = h(1, 0) - (w.p[9] * ox + w.p[10] * oy);
    w.p[5] = h(1, 1) - (w.p[10] * ox + w.p[11] * oy);
    const cv::Point c = st.subset.centre();
    w.set_displacement_at(ox, oy, {st.candidate.x - c.x - ox, st.candidate.y - c.y - oy});
    shapes[static_cast<std::size_t>(i)] = w;
    smoothed[static_cast<std::size_t>(i)] = f;
    retry.push_back(i);
  }
  MatchOptions options = settings.match;
  options.translation_only = true;
  if (!last) options.convergence_px = std::max(options.convergence_px, settings.fixed_shape_convergence_px);
  cv::parallel_for_(cv::Range(0, static_cast<int>(retry.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = retry[static_cast<std::size_t>(k)];
      TrackState& st = states[static_cast<std::size_t>(i)];
      Warp w = shapes[static_cast<std::size_t>(i)];
      if (!st.wide.empty() && !st.wide.has_pixels()) {
        Subset subset, wide;
        if (build_subsets(keys[static_cast<std::size_t>(st.key)]->anchor, st.subset.centre(), subset, wide))
          st.wide = std::move(wide);
      }
      const Subset& subset = st.wide.empty() ? st.subset : st.wide;
      const MatchResult m = subset.match(match_f, match_mask, w, options);
      if (!m.converged || m.zncc < settings.min_zncc) continue;
      const cv::Point c = st.subset.centre();
      const Vec2 u = w.displacement_px(st.offset.x, st.offset.y);
      const Vec2 p{c.x + st.offset.x + u.x, c.y + st.offset.y + u.y};
      if (std::hypot(p.x - st.candidate.x, p.y - st.candidate.y) > settings.neighbour_tolerance_px) continue;
      st.candidate = p;
      st.match = m;
      st.fixed_shape = true;
      // The fitted F is far less noisy than one subset's: it is what the fusion and the neighbour check
      // carry positions over with, and what the track reports.
      if (settings.smoothed_gradient) st.deformation = smoothed[static_cast<std::size_t>(i)];
      st.fixed_information = subset.fixed_shape_information();
    }
  });
}

// The fixed-shape rounds (above) for the tracks anchored in frame 0 itself, on the current frame resampled
// once per round through the neighbours' fitted field (flow/shape_field.hpp) rather than subset by subset.
// Each round fits the field to the tracks' positions, resamples the frame into frame 0's coordinates, and
// moves every track by one translation-only Gauss-Newton step of its wide subset: x = (X − Δ) + u(X − Δ).
// The shape is the blend of the nodes' neighbourhood fits instead of the track's own, and fit and match
// iterate together.
void FeatureTracker::Impl::resampled_shape_pass() {
  resampled_done.assign(states.size(), 0);
  if (keys.empty() || !keys[0] || keys[0]->frame != 0) return;
  eligible.clear();
  others.clear();
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int i : alive) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
    // Tracks anchored later take part in the fit (their reference positions are frame 0's too) but are
    // matched subset by subset.
    if (st.key != 0 || !st.exact_reference) {
      others.push_back(i);
      continue;
    }
    eligible.push_back(i);
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    x0 = std::min(x0, X.x), y0 = std::min(y0, X.y), x1 = std::max(x1, X.x), y1 = std::max(y1, X.y);
  }
  if (eligible.size() < 6) return;
  // The field's nodes on the seeding lattice (multiples of fixed_shape_node_grid grid steps): there a
  // node's fit is that seeded track's own neighbourhood fit, as in the subset-by-subset rounds.
  const int reach = std::max(settings.subset_radius_px, settings.fixed_shape_radius_px) + 2;
  const double step = settings.fixed_shape_node_grid * settings.grid_step_px;
  const int left = static_cast<int>(std::lround(std::max(0.0, std::floor((x0 - reach) / step)) * step));
  const int top = static_cast<int>(std::lround(std::max(0.0, std::floor((y0 - reach) / step)) * step));
  const cv::Rect region =
      cv::Rect(cv::Point(left, top), cv::Point(static_cast<int>(std::ceil(x1)) + reach + 1,
                                               static_cast<int>(std::ceil(y1)) + reach + 1)) &
      cv::Rect(0, 0, size.width, size.height);
  const double sigma = settings.fixed_shape_sigma_grid * settings.grid_step_px;
  const std::size_t n = eligible.size();
  resampled_position.resize(states.size());
  resampled_match.assign(n, MatchResult{});
  resampled_moved.assign(n, 0.0);
  for (int i : eligible)
    resampled_position[static_cast<std::size_t>(i)] = states[static_cast<std::size_t>(i)].candidate;
  // The subsets read every stride-th pixel: only their lattices are resampled (one in four pixels at
  // stride 2: the wide subsets sample the image's lattice).
  PixelClasses lattices(settings.fixed_shape_stride);
  for (int i : eligible) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    const Subset& subset = st.wide.empty() ? st.subset : st.wide;
    if (subset.stride() != settings.fixed_shape_stride) {
      lattices = PixelClasses();
      break;
    }
    lattices.add(subset.centre().x + subset.first_offset().x, subset.centre().y + subset.first_offset().y);
  }
  for (int round = 0; round < settings.fixed_shape_resampled_rounds; ++round) {
    field_anchor.clear();
    field_displacement.clear();
    for (int i : eligible) {
      const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
      const Vec2 x = resampled_position[static_cast<std::size_t>(i)];
      field_anchor.push_back(X);
      field_displacement.push_back({x.x - X.x, x.y - X.y});
    }
    for (int i : others) {
      const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
      const Vec2 x = states[static_cast<std::size_t>(i)].candidate;
      field_anchor.push_back(X);
      field_displacement.push_back({x.x - X.x, x.y - X.y});
    }
    shape_field.fit(field_anchor, field_displacement, region, step, sigma);
    resample_through(match_f, match_mask, shape_field, keys[0]->anchor.mask(), region, resampled,
                     resampled_valid, lattices);
    window_sums.build(keys[0]->anchor, resampled, resampled_valid, region, settings.fixed_shape_stride,
                      lattices);
    cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) {
        const int i = eligible[static_cast<std::size_t>(k)];
        const TrackState& st = states[static_cast<std::size_t>(i)];
        const Subset& subset = st.wide.empty() ? st.subset : st.wide;
        Vec2 step;
        MatchResult& m = resampled_match[static_cast<std::size_t>(k)];
        m = subset.translation_step(window_sums, keys[0]->anchor, resampled, resampled_valid,
                                    settings.match.min_valid_fraction, step);
        resampled_moved[static_cast<std::size_t>(k)] = 0.0;
        if (!m.converged) continue;
        const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
        const Vec2 q{X.x - step.x, X.y - step.y};
        Vec2 u;
        if (!shape_field.displacement(q.x, q.y, u)) {
          m.converged = false;
          continue;
        }
        Vec2& x = resampled_position[static_cast<std::size_t>(i)];
        const Vec2 p{q.x + u.x, q.y + u.y};
        resampled_moved[static_cast<std::size_t>(k)] = std::hypot(p.x - x.x, p.y - x.y);
        x = p;
      }
    });
    // The rounds are not iterated to their fixed point: where the fit passes a pattern that the subsets
    // average out (scales between the fit's σ and the subset's width) it amplifies the noise there, and a
    // few rounds (like the subset-by-subset passes' three) regularise it. Stop early only once nothing moves.
    if (*std::max_element(resampled_moved.begin(), resampled_moved.end()) < 1e-3) break;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const int i = eligible[k];
    TrackState& st = states[static_cast<std::size_t>(i)];
    const MatchResult& m = resampled_match[k];
    if (!m.converged || m.zncc < settings.min_zncc) continue;
    // Taken even where it is further than the neighbour tolerance from the main match: the rounds' answer
    // is pinned by the neighbours' field, the main match by one subset, and where they disagree (0.6-1.5
    // px; ~0.5 % of track-frames on the hard scenes) the main match was the wrong one. Keeping it left a
    // border track 2.37 px off on paper_2N_5mm_s end to end for a frame before the neighbour check caught
    // it; taking the rounds' answer: max 2.37 -> 0.81 px there, hard_sweat_blobs 2.05 -> 0.81 px,
    // displacement RMS 1-3 % lower on every scene measured (session 11, BENCHMARKS.md).
    const Vec2 p = resampled_position[static_cast<std::size_t>(i)];
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    Vec2 u;
    Mat2d gradient;
    if (!shape_field.displacement(X.x, X.y, u, &gradient)) continue;
    st.candidate = p;
    st.match = m;
    st.fixed_shape = true;
    if (settings.smoothed_gradient) st.deformation = Mat2d::Identity() + gradient;
    st.fixed_information = (st.wide.empty() ? st.subset : st.wide).fixed_shape_information();
    resampled_done[static_cast<std::size_t>(i)] = 1;
  }
}

// Unrefined tracks only: LK from each anchor frame straight to the current frame, started at the chained
// estimate. Where both agree, the anchored result replaces the chained one, so the random walk of
// frame-to-frame chaining is reset every few frames instead of growing over the whole trial.
void FeatureTracker::Impl::reanchor() {
  const cv::Size window(settings.window_px, settings.window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, settings.lk_max_iterations,
                              settings.lk_epsilon);
  const cv::Point2f tl(static_cast<float>(roi.x), static_cast<float>(roi.y));
  for (std::size_t k = 0; k < keys.size(); ++k) {
    if (!keys[k] || keys[k]->users == 0 || keys[k]->frame == frame) continue;
    retry.clear();
    lk_from.clear();
    lk_to.clear();
    for (int i : alive) {
      const TrackState& st = states[static_cast<std::size_t>(i)];
      if (st.key != static_cast<int>(k) || !is_alive(tracks[static_cast<std::size_t>(i)].status) ||
          st.suspect)
        continue;
      retry.push_back(i);
      lk_from.push_back(
          cv::Point2f(static_cast<float>(st.anchor_point.x), static_cast<float>(st.anchor_point.y)) - tl);
      lk_to.push_back(cv::Point2f(static_cast<float>(st.candidate.x), static_cast<float>(st.candidate.y)) -
                      tl);
    }
    if (retry.empty()) continue;
    build_pyramid(keys[k]->image_u8, anchor_pyramid);
    cv::calcOpticalFlowPyrLK(anchor_pyramid, current_pyramid, lk_from, lk_to, lk_status, lk_error, window,
                             settings.pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    for (std::size_t n = 0; n < retry.size(); ++n) {
      TrackState& st = states[static_cast<std::size_t>(retry[n])];
      const Vec2 anchored{lk_to[n].x + tl.x, lk_to[n].y + tl.y};
      if (lk_status[n] && std::hypot(anchored.x - st.candidate.x, anchored.y - st.candidate.y) <=
                              settings.reanchor_tolerance_px)
        st.candidate = anchored;
    }
  }
}

// A subset of about one ridge period pins the motion across its ridges but hardly along them, and where
// the ridges run straight for a while, all its neighbours share that blind direction. So the positions are
// the solution of a small regularised least-squares problem: each track's match weighted by its subset's
// translation information, plus a weak smoothness term tying it to what its neighbours imply (their
// positions carried over by the mean deformation gradient). The smoothness weight is a small fraction of
// each track's own information, so it decides only the directions the texture leaves open; Jacobi sweeps,
// warm-started from the matches, spread that information along the ridges.
void FeatureTracker::Impl::fuse() {
  const double sigma = settings.fusion_sigma_px;
  const double radius = 2.0 * sigma;
  build_hash(true);
  const std::size_t n = alive.size();
  fused.resize(n);
  fusion_terms.resize(n);
  fusion_neighbours.resize(n);
  // Everything but the neighbours' positions is the same in every sweep (the weights depend on the
  // reference positions, the neighbours' offsets on the deformation gradients, the system on the track's
  // own information), so it is set up once and a sweep is a weighted sum per track.
  cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = alive[static_cast<std::size_t>(k)];
      const TrackState& st = states[static_cast<std::size_t>(i)];
      FusionTerm& term = fusion_terms[static_cast<std::size_t>(k)];
      std::vector<std::pair<int, double>>& list = fusion_neighbours[static_cast<std::size_t>(k)];
      term.active = false;
      list.clear();
      if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
      const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
      const Vec2 p = st.candidate;
      const Eigen::Matrix2d own = st.fixed_shape ? st.fixed_information : st.subset.translation_information();
      const double alpha = settings.fusion_weight * 0.5 * own.trace();
      double wsum = 0.0;
      Eigen::Vector2d offset_sum = Eigen::Vector2d::Zero();
      const int cx0 = std::max(0, static_cast<int>((p.x - radius) / hash_cell));
      const int cx1 = std::min(hash_cols - 1, static_cast<int>((p.x + radius) / hash_cell));
      const int cy0 = std::max(0, static_cast<int>((p.y - radius) / hash_cell));
      const int cy1 = std::min(hash_rows - 1, static_cast<int>((p.y + radius) / hash_cell));
      for (int cy = cy0; cy <= cy1; ++cy)
        for (int cx = cx0; cx <= cx1; ++cx) {
          const std::size_t c = static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash_cols) +
                                static_cast<std::size_t>(cx);
          for (int h = hash_start[c]; h < hash_start[c + 1]; ++h) {
            const int j = hash_items[static_cast<std::size_t>(h)];
            if (j == i) continue;
            const TrackState& nb = states[static_cast<std::size_t>(j)];
            const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
            const double dx = X.x - Xj.x, dy = X.y - Xj.y, d2 = dx * dx + dy * dy;
            if (d2 > radius * radius) continue;
            const double w = std::exp(-0.5 * d2 / (sigma * sigma));
            offset_sum += w * 0.5 * (nb.deformation + st.deformation) * Eigen::Vector2d(dx, dy);
            wsum += w;
            list.emplace_back(j, w);
          }
        }
      if (wsum <= 0.0) continue;
      term.active = true;
      term.solve = (own + alpha * Eigen::Matrix2d::Identity()).inverse();
      term.scale = alpha / wsum;
      term.constant = own * Eigen::Vector2d(st.candidate.x, st.candidate.y) + term.scale * offset_sum;
    }
  });
  for (int sweep = 0; sweep < settings.fusion_sweeps; ++sweep) {
    cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) {
        const FusionTerm& term = fusion_terms[static_cast<std::size_t>(k)];
        const Vec2 current = states[static_cast<std::size_t>(alive[static_cast<std::size_t>(k)])].candidate;
        fused[static_cast<std::size_t>(k)] = current;
        if (!term.active) continue;
        Eigen::Vector2d q_sum = Eigen::Vector2d::Zero();
        for (const auto& [j, w] : fusion_neighbours[static_cast<std::size_t>(k)]) {
          const Vec2 c = states[static_cast<std::size_t>(j)].candidate;
          q_sum += w * Eigen::Vector2d(c.x, c.y);
        }
        const Eigen::Vector2d x = term.solve * (term.constant + term.scale * q_sum);
        if (x.allFinite()) fused[static_cast<std::size_t>(k)] = {x.x(), x.y()};
      }
    });
    for (std::size_t k = 0; k < n; ++k) states[static_cast<std::size_t>(alive[k])].candidate = fused[k];
  }
}

void FeatureTracker::Impl::retire(int index, TrackStatus why) {
  Track& t = tracks[static_cast<std::size_t>(index)];
  if (!is_alive(t.status)) return;
  t.status = why;
  t.retired_frame = frame;
  TrackState& st = states[static_cast<std::size_t>(index)];
  release_key(st.key);
  st.key = -1;
  st.subset = Subset();
  st.wide = Subset();
  ++stats.retired;
}

// A newborn whose skin was in the contact in frame 0 (its mapped reference position inside frame 0's
// matching mask) is anchored to frame 0 itself: its subset is cut from frame 0 at the nearest pixel X0 of the
// mapped position, and matched into the current frame from the neighbours' prediction. Its reference
// position is then exact, not an extrapolation of the neighbours' map, and it is an ordinary frame-0 track.
FeatureTracker::Impl::FirstFrameBirth FeatureTracker::Impl::birth_from_first_frame(Vec2 x, Vec2 reference,
                                                                                   const Mat2d& dX_dx,
                                                                                   Vec2 velocity) {
  if (keys.empty() || !keys[0] || keys[0]->frame != 0) return FirstFrameBirth::kNotSeen;
  const cv::Point X0(static_cast<int>(std::lround(reference.x)), static_cast<int>(std::lround(reference.y)));
  if (!inside_mask(keys[0]->anchor.mask(), {static_cast<double>(X0.x), static_cast<double>(X0.y)}))
    return FirstFrameBirth::kNotSeen;
  const Vec2 X{static_cast<double>(X0.x), static_cast<double>(X0.y)};
  if (!create_track(X, X, Mat2d::Identity(), velocity, 0, TrackStatus::kBorn))
    return FirstFrameBirth::kFailed;
  const int index = static_cast<int>(states.size()) - 1;
  TrackState& st = states.back();
  const Mat2d f = dX_dx.inverse();
  const Eigen::Vector2d shift = f * Eigen::Vector2d(X.x - reference.x, X.y - reference.y);
  const Vec2 guess{x.x + shift.x(), x.y + shift.y()};
  Warp w;
  w.p[2] = f(0, 0) - 1.0;
  w.p[3] = f(0, 1);
  w.p[4] = f(1, 0);
  w.p[5] = f(1, 1) - 1.0;
  if (settings.shape == ShapeFunction::kTranslation) w.p[2] = w.p[3] = w.p[4] = w.p[5] = 0.0;
  match_track(index, guess, &w);
  if (!st.matched ||
      std::hypot(st.candidate.x - guess.x, st.candidate.y - guess.y) > settings.neighbour_tolerance_px) {
    --keys[0]->users;
    tracks.pop_back();
    states.pop_back();
    return FirstFrameBirth::kFailed;
  }
  st.previous = st.candidate;
  st.suspect = false;
  tracks.back().position_px = st.candidate;
  tracks.back().zncc = st.match.zncc;
  const Mat2d h = st.deformation - Mat2d::Identity();
  tracks.back().gradient = {h(0, 0), h(0, 1), h(1, 0), h(1, 1)};
  return FirstFrameBirth::kBorn;
}

void FeatureTracker::Impl::births() {
  // Lattice points of the seeding grid that no live track is near any more.
  const double step = settings.grid_step_px;
  const int cols = static_cast<int>((size.width - 1) / step) + 1,
            rows = static_cast<int>((size.height - 1) / step) + 1;
  lattice_taken.assign(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), 0);
  int live = 0;
  for (int i : alive) {
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status)) continue;
    ++live;
    const Vec2 p = states[static_cast<std::size_t>(i)].candidate;
    const int ci = static_cast<int>(std::floor(p.x / step)), cj = static_cast<int>(std::floor(p.y / step));
    for (int dj = 0; dj <= 1; ++dj)
      for (int di = 0; di <= 1; ++di) {
        const int li = ci + di, lj = cj + dj;
        if (li < 0 || lj < 0 || li >= cols || lj >= rows) continue;
        if (std::hypot(li * step - p.x, lj * step - p.y) < 0.6 * step)
          lattice_taken[static_cast<std::size_t>(lj) * static_cast<std::size_t>(cols) +
                        static_cast<std::size_t>(li)] = 1;
      }
  }
  if (live >= settings.max_features) return;
  const int margin = static_cast<int>(std::ceil(settings.border_margin_px));
  cv::erode(mask, birth_mask,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
  min_eigenvalue_map(current_f(roi), settings.eigen_block_px, eigen, eigen_scratch);
  build_hash(false);
  int key = -1;
  const double radius = std::max(settings.neighbour_radius_px, 2.5 * step);
  for (int lj = 0; lj < rows && live < settings.max_features; ++lj)
    for (int li = 0; li < cols && live < settings.max_features; ++li) {
      if (lattice_taken[static_cast<std::size_t>(lj) * static_cast<std::size_t>(cols) +
                        static_cast<std::size_t>(li)])
        continue;
      const cv::Point p(static_cast<int>(std::lround(li * step)), static_cast<int>(std::lround(lj * step)));
      if (!roi.contains(p) || !birth_mask.at<std::uint8_t>(p)) continue;
      if (eigen.at<float>(p - roi.tl()) < eigen_threshold) continue;
      const Vec2 x{static_cast<double>(p.x), static_cast<double>(p.y)};
      gather_neighbours(x, radius, -1);
      const double fit_radius = radius;
      if (neighbours.size() < 4) continue;
      // Local fit of the map current → reference position around the newborn, weighted towards the
      // nearest neighbours; quadratic when the neighbours surround it, affine when they lie to one side
      // (extrapolating a quadratic is unstable).
      int quadrants = 0;
      for (int j : neighbours) {
        const Vec2 q = states[static_cast<std::size_t>(j)].candidate;
        quadrants |= 1 << ((q.x >= x.x ? 1 : 0) + (q.y >= x.y ? 2 : 0));
      }
      const bool quadratic = neighbours.size() >= 10 && quadrants == 15;
      const int m = quadratic ? 6 : 3;
      Eigen::MatrixXd a(static_cast<Eigen::Index>(neighbours.size()), m);
      Eigen::MatrixXd b(static_cast<Eigen::Index>(neighbours.size()), 2);
      Eigen::VectorXd w(static_cast<Eigen::Index>(neighbours.size()));
      Vec2 velocity{0.0, 0.0};
      double wsum = 0.0;
      for (std::size_t k = 0; k < neighbours.size(); ++k) {
        const int j = neighbours[k];
        const Vec2 q = states[static_cast<std::size_t>(j)].candidate;
        const double dx = (q.x - x.x) / fit_radius, dy = (q.y - x.y) / fit_radius;
        const auto r = static_cast<Eigen::Index>(k);
        a(r, 0) = 1.0;
        a(r, 1) = dx;
        a(r, 2) = dy;
        if (quadratic) {
          a(r, 3) = dx * dx;
          a(r, 4) = dx * dy;
          a(r, 5) = dy * dy;
        }
        b(r, 0) = tracks[static_cast<std::size_t>(j)].reference_px.x;
        b(r, 1) = tracks[static_cast<std::size_t>(j)].reference_px.y;
        w[r] = std::exp(-2.0 * (dx * dx + dy * dy));
        velocity.x += w[r] * states[static_cast<std::size_t>(j)].velocity.x;
        velocity.y += w[r] * states[static_cast<std::size_t>(j)].velocity.y;
        wsum += w[r];
      }
      const Eigen::MatrixXd aw = w.asDiagonal() * a;
      const Eigen::MatrixXd normal = a.transpose() * aw;
      Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.rcond() < 1e-8) continue;
      const Eigen::MatrixXd coef = ldlt.solve(aw.transpose() * b);
      Mat2d dX_dx;
      dX_dx << coef(1, 0) / fit_radius, coef(2, 0) / fit_radius, coef(1, 1) / fit_radius,
          coef(2, 1) / fit_radius;
      if (!(dX_dx.determinant() > 0.05) || !coef.allFinite()) continue;
      // A plausible map stays within the neighbours' range of displacements (plus 2 px): an ill-posed fit
      // to a few one-sided neighbours can put X anywhere.
      {
        double lo_x = 1e300, hi_x = -1e300, lo_y = 1e300, hi_y = -1e300;
        for (int j : neighbours) {
          const Vec2 q = states[static_cast<std::size_t>(j)].candidate;
          const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
          lo_x = std::min(lo_x, q.x - Xj.x);
          hi_x = std::max(hi_x, q.x - Xj.x);
          lo_y = std::min(lo_y, q.y - Xj.y);
          hi_y = std::max(hi_y, q.y - Xj.y);
        }
        const double ux = x.x - coef(0, 0), uy = x.y - coef(0, 1);
        if (ux < lo_x - 2.0 || ux > hi_x + 2.0 || uy < lo_y - 2.0 || uy > hi_y + 2.0) continue;
      }
      velocity = {velocity.x / wsum, velocity.y / wsum};
      if (settings.refine) {
        const FirstFrameBirth b = birth_from_first_frame(x, {coef(0, 0), coef(0, 1)}, dX_dx, velocity);
        if (b == FirstFrameBirth::kBorn) {
          ++live;
          ++stats.born;
        }
        // Skin that frame 0 saw but that does not match there is not born by extrapolation either.
        if (b != FirstFrameBirth::kNotSeen) continue;
        // Nor, by default, skin that slid into a contact that did not grow: its reference position would be
        // an extrapolation of the field past the contact border (0.5 px RMS on the default scene, against
        // 0.24 px for newborns matched in frame 0). Only where the contact grew is extrapolation the way.
        // The test is against where frame 0 seeded, not its whole contact: a contact that grows carries its
        // births across frame 0's border band (seeded by neither frame 0 nor, unless extrapolated, by
        // births), and a contact that does not grow has no birth candidates in that band anyway.
        if (!settings.extrapolate_all_births && keys[0] && keys[0]->frame == 0 &&
            inside_mask(first_seeded, x))
          continue;
      }
      if (key < 0) key = add_key_frame();
      if (create_track(x, {coef(0, 0), coef(0, 1)}, dX_dx, velocity, key, TrackStatus::kBorn)) {
        tracks.back().reference_extrapolated = true;
        states.back().candidate = x;
        states.back().matched = true;
        ++live;
        ++stats.born;
      }
    }
  if (key >= 0 && keys[static_cast<std::size_t>(key)]->users == 0)
    keys[static_cast<std::size_t>(key)].reset();
}

void FeatureTracker::Impl::finish_frame() {
  for (int i : alive) {
    Track& t = tracks[static_cast<std::size_t>(i)];
    if (!is_alive(t.status)) continue;
    TrackState& st = states[static_cast<std::size_t>(i)];
    st.velocity = {st.candidate.x - st.previous.x, st.candidate.y - st.previous.y};
    st.previous = st.candidate;
    t.position_px = st.candidate;
    t.model = st.model;
    t.model_mahalanobis2 = st.model_mahalanobis2;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const Eigen::Matrix2d& c = st.own.covariance_px2;
    t.covariance_px2 = st.own_valid ? std::array<double, 3>{c(0, 0), c(0, 1), c(1, 1)}
                                    : std::array<double, 3>{nan, nan, nan};
    if (settings.refine) {
      t.zncc = st.match.zncc;
      t.subset_inside_fraction = st.match.valid_fraction;
      const Mat2d h = st.deformation - Mat2d::Identity();
      t.gradient = {h(0, 0), h(0, 1), h(1, 0), h(1, 1)};
    }
  }
}

FeatureTracker::FeatureTracker(TrackerSettings settings, std::optional<RoiPx> plate_roi)
    : impl_(std::make_unique<Impl>()) {
  validate(settings);
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
  m.adapt_to_texture(!points_px.empty()
                         ? static_cast<double>(points_px.size())
                         : cv::countNonZero(m.mask) / (m.settings.grid_step_px * m.settings.grid_step_px));
  m.update_roi(false);
  m.prepare_matching();
  m.build_pyramid(m.current_u8, m.previous_pyramid);
  if (m.settings.global_prediction) {
    m.high_pass(m.current_f, m.previous_hp);
    m.global_correlation.set_reference(m.previous_hp);
  }
  m.add_key_frame();
  // The measured outline moves by a pixel or two from frame to frame: only skin this far beyond where frame
  // 0 seeded counts as a contact that grew.
  constexpr int kGrowthTolerancePx = 4;
  const int margin =
      std::max(0, static_cast<int>(std::ceil(m.settings.border_margin_px)) - kGrowthTolerancePx);
  cv::erode(m.mask, m.first_seeded,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
  m.rest_count = 0;
  // Noise-free frames gain nothing from a mean anchor, and would only risk the blur of a slow creep.
  const bool noisy = !m.settings.adapt_to_texture || m.texture.snr < m.settings.min_unfiltered_snr;
  m.resting = m.settings.refine && m.settings.rest_average_frames > 1 && noisy;
  if (m.resting) {
    m.rest_sum = m.match_f.clone();
    m.rest_mask = m.match_mask.clone();
    m.rest_count = 1;
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
    PlateSettings ps;
    ps.subset_radius_px = m.settings.plate_subset_radius_px;
    ps.grid_step_px = m.settings.plate_grid_step_px;
    ps.prefilter_sigma_px = m.settings.plate_prefilter_sigma_px;
    m.plate.emplace();
    m.plate->start(m.current_f, m.current_u8, *m.plate_roi, ps, t_s);
  }
  if (m.keys[0]->users == 0 && !m.settings.births) m.keys[0].reset();
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
  ++m.frame;
  m.stats = FrameStats{};
  m.stats.frame = m.frame;
  m.prepare(image, contact_mask);
  m.update_roi(true);
  m.prepare_matching();
  m.build_pyramid(m.current_u8, m.current_pyramid);
  for (Track& t : m.tracks)
    if (t.status == TrackStatus::kBorn || t.status == TrackStatus::kRecovered ||
        t.status == TrackStatus::kUnchecked)
      t.status = TrackStatus::kTracked;
  m.predict_and_match();
  if (m.settings.refine && m.settings.neighbour_check) m.check_neighbours();
  m.resampled_done.clear();
  if (m.settings.refine && m.settings.fixed_shape_pass && m.settings.fixed_shape_resampled)
    m.resampled_shape_pass();
  if (!m.skipped.empty()) m.match_unconfirmed_skipped();
  if (m.settings.refine && m.settings.fixed_shape_pass)
    for (int k = 0; k < m.settings.fixed_shape_iterations; ++k)
      m.fixed_shape_pass(k + 1 == m.settings.fixed_shape_iterations);
  if (m.settings.refine) m.record_own_matches();
  if (m.settings.refine && m.settings.fusion_sigma_px > 0.0) {
    m.fuse();
    m.decline_fusion_beyond_noise();
  }
  if (!m.settings.refine && m.settings.reanchor_interval_frames > 0 &&
      m.frame % m.settings.reanchor_interval_frames == 0)
    m.reanchor();
  for (int i : m.alive) {
    if (!is_alive(m.tracks[static_cast<std::size_t>(i)].status)) continue;
    TrackState& st = m.states[static_cast<std::size_t>(i)];
    if (st.suspect) {
      if (!m.settings.refine)
        m.retire(i, TrackStatus::kForwardBackward);
      else
        m.retire(i, st.match.valid_fraction < m.settings.match.min_valid_fraction ? TrackStatus::kLeftContact
                                                                                  : TrackStatus::kPoorMatch);
      continue;
    }
    const Vec2 p = st.candidate;
    if (p.x < 0 || p.y < 0 || p.x > m.size.width - 1 || p.y > m.size.height - 1) {
      m.retire(i, TrackStatus::kLeftImage);
      continue;
    }
    if (!m.points_mode && !inside_mask(m.mask, p)) m.retire(i, TrackStatus::kLeftContact);
  }
  m.finish_frame();
  m.follow_rest();
  if (!m.points_mode && m.settings.births && m.frame % m.settings.birth_interval_frames == 0) m.births();
  if (m.plate) m.plate->track(m.current_f, m.current_u8, t_s);
  // Key frames nobody anchors to any more.
  for (auto& k : m.keys)
    if (k && k->users == 0) k.reset();
  std::swap(m.previous_pyramid, m.current_pyramid);
  std::swap(m.previous_u8, m.current_u8);
  std::swap(m.previous_hp, m.current_hp);
  // The high-passed frame correlated this frame is the next reference (its spectrum kept); otherwise the
  // reference follows whatever previous_hp now holds.
  if (!m.global_correlation.adopt_last_as_reference() && !m.previous_hp.empty())
    m.global_correlation.set_reference(m.previous_hp);
  m.stats.alive = static_cast<int>(
      std::count_if(m.tracks.begin(), m.tracks.end(), [](const Track& t) { return is_alive(t.status); }));
  return m.stats;
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
const TrackerSettings& FeatureTracker::settings() const {
  return impl_->settings;
}
const TextureQuality& FeatureTracker::texture() const {
  return impl_->texture;
}
bool FeatureTracker::low_snr_texture() const {
  return impl_->low_snr;
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
