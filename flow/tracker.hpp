#pragma once
// Feature tracking of the skin inside the contact, one frame at a time (the pipeline calls track() per
// frame; `tirstrain track` drives it over an image sequence).
//
// Per frame: the frame's LK pyramid is built once (on the contact ROI) and reused as the previous pyramid
// next frame; every live track is predicted (its own last motion, or the contact's global shift from phase
// correlation when the frame jumped), followed by pyramidal LK with a forward–backward check, then refined
// against its anchor frame (frame 0, or the frame it was born in) by a masked IC-GN subset match with a
// second-order shape function, so the error never accumulates from frame to frame. Each track is then
// checked against what its neighbours imply (their positions carried over by their deformation gradients);
// a disagreeing track is re-matched from that prediction or retired. Each trusted track is then matched
// again for its translation only, its shape fixed at a fit of its neighbours' displacements (the shape
// terms otherwise let noise slide a subset along its ridges). Tracks leaving the contact are retired; where
// coverage thins, tracks are born: X is first mapped back through a local fit of the neighbours' current →
// reference map, then, where frame 0 saw that skin, matched in frame 0 itself. See docs/flow.md.
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "flow/model_check.hpp"
#include "flow/settings.hpp"
#include "flow/texture.hpp"

namespace tirstrain {
class Archive;
}

namespace tirstrain::flow {

// Written per frame and track as /tracks/status. Values < 10 are live tracks; ≥ 10 say why a track was
// retired (in the frame it was retired; afterwards it is simply not alive).
enum class TrackStatus : std::int8_t {
  kTracked = 0,           // matched this frame
  kBorn = 1,              // born this frame (reference position mapped back through its neighbours)
  kRecovered = 2,         // re-matched from its neighbours' prediction (either case of docs/flow.md step 6)
  kUnchecked = 3,         // matched, but too few neighbours to check it against
  kLeftContact = 10,      // left the contact (or too little of its subset is still in contact)
  kForwardBackward = 11,  // forward–backward LK check failed (unrefined tracking)
  kPoorMatch = 12,        // no converged match with enough correlation
  kInconsistent = 13,     // disagreed with its neighbours even after re-matching
  kLeftImage = 14,        // left the image or the tracked region
};

inline bool is_alive(TrackStatus s) {
  return static_cast<int>(s) < 10;
}
const char* to_string(TrackStatus status);

struct Track {
  std::int64_t id = 0;
  Vec2 reference_px;  // X: position in the reference (first) frame
  Vec2 position_px;   // x_t: current position while alive; the last good position after retirement
  TrackStatus status = TrackStatus::kTracked;
  int born_frame = 0;
  int retired_frame = -1;
  // X was not matched in the reference frame but extrapolated from the neighbours' map current → reference:
  // skin the reference frame did not see (where the contact grew). Its displacement is then partly a model.
  bool reference_extrapolated = false;
  double zncc = 0.0;  // correlation of the last refined match (1 for unrefined tracks)
  // Share of the last refined match's subset pixels that lay inside the contact (and the image): below 1
  // where the subset crosses the contact's border; the rest of its pixels are not used.
  double subset_inside_fraction = 1.0;
  Gradient2 gradient;  // du/dX at the track from its subset's shape function (zero if unrefined)
  // What position_px is this frame: the track's own match, or a model a test on the frame accepted
  // (flow/model_check.hpp), with that test's statistic for this track: the squared Mahalanobis distance of
  // the model's position from the own match, in the match's predicted noise (NaN for the own match).
  TrackModel model = TrackModel::kOwnMatch;
  double model_mahalanobis2 = std::numeric_limits<double>::quiet_NaN();
  // The own match's position this frame, whatever position_px reports (NaN where the track was not matched by
  // a subset): what a model fit downstream should be given, not another model's smoothing.
  Vec2 own_position_px{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  // For a local fit (TrackModel::kLocalFit), the radius of the window each component (x, y) was fitted over,
  // px (0: that component is the own match's; the whole frame's fit: its reach); NaN otherwise.
  std::array<double, 2> model_window_px{std::numeric_limits<double>::quiet_NaN(),
                                        std::numeric_limits<double>::quiet_NaN()};
  // The own match's predicted covariance this frame, px² (xx, xy, yy; flow/model_check.hpp); NaN where the
  // track was not matched by a subset (unrefined tracking, a frame whose match failed).
  std::array<double, 3> covariance_px2{std::numeric_limits<double>::quiet_NaN(),
                                       std::numeric_limits<double>::quiet_NaN(),
                                       std::numeric_limits<double>::quiet_NaN()};
};

struct FrameStats {
  int frame = 0;
  int alive = 0;
  int born = 0;
  int retired = 0;
  int recovered = 0;
  int main_matched = 0;  // tracks that took LK and the main match (the others started from their neighbours)
  bool global_jump = false;      // the frame's prediction came from the global shift, not the tracks' motion
  Vec2 global_shift_px;          // phase-correlation shift of the contact since the previous frame
  int rest_frames_averaged = 0;  // 1: this frame was at rest and joined frame 0's averaged anchor
  bool at_rest = false;  // this frame was at rest: its frame-0 tracks report the affine fit of their motion
  // The rest test of this frame (tested: while the anchor may still be averaged), RestTest's statistics.
  bool rest_tested = false;
  double rest_chi2_per_dof = std::numeric_limits<double>::quiet_NaN();
  double rest_correlation_z = std::numeric_limits<double>::quiet_NaN();
  int rest_pairs = 0;
  double rest_motion_px = std::numeric_limits<double>::quiet_NaN();  // the fitted motion's RMS
  int on_rest_fit = 0;                                               // tracks reporting the rest fit
  // The affine-fit test of this frame (tested: the frame was not at rest and the step is on), RestTest's
  // statistics, and whether the fit stands in for the matches that lie within their noise of it.
  bool affine_tested = false;
  double affine_chi2_per_dof = std::numeric_limits<double>::quiet_NaN();
  double affine_correlation_z = std::numeric_limits<double>::quiet_NaN();
  // The non-affine motion (RMS over the frame, px) the test's χ² bound would let through at these matches'
  // noise; the fit stands in only where it is at most TrackerOptions::affine_fit.max_hidden_px.
  double affine_hidden_px = std::numeric_limits<double>::quiet_NaN();
  bool affine_fit = false;
  int on_affine_fit = 0;    // tracks reporting the frame's affine fit
  int fused = 0;            // tracks reporting the neighbour fusion's position
  int fusion_declined = 0;  // tracks whose fused position lay outside their own match's noise: own match
  int local_fit = 0;        // tracks reporting a local fit of their neighbours' matches (flow/local_fit.hpp)
  int local_fit_by_component = 0;  // of those, tracks whose two components come from different windows
  // Alive tracks whose own match has a direction the texture does not determine (straight ridges, no
  // texture): their position is not measured along it (covariance kUnmeasuredVariance_px2 there).
  int unmeasured_direction = 0;
};

// Frame 0's sizing of the main subsets for the moving frame's affine test (docs/flow.md, "Frame 0"): the
// non-affine motion the test could not see, predicted from frame 0's texture and noise, at the preset's
// radius and at the radius in effect.
struct MainSubsetSizing {
  int preset_radius_px = 0;
  int radius_px = 0;
  double predicted_hidden_px = std::numeric_limits<double>::quiet_NaN();        // at preset_radius_px
  double predicted_hidden_after_px = std::numeric_limits<double>::quiet_NaN();  // at radius_px
  bool grown() const { return radius_px > preset_radius_px; }
};

class PlateTracker;

// The settings in a checkpoint (core/archive.hpp).
void archive(Archive& a, TrackerOptions& settings);

class FeatureTracker {
 public:
  // `plate_roi`: the band of the image showing the pattern printed on the glass
  // (Scene::reference_pattern_roi).
  explicit FeatureTracker(TrackerOptions settings, std::optional<RoiPx> plate_roi = std::nullopt);
  ~FeatureTracker();
  FeatureTracker(const FeatureTracker&) = delete;
  FeatureTracker& operator=(const FeatureTracker&) = delete;

  // Frame 0. `image` CV_8U, CV_16U or CV_32F (full scale 1) grey; `contact_mask` CV_8U (non-zero = contact)
  // of the same size, or empty (the whole image). Seeds features on the grid inside the contact (Shi–Tomasi).
  void start(const cv::Mat& image, const cv::Mat& contact_mask, double t_s);
  // The same, tracking the given points instead of a grid (no births).
  void start(const cv::Mat& image, const cv::Mat& contact_mask, double t_s,
             const std::vector<Vec2>& points_px);
  // The next frame. Throws Error if the size differs from the first frame's.
  const FrameStats& track(const cv::Mat& image, const cv::Mat& contact_mask, double t_s);

  int frame_index() const;  // 0 after start(), incremented by each track()
  // Every track ever created; tracks()[k].id == k, so K only grows. Alive: is_alive(status).
  const std::vector<Track>& tracks() const;
  const FrameStats& stats() const;
  // The settings in effect (after adapt_to_texture, once started).
  const TrackerOptions& settings() const;
  // Frame 0's texture as measured at start() (refined tracking only), and whether it made the subsets
  // drop to the low-SNR configuration.
  const TextureQuality& texture() const;
  bool low_snr_texture() const;
  const MainSubsetSizing& main_subset_sizing() const;
  // The whole state after the last frame, as a checkpoint (core/archive.hpp), and that state put back into a
  // tracker made with the same settings and plate band: the next track() then gives what it would have
  // given on the tracker that wrote it. Throws Error for a checkpoint from another build.
  std::vector<char> checkpoint() const;
  void restore(const std::vector<char>& snapshot);
  // The same state written into, or read back from, a larger snapshot (a pipeline stage's).
  void archive(Archive& a);
  // Plate displacement since frame 0 (median over the pattern's subsets); nullopt without a pattern ROI.
  std::optional<Vec2> plate_displacement_px() const;
  // How this frame's plate displacement was obtained (a flow/plate.hpp PlateStatus); nullopt without a
  // pattern ROI.
  std::optional<std::int8_t> plate_status() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Frame conversions: float with full scale 1, and 8 bits for LK. `full_scale` is the code of full scale of
// an 8- or 16-bit image (core/full_scale.hpp decides it); float images are taken as fractions already.
cv::Mat to_float_image(const cv::Mat& image);  // with full_scale_of(image)
void to_float_image(const cv::Mat& image, cv::Mat& out, double full_scale);
void to_u8_image(const cv::Mat& image, cv::Mat& out, double full_scale);

}  // namespace tirstrain::flow
