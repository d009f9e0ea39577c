#pragma once
// The feature tracker's state, shared by the files that implement its stages (flow/tracker*.cpp): frame
// preparation and the public calls (tracker.cpp), prediction and the main match (tracker_match.cpp), the
// neighbour check (tracker_neighbours.cpp), the shape rounds (tracker_rounds.cpp), fusion
// (tracker_fusion.cpp), rest handling (tracker_rest.cpp), births and retirement (tracker_births.cpp).
// Not a public header: only those files include it.
#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "flow/local_fit.hpp"
#include "flow/mask_erosion.hpp"
#include "flow/phase_correlation.hpp"
#include "flow/plate.hpp"
#include "flow/shape_field.hpp"
#include "flow/tracker.hpp"

namespace tirstrain::flow::tracker_detail {

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

// The frame-0 tracks a moving frame's affine fit may speak for (their X is a matched frame-0 pixel, so X and
// x share frame 0's coordinates), and the matches it is tested on: the main matches of this frame, whose
// predicted covariance is the subset's own (the rounds' wider subsets take their shape from the neighbours,
// and share their errors).
struct AffineFitMembers {
  std::vector<int> members;
  std::vector<OwnMatch> tested;
};

// A contact with fewer grid points than this is small enough to be mostly border (adapt_to_texture).
constexpr double kFewTracks = 300.0;
// Texture without ridges: the noise the final (fixed-shape) subset is sized for, px.
constexpr double kTargetNoisePx = 0.01;

inline bool inside_mask(const cv::Mat& mask, Vec2 p) {
  const long ix = std::lround(p.x), iy = std::lround(p.y);
  if (ix < 0 || iy < 0 || ix >= mask.cols || iy >= mask.rows) return false;
  return mask.ptr<std::uint8_t>(static_cast<int>(iy))[ix] != 0;
}

inline Mat2d to_matrix(const Gradient2& g) {
  Mat2d m;
  m << g.xx, g.xy, g.yx, g.yy;
  return m;
}

}  // namespace tirstrain::flow::tracker_detail

namespace tirstrain::flow {

struct FeatureTracker::Impl {
  using Mat2d = tracker_detail::Mat2d;
  using KeyFrame = tracker_detail::KeyFrame;
  using TrackState = tracker_detail::TrackState;
  using AffineFitMembers = tracker_detail::AffineFitMembers;

  TrackerOptions settings;
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
  double full_scale = 0.0;  // code of full scale of the sequence's frames, set by the first frame
  cv::Mat current_f, current_u8, previous_u8, mask, match_mask, birth_mask, eigen, eigen_scratch;
  MatchMaskScratch erosion_scratch;
  cv::Mat match_f;       // what subsets are matched in: current_f, smoothed by prefilter_sigma_px
  cv::Mat match_spline;  // match_f's cubic B-spline coefficients over the ROI (B-spline interpolation)
  // What the subsets read the current frame from: match_f's pixels (Keys) or its spline coefficients.
  const cv::Mat& match_source() const {
    return settings.main_match.solver.interpolation == Interpolation::kCubicBSpline ? match_spline : match_f;
  }
  TextureQuality texture;
  bool low_snr = false;
  MainSubsetSizing sizing;
  cv::Rect roi;
  std::vector<cv::Mat> previous_pyramid, current_pyramid;

  // The prediction's global jump (global_jump_shift): the contact's high-passed, reduced frames, this one
  // against the previous one by phase correlation.
  struct HighPass {
    cv::Mat previous, current, blur, weight, small, quarter, mask;
    PhaseCorrelator correlation;  // current against previous
  } jump;

  // Rest handling (follow_rest): until the skin first moves, frame 0's anchor is averaged over the frames so
  // far (`count` of them, up to rest.average_frames) and tracks report the fitted rest motion.
  struct RestAnchor {
    bool active = false;  // still at rest and averaging
    cv::Mat sum, mask;
    int count = 0;
  } rest;

  // The prediction's LK pass (lk_forward, lk_backward_*): points and answers, reused every frame.
  struct LkScratch {
    std::vector<cv::Point2f> from, to, back;
    std::vector<unsigned char> status, back_status, check_status;
    std::vector<int> check;
    std::vector<cv::Point2f> back_from, back_to;
    std::vector<float> error;
  } lk;

  // Per-frame scratch, reused.
  std::vector<int> alive;
  std::vector<double> scratch_x, scratch_y;
  std::vector<int> retry;
  // The neighbour check's second opinions: a match beyond its own noise of the neighbours' prediction,
  // matched again from that prediction.
  struct SecondOpinion {
    int index = -1;
    Vec2 predicted;
    Mat2d deformation = Mat2d::Identity();
  };
  std::vector<SecondOpinion> second_opinion;

  // The fusion (fuse): per alive track, what its sweeps need besides the neighbours' current positions.
  struct FusionTerm {
    bool active = false;
    Eigen::Matrix2d solve = Eigen::Matrix2d::Zero();  // (own information + alpha I)^-1
    Eigen::Vector2d constant = Eigen::Vector2d::Zero();
    double scale = 0.0;  // alpha / sum of the neighbours' weights
  };
  struct FusionScratch {
    std::vector<Vec2> positions;  // each sweep's answers
    std::vector<FusionTerm> terms;
    std::vector<std::vector<std::pair<int, double>>> neighbours;
  } fusion;

  // The rounds' neighbourhood shapes (neighbourhood_shape).
  std::vector<Warp> shapes;
  std::vector<Mat2d> smoothed;

  // Spatial hash of live tracks by current position (build_hash, gather_neighbours).
  struct SpatialHash {
    int cols = 0, rows = 0;
    double cell = 1.0;
    std::vector<int> start, items, fill;
  } hash;
  std::vector<std::uint8_t> lattice_taken;  // births: lattice points with a track nearby
  std::vector<int> neighbours, exact;       // gather_neighbours' answer
  std::vector<cv::Mat> anchor_pyramid;

  // The resampled rounds (resampled_shape_pass): the neighbours' fitted field, the current frame resampled
  // through it, and each frame-0 track's answer of the round.
  struct FieldRounds {
    ShapeField shape;
    cv::Mat frame, valid;    // the resampled frame and where it has data
    WindowSums window_sums;  // of each round's resampled frame, for the subsets' translation steps
    std::vector<Vec2> anchor, displacement;
    std::vector<std::uint8_t> done;
    std::vector<Vec2> position;
    std::vector<MatchResult> match;
    std::vector<double> moved;
    std::vector<int> eligible, others;  // tracks the round takes, and those left to the subset-by-subset pass
  } field;

  // The main match's schedule (main_match.period_frames): tracks that skip this frame's main match, and the
  // tracks that take it.
  struct MainMatchSchedule {
    std::vector<std::uint8_t> skip;
    std::vector<int> to_match, skipped;
  } schedule;

  // The state a checkpoint holds (flow/tracker_checkpoint.cpp).
  void archive(Archive& a);
  void check_input(const cv::Mat& image, const cv::Mat& contact_mask) const;
  void begin_frame(const cv::Mat& image, const cv::Mat& contact_mask);
  void refine_matches();
  void retire_lost();
  void end_frame();
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
  void build_birth_mask();
  void seed_grid();
  void predict_and_match();
  void collect_alive();
  Vec2 global_jump_shift();
  void choose_main_matches();
  Vec2 motion_guess(const TrackState& st, Vec2 shift) const;
  cv::Point2f to_roi(Vec2 p) const;
  cv::TermCriteria lk_criteria() const;
  void lk_forward();
  void lk_backward_all();
  void lk_backward_where_uncorroborated(Vec2 shift);
  void take_lk_guesses(Vec2 shift);
  void match_from_lk_guesses(Vec2 shift);
  bool skips_main_match(int index) const;
  void start_skipped_from_neighbours();
  void match_unconfirmed_skipped();
  void match_from_guesses(const std::vector<int>& indices);
  void match_track(int index, Vec2 guess, const Warp* initial);
  void build_hash(bool matched_only);
  void gather_neighbours(Vec2 p, double radius, int self);
  bool predict_from_neighbours(int index, Vec2& predicted, Mat2d& deformation);
  void check_neighbours();
  bool beyond_own_noise(const TrackState& st, Vec2 predicted) const;
  void take_second_opinions();
  // `last`: the final round, which converges to match.convergence_px (the others stop at
  // fixed_shape_convergence_px).
  void fixed_shape_pass(bool last);
  bool neighbourhood_shape(int i, Warp& shape, Mat2d& f);
  void match_fixed_shapes(bool last);
  void resampled_shape_pass();
  std::optional<cv::Rect> choose_resampled_tracks();
  PixelClasses resampled_lattices() const;
  void resampled_round(const cv::Rect& region, const PixelClasses& lattices);
  void take_resampled_answers();
  double resampled_node_step_px() const { return settings.rounds.node_grid * settings.seeding.grid_step_px; }
  void reanchor();
  void fuse();
  void retire(int index, TrackStatus why);
  void births();
  int mark_taken_lattice(int cols, int rows);
  // A newborn's map to the reference: its reference position, d(reference)/d(current) and its velocity.
  struct BirthMap {
    Vec2 reference;
    Mat2d dX_dx = Mat2d::Identity();
    Vec2 velocity;
  };
  std::optional<BirthMap> reference_map_at(Vec2 x, double fit_radius) const;
  bool within_neighbours_displacements(Vec2 x, Vec2 reference) const;
  bool born_at(Vec2 x, const BirthMap& map, int& key);
  enum class FirstFrameBirth { kBorn, kFailed, kNotSeen };
  FirstFrameBirth birth_from_first_frame(Vec2 x, Vec2 reference, const Mat2d& dX_dx, Vec2 velocity);
  void finish_frame();
  bool build_subsets(const AnchorImage& anchor, cv::Point centre, Subset& subset, Subset& wide) const;
  // The wide subset of a frame-0 track is matched through the resampled rounds' box sums, which read the
  // reference from the anchor: its per-pixel copy is dropped (Subset::release_pixels) and built again only
  // if the subset-by-subset pass needs it.
  void release_wide_pixels(TrackState& st) const {
    if (st.key == 0 && st.exact_reference && settings.refine && settings.rounds.enabled &&
        settings.rounds.resampled)
      st.wide.release_pixels();
  }
  void record_own_matches();
  void decline_fusion_beyond_noise();
  RestTestOptions rest_test_options() const;
  void follow_rest();
  LocalFitOptions local_fit_options() const;
  void report_local_fits();
  void report_affine_fit();
  RestTestOptions affine_test_options() const;
  double second_look_distance2(const TrackState& st, Vec2 on_fit) const;
  AffineFitMembers affine_fit_members() const;
  void place_on_affine_fit(const RestTest& test, const std::vector<int>& members);
  // Frame 0: the non-affine motion the affine test could not see with main subsets of radius `radius_px`
  // (predicted from frame 0's texture and noise), and the main subsets grown until it can see
  // affine_fit.max_hidden_px.
  double predicted_hidden_px(int radius_px) const;
  void size_main_subsets_for_affine_test();
  double ridge_reach_px() const { return 0.25 * settings.prediction.window_px; }
  // The global shift's images are reduced by 2 or 4 while the ridges stay at least 5 px apart there.
  int high_pass_factor() const {
    const double period =
        settings.ridge_period_px > 0.0 ? settings.ridge_period_px : settings.prediction.window_px;
    int factor = 1;
    while (factor < 4 && period / (2 * factor) >= 5.0) factor *= 2;
    return factor;
  }
};

}  // namespace tirstrain::flow
