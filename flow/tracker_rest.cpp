// Rest handling: while the skin has not yet moved, frame 0's anchor is averaged over the frames so far and
// a rest model stands in for the tracks only where a test on the frame's own evidence accepts it.
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
#include "core/median.hpp"
#include "flow/detail/tracker_impl.hpp"
#include "flow/mask_erosion.hpp"
#include "flow/shi_tomasi.hpp"

namespace tirstrain::flow {

using namespace tracker_detail;

// Two tracks' main matches are independent when no pixel of one's subset (smoothed by the prefilter) enters
// the other's.
RestTestOptions FeatureTracker::Impl::rest_test_options() const {
  RestTestOptions o;
  o.max_chi2_per_dof = settings.rest.max_chi2_per_dof;
  o.max_correlation_z = settings.rest.max_correlation_z;
  const double reach = settings.main_match.subset_radius_px + 2.0 * settings.main_match.prefilter_sigma_px;
  o.independence_px = 2.0 * reach + 1.0;
  o.pair_band_px = 2.0 * settings.seeding.grid_step_px;
  o.tolerance_px = settings.rest.tolerance_px;
  o.max_motion_chi2 = settings.rest.max_motion_chi2;
  o.correlated_tracks = std::numbers::pi * std::pow(reach / settings.seeding.grid_step_px, 2);
  return o;
}

// While nothing has moved since frame 0, frame 0's anchor becomes the mean of the frames so far (see
// TrackerOptions::rest_average_frames): every later match then sees the anchor's pixel noise divided by
// the square root of their number; and the tracks report the fitted rest motion rather than their own
// noise. Rest is a test of an affine fit of the frame-0 tracks' own matches against their predicted
// noise (test_affine_model).
void FeatureTracker::Impl::follow_rest() {
  if (!rest.active) return;
  const auto end_averaging = [this] {
    rest.count = 0;
    rest.sum.release();
    rest.mask.release();
  };
  const auto stop = [&] {
    rest.active = false;
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
  if (rest.count < 1 || rest.count >= settings.rest.average_frames) return end_averaging();
  rest.sum += match_f;
  ++rest.count;
  KeyFrame& key = *keys[0];
  key.anchor.assign(rest.sum * (1.0 / rest.count), rest.mask);
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

}  // namespace tirstrain::flow
