// The neighbour check: a spatial hash of the live tracks, and a track whose match disagrees with its
// neighbours' affine prediction is matched again from that prediction.
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
#include "flow/model_check.hpp"
#include "flow/shi_tomasi.hpp"

namespace tirstrain::flow {

using namespace tracker_detail;

void FeatureTracker::Impl::build_hash(bool matched_only) {
  hash.cell = std::max(4.0, settings.neighbours.radius_px);
  hash.cols = static_cast<int>(size.width / hash.cell) + 1;
  hash.rows = static_cast<int>(size.height / hash.cell) + 1;
  const std::size_t cells = static_cast<std::size_t>(hash.cols) * static_cast<std::size_t>(hash.rows);
  hash.start.assign(cells + 1, 0);
  hash.items.clear();
  const auto cell_of = [&](Vec2 p) {
    const int cx = std::clamp(static_cast<int>(p.x / hash.cell), 0, hash.cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y / hash.cell), 0, hash.rows - 1);
    return static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash.cols) + static_cast<std::size_t>(cx);
  };
  const auto usable = [&](int i) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    return is_alive(tracks[static_cast<std::size_t>(i)].status) &&
           (!matched_only || (st.matched && !st.suspect));
  };
  for (int i : alive)
    if (usable(i)) ++hash.start[cell_of(states[static_cast<std::size_t>(i)].candidate) + 1];
  for (std::size_t c = 0; c < cells; ++c) hash.start[c + 1] += hash.start[c];
  hash.items.resize(static_cast<std::size_t>(hash.start[cells]));
  hash.fill.assign(hash.start.begin(), hash.start.end() - 1);
  for (int i : alive)
    if (usable(i))
      hash.items[static_cast<std::size_t>(
          hash.fill[cell_of(states[static_cast<std::size_t>(i)].candidate)]++)] = i;
}

void FeatureTracker::Impl::gather_neighbours(Vec2 p, double radius, int self) {
  neighbours.clear();
  const int cx0 = std::max(0, static_cast<int>((p.x - radius) / hash.cell));
  const int cx1 = std::min(hash.cols - 1, static_cast<int>((p.x + radius) / hash.cell));
  const int cy0 = std::max(0, static_cast<int>((p.y - radius) / hash.cell));
  const int cy1 = std::min(hash.rows - 1, static_cast<int>((p.y + radius) / hash.cell));
  const double r2 = radius * radius;
  for (int cy = cy0; cy <= cy1; ++cy)
    for (int cx = cx0; cx <= cx1; ++cx) {
      const std::size_t c =
          static_cast<std::size_t>(cy) * static_cast<std::size_t>(hash.cols) + static_cast<std::size_t>(cx);
      for (int k = hash.start[c]; k < hash.start[c + 1]; ++k) {
        const int j = hash.items[static_cast<std::size_t>(k)];
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
  gather_neighbours(st.candidate, settings.neighbours.radius_px, index);
  if (static_cast<int>(neighbours.size()) < settings.neighbours.min_count) return false;
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
  predicted = {tirstrain::median_in_place(scratch_x), tirstrain::median_in_place(scratch_y)};
  deformation = sum / static_cast<double>(neighbours.size());
  return true;
}

namespace {
// A re-match to start the subset's warp from: the neighbours' prediction and mean deformation.
Warp warp_from_neighbours(const Mat2d& deformation, const Mat2d& birth, ShapeFunction shape) {
  Warp w;
  const Mat2d a = deformation * birth.inverse() - Mat2d::Identity();
  w.p[2] = a(0, 0);
  w.p[3] = a(0, 1);
  w.p[4] = a(1, 0);
  w.p[5] = a(1, 1);
  if (shape == ShapeFunction::kTranslation) w.p[2] = w.p[3] = w.p[4] = w.p[5] = 0.0;
  return w;
}

// What match_track changes in a track's state, to put the first match back when a second one loses.
struct MatchSnapshot {
  Warp warp;
  Vec2 guess, candidate;
  bool fixed_shape = false, matched = false, suspect = false;
  Mat2d deformation;
  MatchResult match;
  int main_frame = -1;
  OwnMatch main;

  static MatchSnapshot of(const TrackState& st) {
    return {st.warp,    st.guess,       st.candidate, st.fixed_shape, st.matched,
            st.suspect, st.deformation, st.match,     st.main_frame,  st.main};
  }
  void restore(TrackState& st) const {
    st.warp = warp;
    st.guess = guess;
    st.candidate = candidate;
    st.fixed_shape = fixed_shape;
    st.matched = matched;
    st.suspect = suspect;
    st.deformation = deformation;
    st.match = match;
    st.main_frame = main_frame;
    st.main = main;
  }
};

// Whether b lies beyond a's predicted noise (covariance c, px²) of a: χ²(2) at 99.9 %.
bool beyond_noise(Vec2 a, Vec2 b, const Eigen::Matrix2d& c) {
  if (!(c.determinant() > 0.0)) return false;
  const Eigen::Vector2d d(b.x - a.x, b.y - a.y);
  return d.dot(c.inverse() * d) > kModelShiftChi2;
}

// How much lower than `zncc` another match of the same subset may correlate from the noise alone: a
// squared-residual difference of χ²(2) at 99.9 % in units of the residual's variance per independent pixel
// (Σ (f − g)² ≈ 2 (1 − ZNCC) Σ f², flow/model_check.hpp).
double correlation_tie(double zncc, const Subset& subset, double prefilter_sigma_px) {
  const double independent =
      static_cast<double>(subset.pixel_count()) / correlated_pixels(prefilter_sigma_px, subset.stride());
  return kModelShiftChi2 * (1.0 - zncc) / std::max(1.0, independent);
}
}  // namespace

bool FeatureTracker::Impl::beyond_own_noise(const TrackState& st, Vec2 predicted) const {
  return beyond_noise(st.candidate, predicted, st.main.covariance_px2);
}

void FeatureTracker::Impl::check_neighbours() {
  build_hash(true);
  retry.clear();
  second_opinion.clear();
  for (int i : alive) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    // Placed by its neighbours' corrections: nothing of its own to check yet.
    if (!schedule.skip.empty() && schedule.skip[static_cast<std::size_t>(i)]) continue;
    Vec2 predicted;
    Mat2d deformation;
    if (!predict_from_neighbours(i, predicted, deformation)) {
      if (st.suspect)
        retire(i, st.match.valid_fraction < settings.main_match.solver.min_valid_fraction
                      ? TrackStatus::kLeftContact
                      : TrackStatus::kPoorMatch);
      else
        tracks[static_cast<std::size_t>(i)].status = TrackStatus::kUnchecked;
      continue;
    }
    const double deviation = std::hypot(st.candidate.x - predicted.x, st.candidate.y - predicted.y);
    if (!st.suspect && deviation <= settings.neighbours.tolerance_px) {
      if (st.main_frame == frame && beyond_own_noise(st, predicted))
        second_opinion.push_back({i, predicted, deformation});
      continue;
    }
    if (st.match.valid_fraction < settings.main_match.solver.min_valid_fraction) {
      retire(i, TrackStatus::kLeftContact);
      continue;
    }
    // Re-match from the neighbours' prediction, with their deformation as the subset's first-order terms.
    st.warp = warp_from_neighbours(deformation, st.birth, settings.main_match.shape);
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
    if (st.matched && deviation <= settings.neighbours.tolerance_px) {
      st.suspect = false;
      tracks[static_cast<std::size_t>(i)].status = TrackStatus::kRecovered;
      ++stats.recovered;
    } else {
      retire(i, st.matched ? TrackStatus::kInconsistent
                           : (st.match.valid_fraction < settings.main_match.solver.min_valid_fraction
                                  ? TrackStatus::kLeftContact
                                  : TrackStatus::kPoorMatch));
    }
  }
  take_second_opinions();
}

// A match that settled beyond its own noise of where the neighbours put it, but within the tolerance, is
// matched again from their prediction. Along its ridges a subset's cost hardly changes, so a match started
// from its own last motion can stay where it started; the second match replaces the first when it fits the
// subset as well (its correlation no lower than the noise allows), and the first stands otherwise.
void FeatureTracker::Impl::take_second_opinions() {
  std::vector<char> adopted(second_opinion.size(), 0);
  cv::parallel_for_(cv::Range(0, static_cast<int>(second_opinion.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const SecondOpinion& o = second_opinion[static_cast<std::size_t>(k)];
      TrackState& st = states[static_cast<std::size_t>(o.index)];
      const MatchSnapshot first = MatchSnapshot::of(st);
      const Warp w = warp_from_neighbours(o.deformation, st.birth, settings.main_match.shape);
      match_track(o.index, o.predicted, &w);
      const double tie = correlation_tie(first.match.zncc, st.subset, settings.main_match.prefilter_sigma_px);
      // A second match within the first's noise of it changes nothing worth recording.
      const bool elsewhere = beyond_noise(first.candidate, st.candidate, first.main.covariance_px2);
      if (st.matched && !st.suspect && elsewhere && st.match.zncc >= first.match.zncc - tie)
        adopted[static_cast<std::size_t>(k)] = 1;
      else
        first.restore(st);
    }
  });
  for (std::size_t k = 0; k < second_opinion.size(); ++k) {
    if (!adopted[k]) continue;
    tracks[static_cast<std::size_t>(second_opinion[k].index)].status = TrackStatus::kRecovered;
    ++stats.recovered;
  }
}

}  // namespace tirstrain::flow
