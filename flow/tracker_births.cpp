// Births and retirement: the first frame's grid, new tracks where the contact has room for them, tracks
// retired with the reason, and each frame's results copied out to the public Track records.
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

// Where a track may start: border_margin_px inside the contact's border. The frame's edge is no contact
// border (cv::erode's default border does not erode), but a refined track's subset must fit inside the
// frame, so its centre stays its radius and the interpolation kernel's reach inside.
void FeatureTracker::Impl::build_birth_mask() {
  const int margin = static_cast<int>(std::ceil(settings.seeding.border_margin_px));
  cv::erode(mask, birth_mask,
            cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
  if (!settings.refine) return;
  const int edge =
      std::min({settings.main_match.subset_radius_px + 2, (size.width - 1) / 2, (size.height - 1) / 2});
  birth_mask.rowRange(0, edge).setTo(0);
  birth_mask.rowRange(size.height - edge, size.height).setTo(0);
  birth_mask.colRange(0, edge).setTo(0);
  birth_mask.colRange(size.width - edge, size.width).setTo(0);
}

void FeatureTracker::Impl::seed_grid() {
  build_birth_mask();
  min_eigenvalue_map(current_f(roi), settings.seeding.eigen_block_px, eigen, eigen_scratch);
  double largest = 0.0;
  cv::minMaxLoc(eigen, nullptr, &largest, nullptr, nullptr, birth_mask(roi));
  eigen_threshold = settings.seeding.min_eigen_quality * largest;
  struct Candidate {
    float strength;
    cv::Point p;
  };
  std::vector<Candidate> candidates;
  const double step = settings.seeding.grid_step_px;
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
  if (static_cast<int>(candidates.size()) > settings.seeding.max_features) {
    std::nth_element(candidates.begin(), candidates.begin() + settings.seeding.max_features, candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.strength > b.strength; });
    candidates.resize(static_cast<std::size_t>(settings.seeding.max_features));
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
  if (settings.main_match.shape == ShapeFunction::kTranslation) w.p[2] = w.p[3] = w.p[4] = w.p[5] = 0.0;
  match_track(index, guess, &w);
  if (!st.matched ||
      std::hypot(st.candidate.x - guess.x, st.candidate.y - guess.y) > settings.neighbours.tolerance_px) {
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
  const double step = settings.seeding.grid_step_px;
  const int cols = static_cast<int>((size.width - 1) / step) + 1,
            rows = static_cast<int>((size.height - 1) / step) + 1;
  int live = mark_taken_lattice(cols, rows);
  if (live >= settings.seeding.max_features) return;
  build_birth_mask();
  min_eigenvalue_map(current_f(roi), settings.seeding.eigen_block_px, eigen, eigen_scratch);
  build_hash(false);
  int key = -1;
  const double radius = std::max(settings.neighbours.radius_px, 2.5 * step);
  for (int lj = 0; lj < rows && live < settings.seeding.max_features; ++lj)
    for (int li = 0; li < cols && live < settings.seeding.max_features; ++li) {
      if (lattice_taken[static_cast<std::size_t>(lj) * static_cast<std::size_t>(cols) +
                        static_cast<std::size_t>(li)])
        continue;
      const cv::Point p(static_cast<int>(std::lround(li * step)), static_cast<int>(std::lround(lj * step)));
      if (!roi.contains(p) || !birth_mask.at<std::uint8_t>(p)) continue;
      if (eigen.at<float>(p - roi.tl()) < eigen_threshold) continue;
      const Vec2 x{static_cast<double>(p.x), static_cast<double>(p.y)};
      gather_neighbours(x, radius, -1);
      if (neighbours.size() < 4) continue;
      const std::optional<BirthMap> map = reference_map_at(x, radius);
      if (map && born_at(x, *map, key)) {
        ++live;
        ++stats.born;
      }
    }
  if (key >= 0 && keys[static_cast<std::size_t>(key)]->users == 0)
    keys[static_cast<std::size_t>(key)].reset();
}

// Marks the lattice points of the seeding grid that a live track is near; returns how many tracks live.
int FeatureTracker::Impl::mark_taken_lattice(int cols, int rows) {
  const double step = settings.seeding.grid_step_px;
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
  return live;
}

// Local fit of the map current → reference position around a newborn at `x` from the gathered neighbours,
// weighted towards the nearest; quadratic when the neighbours surround it, affine when they lie to one side
// (extrapolating a quadratic is unstable). None when the fit is ill-posed or implausible.
std::optional<FeatureTracker::Impl::BirthMap> FeatureTracker::Impl::reference_map_at(
    Vec2 x, double fit_radius) const {
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
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.rcond() < 1e-8) return std::nullopt;
  const Eigen::MatrixXd coef = ldlt.solve(aw.transpose() * b);
  BirthMap map;
  map.dX_dx << coef(1, 0) / fit_radius, coef(2, 0) / fit_radius, coef(1, 1) / fit_radius,
      coef(2, 1) / fit_radius;
  if (!(map.dX_dx.determinant() > 0.05) || !coef.allFinite()) return std::nullopt;
  map.reference = {coef(0, 0), coef(0, 1)};
  if (!within_neighbours_displacements(x, map.reference)) return std::nullopt;
  map.velocity = {velocity.x / wsum, velocity.y / wsum};
  return map;
}

// A plausible map stays within the neighbours' range of displacements (plus 2 px): an ill-posed fit to a
// few one-sided neighbours can put X anywhere.
bool FeatureTracker::Impl::within_neighbours_displacements(Vec2 x, Vec2 reference) const {
  double lo_x = 1e300, hi_x = -1e300, lo_y = 1e300, hi_y = -1e300;
  for (int j : neighbours) {
    const Vec2 q = states[static_cast<std::size_t>(j)].candidate;
    const Vec2 Xj = tracks[static_cast<std::size_t>(j)].reference_px;
    lo_x = std::min(lo_x, q.x - Xj.x);
    hi_x = std::max(hi_x, q.x - Xj.x);
    lo_y = std::min(lo_y, q.y - Xj.y);
    hi_y = std::max(hi_y, q.y - Xj.y);
  }
  const double ux = x.x - reference.x, uy = x.y - reference.y;
  return ux >= lo_x - 2.0 && ux <= hi_x + 2.0 && uy >= lo_y - 2.0 && uy <= hi_y + 2.0;
}

// A newborn at `x`: matched in frame 0 where frame 0 saw that skin, otherwise (where the contact grew, or
// with extrapolate_all_births) anchored to this frame with its reference extrapolated by `map` and flagged.
// `key`: this frame's key frame, made on the first extrapolated birth.
bool FeatureTracker::Impl::born_at(Vec2 x, const BirthMap& map, int& key) {
  if (settings.refine) {
    const FirstFrameBirth b = birth_from_first_frame(x, map.reference, map.dX_dx, map.velocity);
    if (b == FirstFrameBirth::kBorn) return true;
    // Skin that frame 0 saw but that does not match there is not born by extrapolation either.
    if (b != FirstFrameBirth::kNotSeen) return false;
    // Nor, by default, skin that slid into a contact that did not grow: its reference position would be an
    // extrapolation of the field past the contact border, about twice as far off as a newborn matched in
    // frame 0. Only where the contact grew is extrapolation the way. The test is against where frame 0
    // seeded, not its whole contact: a contact that grows carries its births across frame 0's border band
    // (seeded by neither frame 0 nor, unless extrapolated, by births), and a contact that does not grow has
    // no birth candidates in that band anyway.
    if (!settings.births.extrapolate_all && keys[0] && keys[0]->frame == 0 && inside_mask(first_seeded, x))
      return false;
  }
  if (key < 0) key = add_key_frame();
  if (!create_track(x, map.reference, map.dX_dx, map.velocity, key, TrackStatus::kBorn)) return false;
  tracks.back().reference_extrapolated = true;
  states.back().candidate = x;
  states.back().matched = true;
  return true;
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
    t.model_window_px = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const Eigen::Matrix2d& c = st.own.covariance_px2;
    t.covariance_px2 = st.own_valid ? std::array<double, 3>{c(0, 0), c(0, 1), c(1, 1)}
                                    : std::array<double, 3>{nan, nan, nan};
    if (st.own_valid && has_unmeasured_direction(c)) ++stats.unmeasured_direction;
    t.own_position_px = st.own_valid ? st.own.position_px : Vec2{nan, nan};
    if (settings.refine) {
      t.zncc = st.match.zncc;
      t.subset_inside_fraction = st.match.valid_fraction;
      const Mat2d h = st.deformation - Mat2d::Identity();
      t.gradient = {h(0, 0), h(0, 1), h(1, 0), h(1, 1)};
    }
  }
}

}  // namespace tirstrain::flow
