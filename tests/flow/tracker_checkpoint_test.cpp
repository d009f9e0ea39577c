// A tracker's checkpoint (FeatureTracker::checkpoint/restore): a tracker restored from the state another
// wrote after frame k continues exactly as that one does, bit for bit, on a Cattaneo–Mindlin trial with a
// plate band, sensor noise and births; a checkpoint that is cut short or from another build is refused.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "core/error.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "flow_support.hpp"

namespace tirstrain::flow {
namespace {

using testing::cm_scene;
using testing::config_of;
using testing::render;

struct CheckpointTrial {
  testing::RenderedTrial frames;
  std::vector<double> t_s;
  RoiPx band{0, 0, 220, 36};
};

CheckpointTrial make_checkpoint_trial() {
  YAML::Node root = cm_scene(220, 240, 16, 50.0);
  root["reference_pattern"]["roi_px"] = YAML::Load("[0, 0, 220, 36]");
  const samples::Trial trial(config_of(root));
  return {render(trial, true), trial.frame_times_s()};
}

bool same_bits_of(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Every field of every track, and the frame's statistics and plate, compared bit for bit.
void expect_identical_trackers(const FeatureTracker& a, const FeatureTracker& b, int frame) {
  ASSERT_EQ(a.tracks().size(), b.tracks().size()) << "frame " << frame;
  for (std::size_t k = 0; k < a.tracks().size(); ++k) {
    const Track& p = a.tracks()[k];
    const Track& q = b.tracks()[k];
    ASSERT_TRUE(
        same_bits_of(p.position_px.x, q.position_px.x) && same_bits_of(p.position_px.y, q.position_px.y) &&
        p.status == q.status && p.model == q.model && same_bits_of(p.zncc, q.zncc) &&
        same_bits_of(p.reference_px.x, q.reference_px.x) && same_bits_of(p.gradient.xx, q.gradient.xx) &&
        same_bits_of(p.covariance_px2[0], q.covariance_px2[0]))
        << "frame " << frame << ", track " << k;
  }
  EXPECT_EQ(a.stats().alive, b.stats().alive) << frame;
  EXPECT_EQ(a.stats().born, b.stats().born) << frame;
  EXPECT_EQ(a.stats().at_rest, b.stats().at_rest) << frame;
  EXPECT_EQ(a.stats().affine_fit, b.stats().affine_fit) << frame;
  ASSERT_EQ(a.plate_displacement_px().has_value(), b.plate_displacement_px().has_value());
  EXPECT_TRUE(same_bits_of(a.plate_displacement_px()->x, b.plate_displacement_px()->x)) << frame;
  EXPECT_TRUE(same_bits_of(a.plate_displacement_px()->y, b.plate_displacement_px()->y)) << frame;
}

TEST(TrackerCheckpoint, ARestoredTrackerContinuesBitForBit) {
  const CheckpointTrial run = make_checkpoint_trial();
  const TrackerOptions settings = preset_options("auto", SceneHints{});
  const auto& f = run.frames.frames;
  const cv::Mat& mask = run.frames.mask;
  for (const int k : {3, 9}) {  // during the load's first frames, and with newborns and the slip annulus
    FeatureTracker uninterrupted(settings, run.band);
    FeatureTracker first(settings, run.band);
    uninterrupted.start(f[0], mask, run.t_s[0]);
    first.start(f[0], mask, run.t_s[0]);
    for (int i = 1; i <= k; ++i) {
      uninterrupted.track(f[i], mask, run.t_s[i]);
      first.track(f[i], mask, run.t_s[i]);
    }
    const std::vector<char> snapshot = first.checkpoint();
    const std::size_t tracks_then = first.tracks().size();
    FeatureTracker resumed(settings, run.band);
    resumed.restore(snapshot);
    expect_identical_trackers(uninterrupted, resumed, k);
    for (int i = k + 1; i < static_cast<int>(f.size()); ++i) {
      uninterrupted.track(f[i], mask, run.t_s[i]);
      resumed.track(f[i], mask, run.t_s[i]);
      expect_identical_trackers(uninterrupted, resumed, i);
    }
    std::printf("[ measured ] checkpoint after frame %d: %zu bytes, %zu tracks then, %zu at the end\n", k,
                snapshot.size(), tracks_then, uninterrupted.tracks().size());
    EXPECT_GT(uninterrupted.tracks().size(), tracks_then) << "births after the checkpoint";
  }
}

// A checkpoint taken just after a frame whose band the plate could not match (here hidden: it bridges the
// frame on its last motion): the plate's LK runs from the last frame it matched, not the previous frame,
// and the restored tracker must run from the same one.
TEST(TrackerCheckpoint, ARestoredPlateRunsFromTheLastFrameItMatched) {
  const CheckpointTrial run = make_checkpoint_trial();
  const TrackerOptions settings = preset_options("auto", SceneHints{});
  std::vector<cv::Mat> f;
  for (const cv::Mat& frame : run.frames.frames) f.push_back(frame.clone());
  constexpr int kHidden = 5;
  const cv::Rect band(run.band.x, run.band.y, run.band.width, run.band.height);
  f[kHidden](band).setTo(cv::mean(f[kHidden](band)));
  const cv::Mat& mask = run.frames.mask;
  FeatureTracker uninterrupted(settings, run.band), first(settings, run.band);
  uninterrupted.start(f[0], mask, run.t_s[0]);
  first.start(f[0], mask, run.t_s[0]);
  for (int i = 1; i <= kHidden; ++i) {
    uninterrupted.track(f[i], mask, run.t_s[i]);
    first.track(f[i], mask, run.t_s[i]);
  }
  ASSERT_TRUE(first.plate_status().has_value());
  ASSERT_NE(*first.plate_status(), static_cast<std::int8_t>(PlateStatus::kMatched))
      << "the hidden band must not match";
  FeatureTracker resumed(settings, run.band);
  resumed.restore(first.checkpoint());
  for (int i = kHidden + 1; i < static_cast<int>(f.size()); ++i) {
    uninterrupted.track(f[i], mask, run.t_s[i]);
    resumed.track(f[i], mask, run.t_s[i]);
    expect_identical_trackers(uninterrupted, resumed, i);
  }
}

TEST(TrackerCheckpoint, ACheckpointCutShortOrFromAnotherBuildIsRefused) {
  const CheckpointTrial run = make_checkpoint_trial();
  const TrackerOptions settings = preset_options("auto", SceneHints{});
  FeatureTracker tracker(settings, run.band);
  tracker.start(run.frames.frames[0], run.frames.mask, run.t_s[0]);
  tracker.track(run.frames.frames[1], run.frames.mask, run.t_s[1]);
  std::vector<char> snapshot = tracker.checkpoint();
  FeatureTracker other(settings, run.band);
  std::vector<char> cut(snapshot.begin(), snapshot.begin() + static_cast<long>(snapshot.size() / 2));
  EXPECT_THROW(other.restore(cut), Error);
  std::vector<char> foreign = snapshot;
  foreign[12] ^= 0x5a;  // inside the build stamp ("tirstrain <version> …")
  EXPECT_THROW(other.restore(foreign), Error);
  std::vector<char> longer = snapshot;
  longer.push_back(0);
  EXPECT_THROW(other.restore(longer), Error);
}

}  // namespace
}  // namespace tirstrain::flow
