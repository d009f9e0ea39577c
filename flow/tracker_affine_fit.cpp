// The frame's affine fit: where one affine motion describes this frame's matches within their predicted
// noise and without spatial structure, it stands in for each match that lies within its own noise of it.
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "core/median.hpp"
#include "flow/detail/tracker_impl.hpp"

namespace tirstrain::flow {

using namespace tracker_detail;

namespace {

// The smaller of the fit's distances from a track's own match and from this frame's main match, in units of
// each one's predicted noise: the fit stands in where either of the track's own measurements agrees with it.
double fit_distance2(Vec2 on_fit, const TrackState& st, int frame) {
  const auto distance2 = [&on_fit](const OwnMatch& m) {
    return mahalanobis2({on_fit.x - m.position_px.x, on_fit.y - m.position_px.y}, m.covariance_px2);
  };
  double d2 = distance2(st.own);
  if (st.main_frame == frame) d2 = std::min(d2, distance2(st.main));
  return d2;
}

// The RMS of a non-affine motion, spread over the frame, that the test's χ² bound lets through: the matches'
// typical noise (the median of each one's geometric-mean σ, det(C)^(1/4)) times sqrt(bound − 1).
double hidden_motion_px(const std::vector<OwnMatch>& tested, double max_chi2_per_dof) {
  std::vector<double> sigma;
  sigma.reserve(tested.size());
  for (const OwnMatch& m : tested)
    sigma.push_back(std::pow(std::max(m.covariance_px2.determinant(), 0.0), 0.25));
  if (sigma.empty()) return std::numeric_limits<double>::infinity();
  return upper_median_in_place(sigma) * std::sqrt(std::max(max_chi2_per_dof - 1.0, 0.0));
}

// The standard deviation of white pixel noise after OpenCV's Gaussian of σ (its kernel for float images),
// per unit of the noise before: the 2-D kernel's Σ w² is the 1-D one's squared.
double gaussian_noise_gain(double sigma_px) {
  if (sigma_px <= 0.0) return 1.0;
  const int side = std::max(3, (static_cast<int>(std::lround(sigma_px * 8.0 + 1.0)) | 1));
  const cv::Mat kernel = cv::getGaussianKernel(side, sigma_px, CV_64F);
  return kernel.dot(kernel);
}

}  // namespace

// What the test's χ² bound would let through on frame 0's texture: each sampled subset's predicted
// covariance (predicted_match_covariance, with the zncc that the frame's own noise in both frames gives,
// 1 − zncc = σ² n / Σf²) put through hidden_motion_px.
double FeatureTracker::Impl::predicted_hidden_px(int radius_px) const {
  const AnchorImage& anchor = keys[0]->anchor;
  const TrackerOptions::MainMatch& main = settings.main_match;
  const double noise = texture.noise_sigma * gaussian_noise_gain(main.prefilter_sigma_px);
  const double correlated = correlated_pixels(main.prefilter_sigma_px, main.subset_stride);
  const int side = 2 * (radius_px / main.subset_stride) + 1;
  // About a hundred subsets, on a lattice over the contact.
  const double area = std::max(1, cv::countNonZero(match_mask));
  const int step =
      std::max(static_cast<int>(settings.seeding.grid_step_px), static_cast<int>(std::sqrt(area / 100.0)));
  std::vector<OwnMatch> sampled;
  Subset subset;
  for (int y = radius_px; y < size.height - radius_px; y += step)
    for (int x = radius_px; x < size.width - radius_px; x += step) {
      if (!match_mask.at<std::uint8_t>(y, x)) continue;
      if (!subset.build(anchor, {x, y}, radius_px, main.subset_stride, main.shape, side * side / 3)) continue;
      const double n = static_cast<double>(subset.pixel_count());
      const double zncc = 1.0 - noise * noise * n / subset.reference_energy();
      OwnMatch m;
      m.covariance_px2 = predicted_match_covariance(zncc, subset.pixel_count(),
                                                    subset.translation_information(), correlated);
      sampled.push_back(m);
    }
  return hidden_motion_px(sampled, settings.affine_fit.max_chi2_per_dof);
}

// A subset about one ridge period wide pins its translation along the ridges only through their curvature:
// on a noisy texture the test of step 5 then cannot see a non-affine motion of max_hidden_px, and no fit may
// stand in. The main subsets grow (up to the rounds' width) until it can; where even that width would not do,
// they keep the preset's size, as growing would only cost resolution.
void FeatureTracker::Impl::size_main_subsets_for_affine_test() {
  TrackerOptions::MainMatch& main = settings.main_match;
  sizing = MainSubsetSizing{};
  sizing.preset_radius_px = sizing.radius_px = main.subset_radius_px;
  if (!settings.refine || !settings.affine_fit.enabled || !settings.texture.adapt ||
      settings.pinned.subset_radius || texture.pixels == 0 || !keys[0])
    return;
  const double target_px = settings.affine_fit.max_hidden_px;
  sizing.predicted_hidden_px = sizing.predicted_hidden_after_px = predicted_hidden_px(main.subset_radius_px);
  const int widest = std::max(main.subset_radius_px, settings.rounds.subset_radius_px);
  if (!(sizing.predicted_hidden_px > target_px) || widest == main.subset_radius_px ||
      !(predicted_hidden_px(widest) <= target_px))
    return;
  // The noise falls about as the subset's side grows: start there, and widen until the prediction passes.
  const double side = (2.0 * main.subset_radius_px + 1.0) * sizing.predicted_hidden_px / target_px;
  int radius = std::clamp(static_cast<int>(std::ceil(0.5 * (side - 1.0))), main.subset_radius_px + 1, widest);
  double hidden_px = predicted_hidden_px(radius);
  while (radius < widest && !(hidden_px <= target_px)) hidden_px = predicted_hidden_px(++radius);
  main.subset_radius_px = sizing.radius_px = radius;
  sizing.predicted_hidden_after_px = hidden_px;
}

// A second main match of a track whose own matches disagree with the fit, started from the fit's position:
// its subset against the anchor again, so that a match that converged beside the answer (along its ridges, or
// to a neighbouring minimum) gets another chance; the track's state is left as it was. The distance² of the
// fit from that match in its predicted noise, or infinity where it does not converge.
double FeatureTracker::Impl::second_look_distance2(const TrackState& st, Vec2 on_fit) const {
  if (st.subset.empty()) return std::numeric_limits<double>::infinity();
  Warp warp = st.warp;
  const cv::Point c = st.subset.centre();
  warp.set_displacement_at(st.offset.x, st.offset.y,
                           {on_fit.x - c.x - st.offset.x, on_fit.y - c.y - st.offset.y});
  const MatchResult match = st.subset.match(match_source(), match_mask, warp, settings.main_match.solver);
  if (!match.converged || match.zncc < settings.main_match.min_zncc)
    return std::numeric_limits<double>::infinity();
  const Vec2 u = warp.displacement_px(st.offset.x, st.offset.y);
  const Vec2 position{c.x + st.offset.x + u.x, c.y + st.offset.y + u.y};
  const Eigen::Matrix2d covariance = predicted_match_covariance(
      match.zncc, st.subset.pixel_count(), st.subset.translation_information(),
      correlated_pixels(settings.main_match.prefilter_sigma_px, st.subset.stride()));
  return mahalanobis2({on_fit.x - position.x, on_fit.y - position.y}, covariance);
}

RestTestOptions FeatureTracker::Impl::affine_test_options() const {
  RestTestOptions o = rest_test_options();
  o.max_chi2_per_dof = settings.affine_fit.max_chi2_per_dof;
  o.max_correlation_z = settings.affine_fit.max_correlation_z;
  return o;
}

// The frame-0 tracks the fit may speak for, and this frame's main matches among them.
AffineFitMembers FeatureTracker::Impl::affine_fit_members() const {
  AffineFitMembers m;
  for (int i : alive) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || st.key != 0 || !st.exact_reference ||
        !st.own_valid)
      continue;
    m.members.push_back(i);
    if (st.main_frame == frame) m.tested.push_back(st.main);
  }
  return m;
}

// Each member whose own match, main match or second look lies within its noise of the fit reports the fit.
void FeatureTracker::Impl::place_on_affine_fit(const RestTest& test, const std::vector<int>& members) {
  const Gradient2 gradient = test.gradient();
  for (int i : members) {
    Track& t = tracks[static_cast<std::size_t>(i)];
    const Vec2 d = test.displacement_px(t.reference_px);
    const Vec2 on_fit{t.reference_px.x + d.x, t.reference_px.y + d.y};
    const TrackState& st = states[static_cast<std::size_t>(i)];
    double d2 = fit_distance2(on_fit, st, frame);
    if (!(d2 <= kModelShiftChi2)) d2 = second_look_distance2(st, on_fit);
    if (!(d2 <= kModelShiftChi2)) continue;  // a motion of its own: it keeps what it reports
    t.position_px = on_fit;
    t.gradient = gradient;
    t.model = TrackModel::kAffineFit;
    t.model_mahalanobis2 = d2;
    t.model_window_px = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
    ++stats.on_affine_fit;
  }
  const auto reporting = [this](TrackModel model) {
    return static_cast<int>(std::count_if(tracks.begin(), tracks.end(), [model](const Track& t) {
      return is_alive(t.status) && t.model == model;
    }));
  };
  stats.fused = reporting(TrackModel::kFused);
  stats.local_fit = reporting(TrackModel::kLocalFit);
}

void FeatureTracker::Impl::report_affine_fit() {
  if (!settings.refine || !settings.affine_fit.enabled || stats.at_rest) return;
  const AffineFitMembers m = affine_fit_members();
  const RestTest test = test_affine_model(m.tested, affine_test_options());
  stats.affine_tested = true;
  stats.affine_chi2_per_dof = test.chi2_per_dof;
  stats.affine_correlation_z = test.correlation_z;
  stats.affine_hidden_px = hidden_motion_px(m.tested, settings.affine_fit.max_chi2_per_dof);
  if (!test.affine || !(stats.affine_hidden_px <= settings.affine_fit.max_hidden_px)) return;
  stats.affine_fit = true;
  place_on_affine_fit(test, m.members);
}

}  // namespace tirstrain::flow
