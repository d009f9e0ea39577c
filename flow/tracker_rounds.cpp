// The shape rounds: subsets matched again with the shape the neighbours' field gives them, either on a
// frame resampled through that field (resampled rounds) or subset by subset (fixed-shape rounds); and
// re-anchoring of unrefined tracks.
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

// Every trusted track is matched again for its translation alone, its subset's shape set to the smoothed
// shape of its neighbourhood: the deformation gradient F averaged over the neighbours (Gaussian weights,
// σ = one grid step) and carried into the track's anchor frame, the curvature averaged over the neighbours
// anchored in the same frame. Both are smooth fields that the neighbourhood pins down far better than one
// subset; with them fixed, the subset's noise no longer leaks into the along-ridge translation.
void FeatureTracker::Impl::fixed_shape_pass(bool last) {
  build_hash(true);
  retry.clear();
  shapes.resize(states.size());
  smoothed.resize(states.size());
  for (int i : alive) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
    if (!field.done.empty() && field.done[static_cast<std::size_t>(i)]) continue;
    // A track whose reference position is extrapolated keeps its own match: the rounds fit the field in
    // reference coordinates, where its extrapolation error would pull it (and, through the fits, its
    // newborn neighbours) a little further each frame, compounding from one generation of births to the next.
    if (tracks[static_cast<std::size_t>(i)].reference_extrapolated) continue;
    if (neighbourhood_shape(i, shapes[static_cast<std::size_t>(i)], smoothed[static_cast<std::size_t>(i)]))
      retry.push_back(i);
  }
  match_fixed_shapes(last);
}

// Weighted least-squares fit of the displacement u(X) = x − X of track i's neighbourhood, in reference
// coordinates scaled by the radius: quadratic when the neighbours are many and on two sides of the track or
// more, affine otherwise or where the quadratic fit is ill-posed. Two sides include a track on the border,
// whose neighbours fill a half-plane: its subset then follows the field's curvature across the slip annulus
// too. Gives the subset's warp with that shape (`shape`) and the fitted F (`f`); false where no fit holds.
bool FeatureTracker::Impl::neighbourhood_shape(int i, Warp& shape, Mat2d& f) {
  const TrackState& st = states[static_cast<std::size_t>(i)];
  const double sigma = settings.rounds.sigma_grid * settings.seeding.grid_step_px;
  const double radius = 2.0 * sigma;
  const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
  gather_neighbours(st.candidate, radius, -1);  // includes the track itself
  if (neighbours.size() < 6) return false;
  int quadrants = 0;
  for (int j : neighbours) {
    const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
    if (Xj.x != X.x || Xj.y != X.y) quadrants |= 1 << ((Xj.x >= X.x ? 1 : 0) + (Xj.y >= X.y ? 2 : 0));
  }
  const int bits = (quadrants & 1) + ((quadrants >> 1) & 1) + ((quadrants >> 2) & 1) + ((quadrants >> 3) & 1);
  int m = neighbours.size() >= 10 && bits >= 2 ? 6 : 3;
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 2> rhs = Eigen::Matrix<double, 6, 2>::Zero();
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
  const auto well_posed = [](const Eigen::LDLT<Eigen::MatrixXd>& fit) {
    return fit.info() == Eigen::Success && fit.isPositive() && fit.rcond() >= 1e-8;
  };
  Eigen::LDLT<Eigen::MatrixXd> ldlt(normal.topLeftCorner(m, m));
  if (!well_posed(ldlt) && m == 6) {  // e.g. neighbours along one line: the affine block may still hold
    m = 3;
    ldlt.compute(normal.topLeftCorner(m, m));
  }
  if (!well_posed(ldlt)) return false;
  const Eigen::MatrixXd coef = ldlt.solve(Eigen::MatrixXd(rhs.topRows(m)));
  if (!coef.allFinite()) return false;
  // du/dX in frame 0's coordinates; the subset's shape is in its anchor's: F_anchor = F · birth⁻¹ … the
  // birth map is identity for frame-0 tracks, and for the others it carries the gradient over.
  const double s1 = 1.0 / radius, s2 = 1.0 / (radius * radius);
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
  shape = w;
  return true;
}

// The translation-only matches of the tracks in `retry`, each with its neighbourhood's shape; an answer
// further than the neighbour tolerance from the track's current position is not taken.
void FeatureTracker::Impl::match_fixed_shapes(bool last) {
  MatchOptions options = settings.main_match.solver;
  options.translation_only = true;
  if (!last) options.convergence_px = std::max(options.convergence_px, settings.rounds.convergence_px);
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
      const MatchResult m = subset.match(match_source(), match_mask, w, options);
      if (!m.converged || m.zncc < settings.main_match.min_zncc) continue;
      const cv::Point c = st.subset.centre();
      const Vec2 u = w.displacement_px(st.offset.x, st.offset.y);
      const Vec2 p{c.x + st.offset.x + u.x, c.y + st.offset.y + u.y};
      if (std::hypot(p.x - st.candidate.x, p.y - st.candidate.y) > settings.neighbours.tolerance_px) continue;
      st.candidate = p;
      st.match = m;
      st.fixed_shape = true;
      // The fitted F is far less noisy than one subset's: it is what the fusion and the neighbour check
      // carry positions over with, and what the track reports.
      if (settings.rounds.smoothed_gradient) st.deformation = smoothed[static_cast<std::size_t>(i)];
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
  field.done.assign(states.size(), 0);
  if (keys.empty() || !keys[0] || keys[0]->frame != 0) return;
  const std::optional<cv::Rect> region = choose_resampled_tracks();
  if (!region) return;
  const std::size_t n = field.eligible.size();
  field.position.resize(states.size());
  field.match.assign(n, MatchResult{});
  field.moved.assign(n, 0.0);
  for (int i : field.eligible)
    field.position[static_cast<std::size_t>(i)] = states[static_cast<std::size_t>(i)].candidate;
  const PixelClasses lattices = resampled_lattices();
  for (int round = 0; round < settings.rounds.resampled_rounds; ++round) {
    resampled_round(*region, lattices);
    // The rounds are not iterated to their fixed point: where the fit passes a pattern that the subsets
    // average out (scales between the fit's σ and the subset's width) it amplifies the noise there, and a
    // few rounds (like the subset-by-subset passes' three) regularise it. Stop early only once nothing moves.
    if (*std::max_element(field.moved.begin(), field.moved.end()) < 1e-3) break;
  }
  take_resampled_answers();
}

// The tracks the resampled rounds move (`eligible`: frame-0 tracks with an exact reference) and those that
// only take part in the fit (`others`: anchored later, their reference positions frame 0's too, matched
// subset by subset); the region the field covers. None when too few tracks are eligible.
std::optional<cv::Rect> FeatureTracker::Impl::choose_resampled_tracks() {
  field.eligible.clear();
  field.others.clear();
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int i : alive) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    if (!is_alive(tracks[static_cast<std::size_t>(i)].status) || !st.matched || st.suspect) continue;
    if (st.key != 0 || !st.exact_reference) {
      field.others.push_back(i);
      continue;
    }
    field.eligible.push_back(i);
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    x0 = std::min(x0, X.x), y0 = std::min(y0, X.y), x1 = std::max(x1, X.x), y1 = std::max(y1, X.y);
  }
  if (field.eligible.size() < 6) return std::nullopt;
  // The field's nodes on the seeding lattice (multiples of fixed_shape_node_grid grid steps): there a
  // node's fit is that seeded track's own neighbourhood fit, as in the subset-by-subset rounds.
  const int reach = std::max(settings.main_match.subset_radius_px, settings.rounds.subset_radius_px) + 2;
  const double step = resampled_node_step_px();
  const int left = static_cast<int>(std::lround(std::max(0.0, std::floor((x0 - reach) / step)) * step));
  const int top = static_cast<int>(std::lround(std::max(0.0, std::floor((y0 - reach) / step)) * step));
  return cv::Rect(cv::Point(left, top), cv::Point(static_cast<int>(std::ceil(x1)) + reach + 1,
                                                  static_cast<int>(std::ceil(y1)) + reach + 1)) &
         cv::Rect(0, 0, size.width, size.height);
}

// The subsets read every stride-th pixel: only their lattices are resampled (one in four pixels at stride
// 2: the wide subsets sample the image's lattice). Every pixel when a subset has another stride.
PixelClasses FeatureTracker::Impl::resampled_lattices() const {
  PixelClasses lattices(settings.rounds.subset_stride);
  for (int i : field.eligible) {
    const TrackState& st = states[static_cast<std::size_t>(i)];
    const Subset& subset = st.wide.empty() ? st.subset : st.wide;
    if (subset.stride() != settings.rounds.subset_stride) return PixelClasses();
    lattices.add(subset.centre().x + subset.first_offset().x, subset.centre().y + subset.first_offset().y);
  }
  return lattices;
}

// One round: the field fitted to the tracks' current answers, the frame resampled through it, and each
// eligible track moved by one translation step of its subset.
void FeatureTracker::Impl::resampled_round(const cv::Rect& region, const PixelClasses& lattices) {
  field.anchor.clear();
  field.displacement.clear();
  for (int i : field.eligible) {
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    const Vec2 x = field.position[static_cast<std::size_t>(i)];
    field.anchor.push_back(X);
    field.displacement.push_back({x.x - X.x, x.y - X.y});
  }
  for (int i : field.others) {
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    const Vec2 x = states[static_cast<std::size_t>(i)].candidate;
    field.anchor.push_back(X);
    field.displacement.push_back({x.x - X.x, x.y - X.y});
  }
  field.shape.fit(field.anchor, field.displacement, region, resampled_node_step_px(),
                  settings.rounds.sigma_grid * settings.seeding.grid_step_px);
  resample_through(match_source(), match_mask, field.shape, keys[0]->anchor.mask(), region, field.frame,
                   field.valid, lattices, settings.main_match.solver.interpolation);
  field.window_sums.build(keys[0]->anchor, field.frame, field.valid, region, settings.rounds.subset_stride,
                          lattices);
  cv::parallel_for_(cv::Range(0, static_cast<int>(field.eligible.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int i = field.eligible[static_cast<std::size_t>(k)];
      const TrackState& st = states[static_cast<std::size_t>(i)];
      const Subset& subset = st.wide.empty() ? st.subset : st.wide;
      Vec2 step;
      MatchResult& m = field.match[static_cast<std::size_t>(k)];
      m = subset.translation_step(field.window_sums, keys[0]->anchor, field.frame, field.valid,
                                  settings.main_match.solver.min_valid_fraction, step);
      field.moved[static_cast<std::size_t>(k)] = 0.0;
      if (!m.converged) continue;
      const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
      const Vec2 q{X.x - step.x, X.y - step.y};
      Vec2 u;
      if (!field.shape.displacement(q.x, q.y, u)) {
        m.converged = false;
        continue;
      }
      Vec2& x = field.position[static_cast<std::size_t>(i)];
      const Vec2 p{q.x + u.x, q.y + u.y};
      field.moved[static_cast<std::size_t>(k)] = std::hypot(p.x - x.x, p.y - x.y);
      x = p;
    }
  });
}

// The rounds' answers become the tracks' positions, taken even where they are further than the neighbour
// tolerance from the main match: the rounds' answer is pinned by the neighbours' field, the main match by
// one subset, and where they disagree the main match is the wrong one far more often (the neighbour check
// would otherwise catch a wrong border track only a frame later).
void FeatureTracker::Impl::take_resampled_answers() {
  for (std::size_t k = 0; k < field.eligible.size(); ++k) {
    const int i = field.eligible[k];
    TrackState& st = states[static_cast<std::size_t>(i)];
    const MatchResult& m = field.match[k];
    if (!m.converged || m.zncc < settings.main_match.min_zncc) continue;
    const Vec2 p = field.position[static_cast<std::size_t>(i)];
    const Vec2 X = tracks[static_cast<std::size_t>(i)].reference_px;
    Vec2 u;
    Mat2d gradient;
    if (!field.shape.displacement(X.x, X.y, u, &gradient)) continue;
    st.candidate = p;
    st.match = m;
    st.fixed_shape = true;
    if (settings.rounds.smoothed_gradient) st.deformation = Mat2d::Identity() + gradient;
    st.fixed_information = (st.wide.empty() ? st.subset : st.wide).fixed_shape_information();
    field.done[static_cast<std::size_t>(i)] = 1;
  }
}

// Unrefined tracks only: LK from each anchor frame straight to the current frame, started at the chained
// estimate. Where both agree, the anchored result replaces the chained one, so the random walk of
// frame-to-frame chaining is reset every few frames instead of growing over the whole trial.
void FeatureTracker::Impl::reanchor() {
  const cv::Size window(settings.prediction.window_px, settings.prediction.window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                              settings.prediction.max_iterations, settings.prediction.epsilon_px);
  const cv::Point2f tl(static_cast<float>(roi.x), static_cast<float>(roi.y));
  for (std::size_t k = 0; k < keys.size(); ++k) {
    if (!keys[k] || keys[k]->users == 0 || keys[k]->frame == frame) continue;
    retry.clear();
    lk.from.clear();
    lk.to.clear();
    for (int i : alive) {
      const TrackState& st = states[static_cast<std::size_t>(i)];
      if (st.key != static_cast<int>(k) || !is_alive(tracks[static_cast<std::size_t>(i)].status) ||
          st.suspect)
        continue;
      retry.push_back(i);
      lk.from.push_back(
          cv::Point2f(static_cast<float>(st.anchor_point.x), static_cast<float>(st.anchor_point.y)) - tl);
      lk.to.push_back(cv::Point2f(static_cast<float>(st.candidate.x), static_cast<float>(st.candidate.y)) -
                      tl);
    }
    if (retry.empty()) continue;
    build_pyramid(keys[k]->image_u8, anchor_pyramid);
    cv::calcOpticalFlowPyrLK(anchor_pyramid, current_pyramid, lk.from, lk.to, lk.status, lk.error, window,
                             settings.prediction.pyramid_levels, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    for (std::size_t n = 0; n < retry.size(); ++n) {
      TrackState& st = states[static_cast<std::size_t>(retry[n])];
      const Vec2 anchored{lk.to[n].x + tl.x, lk.to[n].y + tl.y};
      if (lk.status[n] && std::hypot(anchored.x - st.candidate.x, anchored.y - st.candidate.y) <=
                              settings.reanchor.tolerance_px)
        st.candidate = anchored;
    }
  }
}

}  // namespace tirstrain::flow
