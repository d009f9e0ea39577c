// Prediction and the main match: each track's guess for this frame (its own motion, the global shift, its
// neighbours) and its subset matched there; tracks that skip this frame's main match start from their
// neighbours' field.
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

void FeatureTracker::Impl::match_track(int index, Vec2 guess, const Warp* initial) {
  TrackState& st = states[static_cast<std::size_t>(index)];
  if (initial) st.warp = *initial;
  const cv::Point c = st.subset.centre();
  st.warp.set_displacement_at(st.offset.x, st.offset.y,
                              {guess.x - c.x - st.offset.x, guess.y - c.y - st.offset.y});
  st.guess = guess;
  st.fixed_shape = false;
  st.match = st.subset.match(match_source(), match_mask, st.warp, settings.main_match.solver);
  const Vec2 u = st.warp.displacement_px(st.offset.x, st.offset.y);
  st.candidate = {c.x + st.offset.x + u.x, c.y + st.offset.y + u.y};
  st.matched = st.match.converged && st.match.zncc >= settings.main_match.min_zncc;
  const double moved = std::hypot(st.candidate.x - guess.x, st.candidate.y - guess.y);
  st.suspect = !st.matched || moved > settings.main_match.max_correction_px;
  if (st.matched) {
    const Mat2d a = Mat2d::Identity() + to_matrix(st.warp.gradient(st.offset.x, st.offset.y));
    st.deformation = a * st.birth;
    st.main_frame = frame;
    st.main.reference_px = tracks[static_cast<std::size_t>(index)].reference_px;
    st.main.position_px = st.candidate;
    st.main.covariance_px2 = predicted_match_covariance(
        st.match.zncc, st.subset.pixel_count(), st.subset.translation_information(),
        correlated_pixels(settings.main_match.prefilter_sigma_px, st.subset.stride()));
  }
}

void FeatureTracker::Impl::predict_and_match() {
  collect_alive();
  const Vec2 shift = global_jump_shift();
  choose_main_matches();
  const int n = static_cast<int>(schedule.to_match.size());
  lk.from.resize(static_cast<std::size_t>(n));
  lk.to.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const TrackState& st = states[static_cast<std::size_t>(schedule.to_match[static_cast<std::size_t>(k)])];
    lk.from[static_cast<std::size_t>(k)] = to_roi(st.previous);
    lk.to[static_cast<std::size_t>(k)] = to_roi(motion_guess(st, shift));
  }
  if (n > 0) {
    lk_forward();
    lk.back = lk.from;
    if (settings.refine)
      lk_backward_where_uncorroborated(shift);
    else
      lk_backward_all();
  }
  take_lk_guesses(shift);
  stats.main_matched = n;
  if (!settings.refine) return;
  match_from_lk_guesses(shift);
  if (!schedule.skipped.empty()) start_skipped_from_neighbours();
}

void FeatureTracker::Impl::collect_alive() {
  alive.clear();
  for (std::size_t i = 0; i < tracks.size(); ++i)
    if (is_alive(tracks[i].status)) alive.push_back(static_cast<int>(i));
}

// Prediction: each track's own last motion, unless the whole contact jumped. The jump is the global
// correlation's shift when it is well supported and further than a ridge's reach from the tracks' median
// motion; zero otherwise.
Vec2 FeatureTracker::Impl::global_jump_shift() {
  stats.global_jump = false;
  stats.global_shift_px = {};
  if (!settings.prediction.global_jump || alive.empty()) return {0.0, 0.0};
  high_pass(current_f, jump.current);
  if (!jump.correlation.has_reference() || jump.correlation.reference_size() != jump.current.size())
    return {0.0, 0.0};
  double response = 0.0;
  const cv::Point2d s =
      jump.correlation.correlate(jump.current, &response) * static_cast<double>(high_pass_factor());
  stats.global_shift_px = {s.x, s.y};
  scratch_x.clear();
  scratch_y.clear();
  for (int i : alive) {
    scratch_x.push_back(states[static_cast<std::size_t>(i)].velocity.x);
    scratch_y.push_back(states[static_cast<std::size_t>(i)].velocity.y);
  }
  const double vx = tirstrain::median_in_place(scratch_x), vy = tirstrain::median_in_place(scratch_y);
  if (response > 0.05 && std::hypot(s.x - vx, s.y - vy) > ridge_reach_px()) {
    stats.global_jump = true;
    return {s.x, s.y};
  }
  return {0.0, 0.0};
}

// Which tracks take this frame's main match (to_match) and which start from their neighbours (skipped).
void FeatureTracker::Impl::choose_main_matches() {
  schedule.to_match.clear();
  schedule.skipped.clear();
  schedule.skip.assign(states.size(), 0);
  for (int i : alive) {
    if (!stats.global_jump && skips_main_match(i)) {
      schedule.skip[static_cast<std::size_t>(i)] = 1;
      schedule.skipped.push_back(i);
    } else {
      schedule.to_match.push_back(i);
    }
  }
}

Vec2 FeatureTracker::Impl::motion_guess(const TrackState& st, Vec2 shift) const {
  const Vec2 motion = stats.global_jump ? shift : st.velocity;
  return {st.previous.x + motion.x, st.previous.y + motion.y};
}

cv::Point2f FeatureTracker::Impl::to_roi(Vec2 p) const {
  return cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y)) -
         cv::Point2f(static_cast<float>(roi.x), static_cast<float>(roi.y));
}

cv::TermCriteria FeatureTracker::Impl::lk_criteria() const {
  return {cv::TermCriteria::COUNT | cv::TermCriteria::EPS, settings.prediction.max_iterations,
          settings.prediction.epsilon_px};
}

void FeatureTracker::Impl::lk_forward() {
  cv::calcOpticalFlowPyrLK(previous_pyramid, current_pyramid, lk.from, lk.to, lk.status, lk.error,
                           cv::Size(settings.prediction.window_px, settings.prediction.window_px),
                           settings.prediction.pyramid_levels, lk_criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
}

void FeatureTracker::Impl::lk_backward_all() {
  cv::calcOpticalFlowPyrLK(current_pyramid, previous_pyramid, lk.to, lk.back, lk.back_status, lk.error,
                           cv::Size(settings.prediction.window_px, settings.prediction.window_px),
                           settings.prediction.pyramid_levels, lk_criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
}

// With refinement the backward pass checks only the forward answers that the track's own motion (or the
// global shift) does not corroborate: within forward_backward_px of that prediction, two independent
// estimates agree, and the subset match and the neighbour check follow anyway. A full backward pass costs
// an eighth of the tracker's time on a 640×512 trial.
void FeatureTracker::Impl::lk_backward_where_uncorroborated(Vec2 shift) {
  const auto n = lk.from.size();
  const cv::Point2f tl(static_cast<float>(roi.x), static_cast<float>(roi.y));
  lk.back_status.assign(n, 1);
  lk.check.clear();
  lk.back_from.clear();
  lk.back_to.clear();
  for (std::size_t kk = 0; kk < n; ++kk) {
    if (!lk.status[kk]) continue;
    const Vec2 predicted = motion_guess(states[static_cast<std::size_t>(schedule.to_match[kk])], shift);
    const double dx = lk.to[kk].x + tl.x - predicted.x;
    const double dy = lk.to[kk].y + tl.y - predicted.y;
    if (std::hypot(dx, dy) <= settings.prediction.forward_backward_px) continue;
    lk.check.push_back(static_cast<int>(kk));
    lk.back_from.push_back(lk.to[kk]);
    lk.back_to.push_back(lk.from[kk]);
  }
  if (lk.check.empty()) return;
  cv::calcOpticalFlowPyrLK(current_pyramid, previous_pyramid, lk.back_from, lk.back_to, lk.check_status,
                           lk.error, cv::Size(settings.prediction.window_px, settings.prediction.window_px),
                           settings.prediction.pyramid_levels, lk_criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t j = 0; j < lk.check.size(); ++j) {
    const auto kk = static_cast<std::size_t>(lk.check[j]);
    lk.back[kk] = lk.back_to[j];
    lk.back_status[kk] = lk.check_status[j];
  }
}

// Each matched track's guess: LK's answer where it passed the forward-backward check, its own motion
// otherwise. Without refinement a failed check retires the track (below, with the reason).
void FeatureTracker::Impl::take_lk_guesses(Vec2 shift) {
  const cv::Point2f tl(static_cast<float>(roi.x), static_cast<float>(roi.y));
  for (std::size_t kk = 0; kk < schedule.to_match.size(); ++kk) {
    TrackState& st = states[static_cast<std::size_t>(schedule.to_match[kk])];
    const double fb = std::hypot(lk.back[kk].x - lk.from[kk].x, lk.back[kk].y - lk.from[kk].y);
    st.lk_ok = lk.status[kk] && lk.back_status[kk] && fb <= settings.prediction.forward_backward_px;
    st.guess = st.lk_ok ? Vec2{lk.to[kk].x + tl.x, lk.to[kk].y + tl.y} : motion_guess(st, shift);
    st.candidate = st.guess;
    st.matched = st.lk_ok;
    st.suspect = false;
    if (!settings.refine && !st.lk_ok) st.suspect = true;
  }
}

// The main subset match from each LK guess. A failed LK guess is not the only start: the track's own
// motion may still be right, so a failed match from LK's guess is tried again from there.
void FeatureTracker::Impl::match_from_lk_guesses(Vec2 shift) {
  cv::parallel_for_(cv::Range(0, static_cast<int>(schedule.to_match.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const int index = schedule.to_match[static_cast<std::size_t>(k)];
      TrackState& st = states[static_cast<std::size_t>(index)];
      const Vec2 first = st.guess;
      match_track(index, first, nullptr);
      if (!st.suspect || !st.lk_ok) continue;
      const Vec2 second = motion_guess(st, shift);
      if (std::hypot(second.x - first.x, second.y - first.y) <= 0.5) continue;
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
  });
}

// A frame-0 track skips the main match in the frames where its class on the seeding lattice is not due
// (main_match_period_frames), once it has been matched at least once; tracks anchored later always match.
bool FeatureTracker::Impl::skips_main_match(int index) const {
  const int period = settings.main_match.period_frames;
  if (!settings.refine || !settings.rounds.enabled || !settings.rounds.resampled || period <= 1) return false;
  const TrackState& st = states[static_cast<std::size_t>(index)];
  const Track& t = tracks[static_cast<std::size_t>(index)];
  if (st.key != 0 || !st.exact_reference || t.born_frame + 1 >= frame) return false;
  // Border tracks (their last match had pixels outside the contact) always match: their neighbours lie on
  // one side, and started from them the rounds left more frame-to-frame jitter there (a noise-free 24-frame
  // trial smoothed in time: largest move 0.21 px, against 0.13 px matching every track and 0.15 px so).
  if (st.match.valid_fraction < 0.999) return false;
  const long ix = std::lround(t.reference_px.x / settings.seeding.grid_step_px);
  const long iy = std::lround(t.reference_px.y / settings.seeding.grid_step_px);
  const long lattice_class = period == 2 ? ((ix + iy) & 1) : ((ix & 1) + 2 * (iy & 1));
  return lattice_class != frame % period;
}

// Where a track that skipped the main match starts its rounds: the median of where its matched neighbours
// put it, each carrying its own position over by its deformation gradient (as the neighbour check does):
// the neighbours' matches this frame know the change of motion, which the track's own last motion does not.
// Too few matched neighbours: it takes the main match after all.
void FeatureTracker::Impl::start_skipped_from_neighbours() {
  for (int i : schedule.skipped) states[static_cast<std::size_t>(i)].matched = false;
  build_hash(true);
  retry.clear();
  for (int i : schedule.skipped) {
    TrackState& st = states[static_cast<std::size_t>(i)];
    // (No track skips on a frame with a global jump: its own motion is the prediction here.)
    const Vec2 own{st.previous.x + st.velocity.x, st.previous.y + st.velocity.y};
    gather_neighbours(own, settings.neighbours.radius_px, i);
    if (static_cast<int>(neighbours.size()) < settings.neighbours.min_count) {
      schedule.skip[static_cast<std::size_t>(i)] = 0;
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
    st.guess = {tirstrain::median_in_place(scratch_x), tirstrain::median_in_place(scratch_y)};
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
  for (int i : schedule.skipped) {
    const std::size_t ii = static_cast<std::size_t>(i);
    if (!schedule.skip[ii] || (!field.done.empty() && field.done[ii])) continue;
    if (!is_alive(tracks[ii].status)) continue;
    schedule.skip[ii] = 0;
    retry.push_back(i);
  }
  stats.main_matched += static_cast<int>(retry.size());
  match_from_guesses(retry);
}

}  // namespace tirstrain::flow
