// The tracker's state in a checkpoint (core/archive.hpp), so that an interrupted run continues exactly
// where it stopped: everything a later frame reads (settings as adapted, tracks and their subsets and
// warps, key frames, the rest anchor, the previous frame and its high-pass, the plate) and nothing that
// each frame rebuilds before use (masks, pyramids of the current frame, scratch).
#include <opencv2/video/tracking.hpp>

#include "core/archive.hpp"
#include "flow/detail/eigen_archive.hpp"
#include "flow/detail/tracker_impl.hpp"

namespace tirstrain::flow {

void archive(Archive& a, TrackerOptions& s) {
  a.layout(sizeof(TrackerOptions), "tracker settings");
  a(s.preset, s.refine, s.ridge_period_px, s.seeding, s.births, s.border, s.prediction, s.main_match,
    s.rounds, s.neighbours, s.fusion, s.local_fit, s.affine_fit, s.reanchor, s.rest, s.smoothing.mode,
    s.smoothing.gamma, s.plate, s.texture, s.pinned);
}

void archive(Archive& a, OwnMatch& m) {
  a(m.reference_px, m.position_px, m.covariance_px2);
}

namespace tracker_detail {

void archive(Archive& a, KeyFrame& k) {
  a(k.frame, k.anchor, k.image_u8, k.users);
}

void archive(Archive& a, TrackState& s) {
  a(s.key, s.subset, s.wide, s.warp, s.offset, s.birth, s.deformation, s.velocity, s.previous, s.guess,
    s.candidate, s.anchor_point, s.lk_ok, s.matched, s.suspect, s.fixed_shape, s.exact_reference,
    s.fixed_information, s.match, s.main_frame, s.main, s.own_valid, s.own, s.model, s.model_mahalanobis2);
}

}  // namespace tracker_detail

void FeatureTracker::Impl::archive(Archive& a) {
  Impl& m = *this;
  a.layout(sizeof(Track), "track");
  a.layout(sizeof(FrameStats), "frame statistics");
  a.layout(sizeof(TextureQuality), "texture");
  a.layout(sizeof(MatchResult), "match");
  a(m.settings, m.plate_roi, m.plate, m.tracks, m.states, m.keys, m.stats, m.frame, m.points_mode, m.size,
    m.eigen_threshold, m.first_seeded, m.full_scale, m.previous_u8, m.texture, m.low_snr, m.sizing, m.roi,
    m.jump.previous, m.jump.correlation, m.rest.active, m.rest.sum, m.rest.mask, m.rest.count);
}

void FeatureTracker::archive(Archive& a) {
  Impl& m = *impl_;
  if (!a.reading() && m.frame < 0) throw Error("FeatureTracker: a checkpoint asked for before start");
  m.archive(a);
  if (!a.reading()) return;
  // The previous frame's pyramids are built again from the frame they were cut from (LK reads past a
  // level's edge into it).
  if (!m.previous_u8.empty()) m.build_pyramid(m.previous_u8, m.previous_pyramid);
  if (m.plate) m.plate->rebuild_previous_pyramid();
}

std::vector<char> FeatureTracker::checkpoint() const {
  Archive a = Archive::for_writing();
  // Writing reads the state only.
  const_cast<FeatureTracker&>(*this).archive(a);
  return a.bytes();
}

void FeatureTracker::restore(const std::vector<char>& snapshot) {
  Archive a = Archive::for_reading(snapshot);
  archive(a);
  a.expect_end();
}

}  // namespace tirstrain::flow
