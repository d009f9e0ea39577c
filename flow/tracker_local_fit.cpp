// Spatially adaptive averaging of the tracks' own matches (flow/local_fit.hpp), reported in place of a
// track's match only where the frame's own evidence accepts the window it was fitted over.
#include <algorithm>
#include <cmath>

#include "flow/detail/tracker_impl.hpp"

namespace tirstrain::flow {

using namespace tracker_detail;

// Windows from 1.5 grid steps (the nearest ring of neighbours) growing by √2 up to the largest radius;
// overlapping subsets share noise over the matched subset's side plus the prefilter's reach.
LocalFitOptions FeatureTracker::Impl::local_fit_options() const {
  LocalFitOptions o;
  const double step = settings.seeding.grid_step_px;
  const double largest =
      settings.local_fit.max_radius_px > 0.0 ? settings.local_fit.max_radius_px : 8.0 * step;
  for (double r = 1.5 * step; r < largest * (1.0 + 1e-9); r *= std::sqrt(2.0)) o.radii_px.push_back(r);
  if (o.radii_px.empty() || o.radii_px.back() < largest) o.radii_px.push_back(largest);
  o.agreement_chi2 = settings.local_fit.agreement_chi2;
  o.order = settings.local_fit.order;
  o.per_component = settings.local_fit.per_component;
  const int radius = settings.rounds.enabled
                         ? std::max(settings.main_match.subset_radius_px, settings.rounds.subset_radius_px)
                         : settings.main_match.subset_radius_px;
  o.correlation_side_px = 2.0 * (radius + 2.0 * settings.main_match.prefilter_sigma_px) + 1.0;
  return o;
}

// Every track whose own match is valid takes part; a track reports the chosen window's fit unless the rest
// fit already stands in for it (the same affine motion, tested on the whole frame), or, on low-SNR texture,
// the fusion does: there a subset is pinned along its ridges only by their curvature, its predicted
// covariance is no measure of that direction's error, and the fusion (designed for exactly that direction,
// at full weight) is the better evidence.
void FeatureTracker::Impl::report_local_fits() {
  if (!settings.refine || !settings.local_fit.enabled) return;
  std::vector<OwnMatch> matches;
  std::vector<int> members;
  for (int i : alive) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.own_valid) continue;
    matches.push_back(st.own);
    members.push_back(i);
  }
  const std::vector<LocalFit> fits = choose_local_fits(matches, local_fit_options());
  for (std::size_t k = 0; k < fits.size(); ++k) {
    const LocalFit& fit = fits[k];
    Track& t = tracks[static_cast<std::size_t>(members[k])];
    // A component alone never replaces a position that is not the own match (a fused track keeps it).
    if (fit.window < 0 && t.model != TrackModel::kOwnMatch) continue;
    if (!fit.reports_fit() || t.model == TrackModel::kRestFit || (low_snr && t.model == TrackModel::kFused))
      continue;
    const OwnMatch& own = matches[k];
    const Vec2 position{own.reference_px.x + fit.displacement_px.x,
                        own.reference_px.y + fit.displacement_px.y};
    if (t.model == TrackModel::kFused) --stats.fused;
    t.position_px = position;
    t.model = TrackModel::kLocalFit;
    t.model_mahalanobis2 = fit.own_mahalanobis2;
    t.model_window_px = fit.component_radius_px;
    if (fit.component_radius_px[0] != fit.component_radius_px[1]) ++stats.local_fit_by_component;
    ++stats.local_fit;
  }
}

}  // namespace tirstrain::flow
