// Fusion: each track's own match blended with its neighbours' in proportion to their information, and
// declined where the blend moves a track further than its own match noise allows.
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
    st.own.covariance_px2 = predicted_match_covariance(
        st.match.zncc, matched.pixel_count(), information,
        correlated_pixels(settings.main_match.prefilter_sigma_px, matched.stride()));
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

// A subset of about one ridge period pins the motion across its ridges but hardly along them, and where
// the ridges run straight for a while, all its neighbours share that blind direction. So the positions are
// the solution of a small regularised least-squares problem: each track's match weighted by its subset's
// translation information, plus a weak smoothness term tying it to what its neighbours imply (their
// positions carried over by the mean deformation gradient). The smoothness weight is a small fraction of
// each track's own information, so it decides only the directions the texture leaves open; Jacobi sweeps,
// warm-started from the matches, spread that information along the ridges.
void FeatureTracker::Impl::fuse() {
  const double sigma = settings.fusion.sigma_px;
  const double radius = 2.0 * sigma;
  build_hash(true);
  const std::size_t n = alive.size();
  fusion.positions.resize(n);
  fusion.terms.resize(n);
  fusion.neighbours.resize(n);
  // Everything but the neighbours' positions is the same in every sweep (the weights depend on the
  // reference positions, the neighbours' offsets on the deformation gradients, the system on the track's
  // own information), so it is set up once and a sweep is a weighted sum per track.
  cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = alive[static_cast<std::size_t>(k)];
      const TrackState& st = states[static_cast<std::size_t>(i)];
      FusionTerm& term = fusion.terms[static_cast<std::size_t>(k)];
      std::vector<std::pair<int, double>>& list = fusion.neighbours[static_cast<std::size_t>(k)];
      term.active = false;
      list.clear();
      if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
      const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
      const Vec2 p = st.candidate;
      const Eigen::Matrix2d own = st.fixed_shape ? st.fixed_information : st.subset.translation_information();
      const double alpha = settings.fusion.weight * 0.5 * own.trace();
      double wsum = 0.0;
      Eigen::Vector2d offset_sum = Eigen::Vector2d::Zero();
      const int cx0 = std::max(0, static_cast<int>((p.x - radius) / hash.cell));
      const int cx1 = std::min(hash.cols - 1, static_cast<int>((p.x + radius) / hash.cell));
      const int cy0 = std::max(0, static_cast<int>((p.y - radius) / hash.cell));
      const int cy1 = std::min(hash.rows - 1, static_cast<int>((p.y + radius) / hash.cell));
      for (int cy = cy0; cy <= cy1; ++cy)
        for (int cx = cx0; cx <= cx1; ++cx) {
          const std::size_t c = static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash.cols) +
                                static_cast<std::size_t>(cx);
          for (int h = hash.start[c]; h < hash.start[c + 1]; ++h) {
            const int j = hash.items[static_cast<std::size_t>(h)];
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
  for (int sweep = 0; sweep < settings.fusion.sweeps; ++sweep) {
    cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) {
        const FusionTerm& term = fusion.terms[static_cast<std::size_t>(k)];
        const Vec2 current = states[static_cast<std::size_t>(alive[static_cast<std::size_t>(k)])].candidate;
        fusion.positions[static_cast<std::size_t>(k)] = current;
        if (!term.active) continue;
        Eigen::Vector2d q_sum = Eigen::Vector2d::Zero();
        for (const auto& [j, w] : fusion.neighbours[static_cast<std::size_t>(k)]) {
          const Vec2 c = states[static_cast<std::size_t>(j)].candidate;
          q_sum += w * Eigen::Vector2d(c.x, c.y);
        }
        const Eigen::Vector2d x = term.solve * (term.constant + term.scale * q_sum);
        if (x.allFinite()) fusion.positions[static_cast<std::size_t>(k)] = {x.x(), x.y()};
      }
    });
    for (std::size_t k = 0; k < n; ++k)
      states[static_cast<std::size_t>(alive[k])].candidate = fusion.positions[k];
  }
}

}  // namespace tirstrain::flow
