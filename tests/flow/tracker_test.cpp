// The feature tracker against synthetic trials with exact fields (samples/), small images so the whole
// set stays fast under AddressSanitizer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "flow_support.hpp"
#include "noise_texture.hpp"
#include "samples/generalisation.hpp"

namespace tirstrain::flow {
namespace {

using testing::cm_scene;
using testing::config_of;
using testing::render;
using testing::run_and_score;
using testing::Score;

TrackerOptions auto_settings() {
  return preset_options("auto", SceneHints{});
}

void print(const char* label, const Score& s) {
  std::printf(
      "[%s] tracks %d, samples %ld, rms %.4f px, max %.3f px, >1px %ld, born %d (rms %.3f, max %.3f), "
      "plate rms %.4f px, alive at end %d\n",
      label, s.tracks_started, s.samples, s.rms_px, s.max_px, s.wrong, s.born, s.birth_rms_px, s.birth_max_px,
      s.plate_rms_px, s.frame_alive.back());
}

YAML::Node rigid_scene(int frames, double tx, double ty, double rotation_deg) {
  YAML::Node root = cm_scene(160, 160, frames, 50.0);
  root["synthesis"]["loading"] = YAML::Load("{field: rigid}");
  root["synthesis"]["loading"]["translation_px"].push_back(tx);
  root["synthesis"]["loading"]["translation_px"].push_back(ty);
  root["synthesis"]["loading"]["rotation_deg"] = rotation_deg;
  return root;
}

YAML::Node with_plate(YAML::Node root, int band_px) {
  root["reference_pattern"]["roi_px"] = YAML::Load("[0, 0, 0, 0]");
  root["reference_pattern"]["roi_px"][2] = root["synthesis"]["image"]["width_px"].as<int>();
  root["reference_pattern"]["roi_px"][3] = band_px;
  return root;
}

// The small CM scene with the hard_heavy_noise scene's sensor (300 e⁻ full well, 8 bits): ridge SNR ≈ 2.
YAML::Node heavy_noise_scene(int frames) {
  YAML::Node root = cm_scene(200, 180, frames, 50.0);
  root["synthesis"]["sensor"] =
      YAML::Load("{full_well_electrons: 300, read_noise: 0.04, blur_sigma_px: 0.6}");
  root["synthesis"]["image"]["bit_depth"] = 8;
  return root;
}

struct BothRuns {
  Score automatic, paper;
};

BothRuns run_both(const YAML::Node& scene, bool sensor, bool plate) {
  const samples::Trial trial(config_of(scene));
  const auto frames = render(trial, sensor);
  BothRuns r;
  r.automatic = run_and_score(trial, frames, auto_settings(), plate);
  r.paper = run_and_score(trial, frames, preset_options("delhaye2016", SceneHints{}), plate);
  print("auto", r.automatic);
  print("delhaye2016", r.paper);
  return r;
}

// Tolerances: the targets where they are met; otherwise the measured value (Release, this commit)
// with headroom, marked "regression bound", so a change that makes things worse fails. Measured values
// are in the comments.

TEST(Tracker, RigidTranslationByHalfPixels) {
  // 6 frames ramping to (5.5, −2.5): every frame moves by (1.1, −0.5), the last frame by k + 0.5 overall.
  const BothRuns r = run_both(rigid_scene(6, 5.5, -2.5, 0.0), false, false);
  // Measured: auto 0.031 px RMS, max 0.24 px, none > 1 px (0.035 px before the resampled rounds, session
  // 10); delhaye2016 0.27 px RMS, max 0.75 px.
  EXPECT_EQ(r.automatic.wrong, 0);
  EXPECT_LT(r.automatic.rms_px, 0.05);  // the target
  EXPECT_LT(r.automatic.rms_px, r.paper.rms_px);
  EXPECT_GT(r.automatic.frame_alive.back(), 40);
}

TEST(Tracker, JumpOf25PxIsTrackedNotAliased) {
  // The second frame jumps by 25 px, more than one ridge period: the phase correlation of the contact
  // supplies the prediction; plain LK (delhaye2016) locks onto a neighbouring ridge.
  const BothRuns r = run_both(rigid_scene(2, 25.0, 0.0, 0.0), false, false);
  // Measured: auto 0.024 px RMS, max 0.09 px on 51 tracks.
  EXPECT_EQ(r.automatic.wrong, 0);
  EXPECT_LT(r.automatic.rms_px, 0.1);
  EXPECT_GE(r.automatic.frame_alive.back(), 30);
}

TEST(Tracker, MotionBlurFrameDoesNotBreakTracks) {
  YAML::Node root = rigid_scene(6, 5.5, -2.5, 0.0);
  root["synthesis"]["sensor"]["motion_blur_frames"] = YAML::Load("[3]");
  root["synthesis"]["sensor"]["motion_blur_exposure_s"] = 0.01;
  const BothRuns r = run_both(root, true, false);
  // Measured: auto 0.032 px RMS, none > 1 px.
  EXPECT_EQ(r.automatic.wrong, 0);
  EXPECT_LT(r.automatic.rms_px, 0.05);  // the target
}

TEST(Tracker, CattaneoMindlinAndPlate) {
  const BothRuns r = run_both(with_plate(cm_scene(200, 220, 12, 50.0), 40), false, true);
  // Measured: auto 0.045 px RMS, max 0.62 px, delhaye2016 0.59 px; plate 0.0049 px RMS.
  EXPECT_LT(r.automatic.rms_px, 0.05);  // the target
  EXPECT_LT(r.automatic.max_px, 0.65);  // regression bound
  EXPECT_EQ(r.automatic.wrong, 0);
  EXPECT_LT(r.automatic.rms_px, r.paper.rms_px);
  EXPECT_LT(r.automatic.plate_rms_px, 0.02);
  EXPECT_LT(r.automatic.plate_max_px, 0.05);
  // Newborn reference positions: measured 0.032 px RMS, max 0.057 px (target 0.2 px). Newborns whose skin
  // frame 0 saw are matched in frame 0 (exact X); on this scene all are.
  EXPECT_GT(r.automatic.born, 0);
  EXPECT_LT(r.automatic.birth_rms_px, 0.2);
}

TEST(Tracker, SmallContactKeepsEveryPixel) {
  // Fewer than 300 grid points, mostly border tracks whose own match counts: second order on every pixel,
  // and the rounds' translation steps on every pixel too.
  const samples::Trial trial(config_of(cm_scene(200, 220, 2, 50.0)));
  const auto frames = render(trial, true);
  FeatureTracker probe(auto_settings());
  probe.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_LT(probe.tracks().size(), 300u);
  EXPECT_EQ(probe.settings().main_match.shape, ShapeFunction::kQuadratic);
  EXPECT_EQ(probe.settings().main_match.subset_stride, 1);
  EXPECT_EQ(probe.settings().rounds.subset_stride, 1);
  EXPECT_EQ(probe.settings().main_match.period_frames, 1);
}

// 300×280 px, 10 frames, ≈ 500 grid points of contact: large enough for the resampled rounds.
YAML::Node large_contact_scene() {
  YAML::Node root = cm_scene(300, 280, 10, 50.0);
  root["synthesis"]["contact"]["normal_N"] = 2.1;
  return root;
}

TEST(Tracker, LargeContactSeedsTheResampledRoundsWithACheapMatch) {
  // A contact of ≈ 500 grid points (radius ≈ 100 px, ≈ 260 tracks inside the border margin): the automatic
  // preset's frame-0 tracks get their final positions from the resampled fixed-shape rounds, so the main
  // match only seeds them, affine on every 3rd pixel. It must lose nothing against the full second-order
  // match on every pixel.
  const samples::Trial trial(config_of(large_contact_scene()));
  const auto frames = render(trial, true);
  FeatureTracker probe(auto_settings());
  probe.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_FALSE(probe.low_snr_texture());
  EXPECT_EQ(probe.settings().main_match.shape, ShapeFunction::kAffine);
  EXPECT_EQ(probe.settings().main_match.subset_stride, 3);
  EXPECT_EQ(probe.settings().rounds.subset_stride, 2);
  EXPECT_GT(probe.tracks().size(), 200u);
  TrackerOptions full = auto_settings();
  full.main_match.shape = ShapeFunction::kQuadratic;
  full.main_match.subset_stride = 1;
  full.pinned.shape = full.pinned.subset_stride = true;
  TrackerOptions subset_by_subset = full;
  subset_by_subset.rounds.resampled = false;
  const Score cheap = run_and_score(trial, frames, auto_settings(), false);
  const Score second_order = run_and_score(trial, frames, full, false);
  const Score before = run_and_score(trial, frames, subset_by_subset, false);
  print("auto (affine seed, resampled rounds)", cheap);
  print("second-order seed, resampled rounds", second_order);
  print("second-order seed, rounds subset by subset", before);
  // Measured: 0.0127 px RMS (max 0.10 px) against 0.0166 px with the second-order seed and 0.0209 px with
  // the rounds subset by subset (max 0.35 px); none > 1 px.
  EXPECT_EQ(cheap.wrong, 0);
  EXPECT_LT(cheap.rms_px, 0.05);
  EXPECT_LT(cheap.rms_px, 1.05 * second_order.rms_px);
  EXPECT_LT(cheap.rms_px, 1.05 * before.rms_px);
}

TEST(Tracker, TracksThatSkipTheMainMatchLoseNothing) {
  // The contact of the test above. With main_match_period_frames 4 (the automatic preset) each interior
  // frame-0 track takes LK and the main match every 4th frame; in between it starts the resampled rounds
  // where its matched neighbours put them. Border tracks (a subset reaching out of the contact), newborns
  // and every track in frame 1 match every frame: on this small contact that is most of them.
  // Measured: 0.0127 px RMS (every 2nd frame 0.0124, every frame 0.0126), max 0.100 px each; 53 % and 66 %
  // of the track-frames matched.
  const samples::Trial trial(config_of(large_contact_scene()));
  const auto frames = render(trial, true);
  TrackerOptions every = auto_settings();
  every.main_match.period_frames = 1;
  every.pinned.main_match_period = true;
  TrackerOptions checkerboard = auto_settings();
  checkerboard.main_match.period_frames = 2;
  checkerboard.pinned.main_match_period = true;
  ASSERT_EQ(auto_settings().main_match.period_frames, 4);
  const Score quarter = run_and_score(trial, frames, auto_settings(), false);
  const Score half = run_and_score(trial, frames, checkerboard, false);
  const Score all = run_and_score(trial, frames, every, false);
  print("main match every 4th frame", quarter);
  print("main match every 2nd frame", half);
  print("main match every frame", all);
  std::printf("matched: %ld / %ld / %ld of %ld track-frames\n", quarter.main_matched, half.main_matched,
              all.main_matched, all.entering);
  EXPECT_EQ(all.main_matched, all.entering);
  EXPECT_LT(half.main_matched, 0.75 * static_cast<double>(half.entering));
  EXPECT_LT(quarter.main_matched, 0.85 * static_cast<double>(half.main_matched));
  EXPECT_GT(quarter.main_matched, 0.3 * static_cast<double>(quarter.entering));
  EXPECT_EQ(quarter.wrong, 0);
  EXPECT_EQ(half.wrong, 0);
  EXPECT_LT(quarter.rms_px, 1.1 * all.rms_px);
  EXPECT_LT(half.rms_px, 1.1 * all.rms_px);
  EXPECT_LT(quarter.max_px, 0.3);
}

TEST(Tracker, HeavyNoiseRoundsOverruleADisagreeingMainMatch) {
  // The shipped hard_heavy_noise scene (640x512, ridge SNR ≈ 2, 880 tracks), its first 20 frames. Where a
  // frame-0 track's main match and the resampled fixed-shape rounds disagree by more than the neighbour
  // tolerance, the rounds' answer (pinned by the neighbours' field) is taken. Keeping the main match, as
  // before, left 3 track-frames 1.0-1.55 px off here (and a border track 2.37 px off on paper_2N_5mm_s end
  // to end). Measured: 0.1328 px RMS, max 0.82 px, none > 1 px (before: 0.1351 px, max 1.55 px, 3 > 1 px).
  const Scene scene = load_scene(std::string(TIRSTRAIN_SOURCE_SCENES_DIR) + "/hard_heavy_noise.yaml");
  samples::SynthConfig config = samples::parse_synth_config(scene);
  config.timing.frames = 20;
  const samples::Trial trial(config);
  const auto frames = render(trial, true);
  const Score s = run_and_score(trial, frames, preset_options("auto", hints_from_scene(scene)), false);
  print("auto, hard_heavy_noise, 20 frames", s);
  EXPECT_GT(s.tracks_started, 800);
  EXPECT_EQ(s.wrong, 0);
  EXPECT_LT(s.max_px, 1.0);
  EXPECT_LT(s.rms_px, 0.14);  // regression bound
}

TEST(Tracker, AMatchLeftAlongItsRidgesIsMatchedAgainFromItsNeighbours) {
  // The shipped rigid_rotation scene (640x512, noise-free, 10° about the contact's centre over 60 frames),
  // its first 22 frames, tracked with the ridge period a scene-less run measures on it (23.88 px against
  // the scene's 23.4). At the top of the contact the skin slides along the border and along its ridges,
  // where a subset's cost hardly changes, so a border track's match started from its own last motion can
  // stay where it started and walk away from its neighbours until the neighbour tolerance (0.6 px) catches
  // it. A match beyond its own noise of the neighbours' prediction is matched again from that prediction
  // and the better fit kept. Measured: RMS 0.0007 px, max 0.021 px; without the second match 0.0021 px and
  // 0.051 px (end to end, with the contact stage's mask, 0.0065 px over the 60 frames and a cluster of
  // border tracks 0.1-0.26 px off).
  Scene scene = load_scene(std::string(TIRSTRAIN_SOURCE_SCENES_DIR) + "/rigid_rotation.yaml");
  scene.ridge_period_mm = 23.88 / scene.px_per_mm;
  const samples::Trial trial(samples::parse_synth_config(scene));
  testing::RenderedTrial frames;
  frames.mask = trial.contact_mask();
  for (int f = 0; f < 22; ++f) {
    cv::Mat u16;
    trial.render_clean(f).convertTo(u16, CV_16U, 65535.0);
    frames.frames.push_back(u16);
  }
  const Score s = run_and_score(trial, frames, preset_options("auto", hints_from_scene(scene)), false);
  print("auto, rigid_rotation, 22 frames, period 23.88 px", s);
  EXPECT_GT(s.tracks_started, 600);
  EXPECT_EQ(s.wrong, 0);
  EXPECT_LT(s.max_px, 0.035);
  EXPECT_LT(s.rms_px, 0.0012);
}

TEST(Tracker, PlateCrossingANarrowBandManyTimesDoesNotDrift) {
  // The plate moves across a 40 px band at ~5 px per frame (the band's height every 8 frames) with sensor
  // noise, 40 frames: every patch of pattern is in view for a few frames only. A reference that is
  // replaced whenever the pattern has left the band carries each replacement's error over (the shipped
  // default scene: 0.022 px RMS, growing to 0.03 px at the end; here 0.113 px RMS, 0.19 px at most); the
  // stitched, averaged mosaic does not (measured 0.0033 px RMS).
  YAML::Node root = with_plate(cm_scene(200, 180, 40, 50.0), 40);
  root["synthesis"]["loading"]["direction_deg"] = 270.0;
  root["synthesis"]["loading"]["plate_speed_mm_s"] = 5.0;
  const samples::Trial trial(config_of(root));
  const auto frames = render(trial, true);
  const Score s = run_and_score(trial, frames, auto_settings(), true);
  print("auto, plate across a 40 px band", s);
  const samples::LoadState last = trial.load(trial.frames() - 1);
  std::printf("plate travel %.1f px\n", std::hypot(last.plate_px.x, last.plate_px.y));
  EXPECT_GT(std::hypot(last.plate_px.x, last.plate_px.y), 150.0);
  EXPECT_LT(s.plate_rms_px, 0.02);
  EXPECT_LT(s.plate_max_px, 0.04);
}

TEST(Tracker, NoDriftOver300Frames) {
  // A small Cattaneo–Mindlin contact (radius ≈ 45 px) with sensor noise, sheared into gross slip within the
  // first few frames and then held there for 300 frames: from then on the skin's field no longer changes,
  // so any growth of the error is drift, not a harder field. Every refined track is matched against its
  // anchor frame, so the error must not grow like a random walk. Issue target: the error in the last frame
  // at most 1.5× that of frame 10. (A trial whose strain keeps growing to the end would mix the error's
  // growth with the strain's: measured on such a trial, the error rises from 0.034 px to 0.05–0.08 px as
  // the slip front passes, with no drift in the held frames.)
  YAML::Node root = cm_scene(120, 120, 300, 50.0);
  root["synthesis"]["contact"]["normal_N"] = 0.2;
  root["synthesis"]["loading"]["plate_speed_mm_s"] = 2.0;
  root["synthesis"]["sensor"] = YAML::Load("{full_well_electrons: 20000, read_noise: 0.004}");
  const samples::Trial trial(config_of(root));
  ASSERT_TRUE(trial.load(8).full_slip) << "the held part must start before frame 10";
  const auto frames = render(trial, true);
  const Score s = run_and_score(trial, frames, auto_settings(), false);
  print("auto, 300 frames", s);
  const double early = s.frame_rms_px[10], last = s.frame_rms_px.back();
  std::printf("frame 10: %.4f px, frame 299: %.4f px (%d alive)\n", early, last, s.frame_alive.back());
  EXPECT_GT(early, 0.0);
  EXPECT_LE(last, 1.5 * early);
  EXPECT_GT(s.frame_alive.back(), 20);
}

TEST(Tracker, NoisyTextureSwitchesToTheLowSnrSubsets) {
  // Heavy sensor noise (300 e⁻ full well, as the hard_heavy_noise scene): ridge SNR ≈ 2. Second-order
  // subsets wander along the ridges there and nearly every track is retired within a few frames; the
  // automatic preset measures the texture in frame 0 and matches smoothed, affine, larger subsets instead.
  YAML::Node root = heavy_noise_scene(12);
  const samples::Trial trial(config_of(root));
  const auto frames = render(trial, true);
  TrackerOptions fixed = auto_settings();
  fixed.texture.adapt = false;
  const Score adapted = run_and_score(trial, frames, auto_settings(), false);
  const Score unadapted = run_and_score(trial, frames, fixed, false);
  print("auto, noisy", adapted);
  print("auto without adaptation, noisy", unadapted);
  FeatureTracker probe(auto_settings());
  probe.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_TRUE(probe.low_snr_texture());
  EXPECT_LT(probe.texture().snr, 4.0);
  EXPECT_EQ(probe.settings().main_match.shape, ShapeFunction::kAffine);
  EXPECT_GT(probe.settings().main_match.prefilter_sigma_px, 1.5);
  EXPECT_EQ(probe.settings().fusion.sigma_px, 2.0 * auto_settings().seeding.grid_step_px);
  EXPECT_EQ(probe.settings().fusion.weight, 1.0);
  EXPECT_EQ(probe.settings().main_match.subset_stride, 2);  // smoothed by > 1.5 px: every 2nd pixel each way
  EXPECT_EQ(probe.settings().main_match.period_frames, 1);  // every track matched every frame
  // A pinned setting is kept.
  TrackerOptions pinned = auto_settings();
  pinned.main_match.shape = ShapeFunction::kQuadratic;
  pinned.pinned.shape = true;
  FeatureTracker kept(pinned);
  kept.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_TRUE(kept.low_snr_texture());
  EXPECT_EQ(kept.settings().main_match.shape, ShapeFunction::kQuadratic);
  EXPECT_GT(kept.settings().main_match.prefilter_sigma_px, 1.5);
  TrackerOptions pinned_fusion = auto_settings();
  pinned_fusion.pinned.fusion = true;
  FeatureTracker kept_fusion(pinned_fusion);
  kept_fusion.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_EQ(kept_fusion.settings().fusion.weight, auto_settings().fusion.weight);
  TrackerOptions pinned_stride = auto_settings();
  pinned_stride.main_match.subset_stride = 1;
  pinned_stride.pinned.subset_stride = true;
  FeatureTracker kept_stride(pinned_stride);
  kept_stride.start(frames.frames[0], frames.mask, 0.0);
  EXPECT_EQ(kept_stride.settings().main_match.subset_stride, 1);
  // Measured: adapted 0.23 px RMS (the noise floor of one subset here), 84 of 94 tracks alive at the end;
  // unadapted, every track is retired within the first frames (67 track-frames scored in all).
  EXPECT_GT(adapted.frame_alive.back(), 0.75 * adapted.tracks_started);
  EXPECT_GT(adapted.frame_alive.back(), unadapted.frame_alive.back());
  EXPECT_LT(adapted.rms_px, 0.3);
  EXPECT_LT(adapted.rms_px, unadapted.rms_px);
}

TEST(Tracker, AnchorIsAveragedWhileTheSkinRests) {
  // Every frame is matched against frame 0, so frame 0's noise is in every frame's error. Here the plate
  // waits 0.1 s (frames 1-5 at rest) before it moves ~1 px per frame: with the anchor averaged over those
  // six frames, the anchor's share of the noise falls by sqrt(6); the current frame's share stays, so the
  // error of the moving frames should fall to about sqrt((1 + 1/6) / 2) = 0.76 of the single-frame anchor's.
  YAML::Node root = heavy_noise_scene(14);
  root["synthesis"]["loading"]["shear_start_s"] = 0.1;
  const samples::Trial trial(config_of(root));
  const auto frames = render(trial, true);
  TrackerOptions single = auto_settings();
  single.rest.average_frames = 1;
  const Score averaged = run_and_score(trial, frames, auto_settings(), false);
  const Score plain = run_and_score(trial, frames, single, false);
  print("auto, anchor averaged at rest", averaged);
  print("auto, frame-0 anchor", plain);
  const auto moving_rms = [](const Score& s) {
    double sum2 = 0.0;
    for (std::size_t f = 6; f < s.frame_rms_px.size(); ++f) sum2 += s.frame_rms_px[f] * s.frame_rms_px[f];
    return std::sqrt(sum2 / static_cast<double>(s.frame_rms_px.size() - 6));
  };
  std::printf("moving frames: %.4f px averaged, %.4f px single (ratio %.3f)\n", moving_rms(averaged),
              moving_rms(plain), moving_rms(averaged) / moving_rms(plain));
  EXPECT_EQ(averaged.rest_frames_averaged, 5);
  EXPECT_EQ(plain.rest_frames_averaged, 0);
  EXPECT_EQ(averaged.rest_frames_on_fit, 5);
  EXPECT_EQ(plain.rest_frames_on_fit, 0);
  EXPECT_LT(moving_rms(averaged), 0.88 * moving_rms(plain));
  // At rest the tracks report the affine fit of their motion (known to ~σ_fit), not each subset's noise.
  const auto rest_rms = [](const Score& s) {
    double sum2 = 0.0;
    for (std::size_t f = 1; f < 6; ++f) sum2 += s.frame_rms_px[f] * s.frame_rms_px[f];
    return std::sqrt(sum2 / 5.0);
  };
  std::printf("rest frames: %.4f px averaged (the fit), %.4f px single\n", rest_rms(averaged),
              rest_rms(plain));
  // Measured: 0.081 px (the fit of 94 tracks, σ_fit ≈ 0.05-0.1 px here) against 0.165 px.
  EXPECT_LT(rest_rms(averaged), 0.6 * rest_rms(plain));
  // The anchor's mean stops growing at rest_average_frames; the rest motion is still reported after that.
  TrackerOptions capped = auto_settings();
  capped.rest.average_frames = 2;
  const Score short_mean = run_and_score(trial, frames, capped, false);
  EXPECT_EQ(short_mean.rest_frames_averaged, 1);
  EXPECT_EQ(short_mean.rest_frames_on_fit, 5);
  const auto late_rest_rms = [](const Score& s) {
    double sum2 = 0.0;
    for (std::size_t f = 3; f < 6; ++f) sum2 += s.frame_rms_px[f] * s.frame_rms_px[f];
    return std::sqrt(sum2 / 3.0);
  };
  // Measured, frames 3-5: 0.095 px (the fit, against an anchor of two frames) against 0.160 px.
  EXPECT_LT(late_rest_rms(short_mean), 0.75 * late_rest_rms(plain));

  // No rest: the plate moves from the first frame on, and nothing is averaged.
  root["synthesis"]["loading"]["shear_start_s"] = 0.0;
  const samples::Trial moving(config_of(root));
  const Score at_once = run_and_score(moving, render(moving, true), auto_settings(), false);
  EXPECT_EQ(at_once.rest_frames_averaged, 0);
}

TEST(Tracker, RotationOf4Degrees) {
  const BothRuns r = run_both(rigid_scene(6, 0.0, 0.0, 4.0), false, false);
  // Measured: auto 0.0051 px RMS, max 0.021 px; delhaye2016 1.48 px.
  EXPECT_EQ(r.automatic.wrong, 0);
  EXPECT_LT(r.automatic.rms_px, 0.05);
}

// Known limits, kept visible and bounded (docs/flow.md, "Status"): the issue asks that no live track be
// silently wrong by more than 1 px, and these two cases still break it for a few track-frames. 50 %
// stretch of a small contact: tracks 12 px inside the right border lag across their ridges by up to 1.4 px
// once a quarter of the stretch has carried the skin through the border's contrast fade (their neighbours,
// one-sided there, lag alike, so the neighbour check passes them and their fitted gradient is 0.12 instead
// of 0.25). Low contrast with noise: one track-frame of 1066. Regression bounds on the measured values.
TEST(Tracker, StretchOf50PercentIsTrackedOrRetiredNeverWrongByAPixel) {
  // The skin stretches by 50 % over 10 frames and carries tracks through the border band into the border.
  // Measured: auto 0.068 px RMS, max 0.71 px, none > 1 px (tracks retired once less than 60 % of their
  // subset is inside the contact; at 50 %: 0.150 px RMS, 4 of 725 track-frames 1.0-1.4 px off). The
  // fixed-shape rounds before the last stop at a 0.1 px step: with every round converged to 0.01 px, 0.091
  // px and max 0.95 px; with the last round loose too, one track 1.007 px off. delhaye2016 4.9 px RMS.
  YAML::Node stretch = cm_scene(160, 160, 11, 50.0);
  stretch["synthesis"]["loading"] =
      YAML::Load("{field: affine, translation_px: [0, 0], gradient: [0.5, 0, 0, 0]}");
  const BothRuns stretched = run_both(stretch, false, false);
  EXPECT_LT(stretched.automatic.rms_px, 0.12);
  EXPECT_LT(stretched.automatic.max_px, 1.0);
  EXPECT_EQ(stretched.automatic.wrong, 0);
  EXPECT_GT(stretched.automatic.samples, 650);  // retired honestly, not wholesale
  EXPECT_LT(stretched.automatic.rms_px, 0.1 * stretched.paper.rms_px);
}

TEST(TrackerKnownLimits, LowContrastStaysWithinItsMeasuredBounds) {
  YAML::Node noisy = cm_scene(200, 180, 12, 50.0);
  noisy["synthesis"]["sensor"] =
      YAML::Load("{full_well_electrons: 5000, read_noise: 0.01, blur_sigma_px: 0.8}");
  noisy["synthesis"]["fingerprint"]["ridge_contrast"] = 0.25;
  noisy["synthesis"]["image"]["bit_depth"] = 8;
  const BothRuns low_contrast = run_both(noisy, true, false);
  // Measured: auto 0.155 px RMS, max 1.50 px, 3 of 1041 > 1 px, 91 of 94 tracks alive; delhaye2016
  // 0.63 px.
  EXPECT_LT(low_contrast.automatic.rms_px, 0.2);
  EXPECT_LE(low_contrast.automatic.wrong, 4);
  EXPECT_LT(low_contrast.automatic.rms_px, low_contrast.paper.rms_px);
}

// A contact that grows (normal loading) while the skin deforms: skin the reference frame did not see gets
// tracks, their reference positions extrapolated from the neighbours' map and flagged as such. Speckle-like
// texture (smoothed noise), an affine field with a drift, the contact's radius 60 → 105 px over 10 frames.
TEST(Tracker, GrowingContactGetsTracksInItsNewAreaFlaggedAsExtrapolated) {
  const cv::Size size(260, 260);
  cv::Mat texture = testing::smoothed_noise(size, 5, 2.0);
  cv::normalize(texture, texture, 30.0, 220.0, cv::NORM_MINMAX);
  const cv::Point2d centre(130.0, 130.0);
  const int frames = 10;
  // x = centre + A_k (X − centre) + t_k.
  const auto field = [&](int k) {
    const double s = static_cast<double>(k) / (frames - 1);
    cv::Matx23d m(1.0 + 0.02 * s, 0.006 * s, 0.0, -0.004 * s, 1.0 - 0.015 * s, 0.0);
    m(0, 2) = centre.x + 3.0 * s - (m(0, 0) * centre.x + m(0, 1) * centre.y);
    m(1, 2) = centre.y - 1.5 * s - (m(1, 0) * centre.x + m(1, 1) * centre.y);
    return m;
  };
  const auto frame = [&](int k) {
    cv::Mat warped, u8;
    cv::warpAffine(texture, warped, field(k), size, cv::INTER_CUBIC, cv::BORDER_REFLECT);
    warped.convertTo(u8, CV_8U);
    return u8;
  };
  const auto radius_px = [&](int k) { return 60.0 + 5.0 * k; };
  const auto mask = [&](int k) {
    cv::Mat m(size, CV_8U, cv::Scalar(0));
    cv::circle(m, cv::Point(130, 130), static_cast<int>(radius_px(k)), cv::Scalar(255), cv::FILLED);
    return m;
  };
  TrackerOptions settings = auto_settings();
  settings.births.interval_frames = 1;
  FeatureTracker tracker(settings);
  tracker.start(frame(0), mask(0), 0.0);
  for (int k = 1; k < frames; ++k) tracker.track(frame(k), mask(k), 0.02 * k);

  // Reference positions against the exact inverse map, for the alive tracks.
  cv::Matx23d inverse;
  cv::invertAffineTransform(field(frames - 1), inverse);
  int extrapolated = 0, matched = 0, in_new_area = 0;
  double sum2_extrapolated = 0.0, sum2_matched = 0.0;
  for (const Track& t : tracker.tracks()) {
    if (!is_alive(t.status)) continue;
    const Vec2 x = t.position_px;
    const Vec2 X{inverse(0, 0) * x.x + inverse(0, 1) * x.y + inverse(0, 2),
                 inverse(1, 0) * x.x + inverse(1, 1) * x.y + inverse(1, 2)};
    const double e2 = std::pow(t.reference_px.x - X.x, 2) + std::pow(t.reference_px.y - X.y, 2);
    const double r_reference = std::hypot(X.x - centre.x, X.y - centre.y);
    if (r_reference > radius_px(0)) ++in_new_area;
    if (t.reference_extrapolated) {
      ++extrapolated;
      sum2_extrapolated += e2;
      // Only skin that frame 0 did not match is extrapolated: beyond its contact, or in the band along its
      // border where subsets are not matched (border_exclusion_px).
      EXPECT_GT(r_reference, radius_px(0) - tracker.settings().border.exclusion_px - 6.0) << "track " << t.id;
    } else {
      ++matched;
      sum2_matched += e2;
    }
  }
  const double rms_extrapolated = std::sqrt(sum2_extrapolated / std::max(1, extrapolated));
  const double rms_matched = std::sqrt(sum2_matched / std::max(1, matched));
  std::printf("alive %d: matched %d (X error rms %.3f px), extrapolated %d (rms %.3f px), in new area %d\n",
              matched + extrapolated, matched, rms_matched, extrapolated, rms_extrapolated, in_new_area);
  // Measured: 89 frame-0 tracks (X error 0.030 px RMS), 261 extrapolated (0.175 px RMS), 194 of them on
  // skin beyond frame 0's contact. The annulus 60-105 px is 2.1 times frame 0's disk: most tracks are new.
  EXPECT_GT(in_new_area, 150);
  EXPECT_GT(extrapolated, 200);
  // An affine map extrapolates exactly; what is left is the tracking noise of the neighbours it was fitted
  // to, passed on from one generation of births to the next (regression bound: the measured value + 40 %).
  EXPECT_LT(rms_extrapolated, 0.25);
  EXPECT_LT(rms_matched, 0.06);
}

struct AffineFitRun {
  FrameStats stats;
  int on_fit = 0;              // tracks whose model is the frame's affine fit
  double max_on_fit_d2 = 0.0;  // their largest Mahalanobis distance from their own match
  double rms_on_fit_px = 0.0;  // their error against the exact field
};

// Frame 0 and the first moving frame of a generalisation case (exact rendering, 0.5 % noise, test size),
// tracked with the automatic preset over the whole frame.
AffineFitRun track_first_moving_frame(samples::GeneralisationField field) {
  const samples::GeneralisationCase sequence(
      samples::generalisation_config(field, samples::GeneralisationTexture::kSpeckle, 0.005, true));
  FeatureTracker tracker(auto_settings());
  tracker.start(sequence.add_noise(sequence.render_clean(0), 0), cv::Mat(), 0.0);
  AffineFitRun r;
  r.stats = tracker.track(sequence.add_noise(sequence.render_clean(1), 1), cv::Mat(), 0.01);
  double sum2 = 0.0;
  for (const Track& t : tracker.tracks()) {
    if (!is_alive(t.status) || t.model != TrackModel::kAffineFit) continue;
    ++r.on_fit;
    r.max_on_fit_d2 = std::max(r.max_on_fit_d2, t.model_mahalanobis2);
    const Vec2 u = sequence.field(t.reference_px, 1).displacement_px;
    sum2 += std::pow(t.position_px.x - t.reference_px.x - u.x, 2) +
            std::pow(t.position_px.y - t.reference_px.y - u.y, 2);
  }
  if (r.on_fit > 0) r.rms_on_fit_px = std::sqrt(sum2 / r.on_fit);
  return r;
}

TEST(Tracker, ARigidShiftIsReportedOnTheFramesAffineFitAndFlagged) {
  // Every track that reports the fit is flagged with its distance from its own match, within the χ²(2)
  // bound, and counted in the frame's statistics. Measured: 267 of 267 tracks, χ²/dof 0.63, 0.0019 px.
  const AffineFitRun r = track_first_moving_frame(samples::GeneralisationField::kSubpixelShift);
  std::printf("[ measured ] %d of %d tracks on the fit, chi2/dof %.2f, RMS %.4f px\n", r.on_fit,
              r.stats.alive, r.stats.affine_chi2_per_dof, r.rms_on_fit_px);
  EXPECT_TRUE(r.stats.affine_tested);
  EXPECT_TRUE(r.stats.affine_fit);
  EXPECT_LE(r.stats.affine_chi2_per_dof, 1.5);
  EXPECT_EQ(r.on_fit, r.stats.on_affine_fit);
  EXPECT_GT(r.on_fit, 0.8 * r.stats.alive);
  EXPECT_LE(r.max_on_fit_d2, kModelShiftChi2);
  EXPECT_LT(r.rms_on_fit_px, 0.005);
}

TEST(Tracker, ANonAffineFieldOfATenthOfAPixelIsNotReportedOnTheAffineFit) {
  // The chirp, u_x = 0.1 px sin φ(x) with wavelengths from 200 to 10 px: the residuals about an affine fit
  // are the sine, several times the matches' noise and correlated between neighbours, so the matches stand.
  // Measured: χ²/dof 39.
  const AffineFitRun r = track_first_moving_frame(samples::GeneralisationField::kChirp);
  std::printf("[ measured ] chi2/dof %.2f, correlation z %.1f\n", r.stats.affine_chi2_per_dof,
              r.stats.affine_correlation_z);
  EXPECT_TRUE(r.stats.affine_tested);
  EXPECT_FALSE(r.stats.affine_fit);
  EXPECT_GT(r.stats.affine_chi2_per_dof, 3.0);
  EXPECT_EQ(r.on_fit, 0);
  EXPECT_EQ(r.stats.on_affine_fit, 0);
}

TEST(Tracker, RejectsFramesOfAnotherSize) {
  FeatureTracker tracker(auto_settings());
  tracker.start(cv::Mat(64, 64, CV_8U, cv::Scalar(100)), cv::Mat(), 0.0);
  EXPECT_THROW(tracker.track(cv::Mat(32, 64, CV_8U, cv::Scalar(100)), cv::Mat(), 0.1), Error);
  EXPECT_THROW(tracker.track(cv::Mat(64, 64, CV_8UC3), cv::Mat(), 0.1), Error);
}

}  // namespace
}  // namespace tirstrain::flow
