// The channels stage on synthesised trials (samples/, rendered in process: only the load history and the
// channels are needed, no images): friction, events and external work against the load history computed
// from the scene; resampled channels against direct evaluation; the three clock alignments recovering a
// known offset; bad channel files and scene sections named by file, row, column or key.
#include <gtest/gtest.h>
#include <matio.h>
#include <sys/wait.h>
#include <yaml-cpp/yaml.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <tuple>

#include "capture/frame_source.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "model/cattaneo_mindlin.hpp"
#include "pipeline/channels_stage.hpp"
#include "samples/trial.hpp"
#include "signals/channels.hpp"
#include "tests/signals/synthetic_recording.hpp"
#include "tests/support/expect_error.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

constexpr double kMu = 0.8, kNormal_N = 1.0, kRadius_m = 0.01, kSpeed_m_s = 5e-3, kShearStart_s = 0.2;

fs::path scratch(const std::string& name) {
  return testing::scratch_dir("pipeline_channels", name);
}

// A 1 s trial at 100 fps: at rest until 0.2 s, then the plate moves distally (-y) at 5 mm/s; full slip
// after about 73 ms. Channels at 1 kHz.
samples::Trial make_trial(double normal_noise_N, double tangential_noise_N, double jitter_s) {
  YAML::Node root = YAML::Load(R"(
calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
synthesis:
  seed: 5
  image: {width_px: 64, height_px: 64, bit_depth: 8}
  timing: {frames: 100, frame_rate_hz: 100}
  contact: {shape: hertz, normal_N: 1.0, radius_m: 0.01}
  loading: {field: cattaneo_mindlin, friction: 0.8, direction_deg: 270, plate_speed_mm_s: 5.0,
            shear_start_s: 0.2}
  channels: {rate_hz: 1000}
)");
  root["synthesis"]["timing"]["jitter_s"] = jitter_s;
  root["synthesis"]["channels"]["normal_noise_N"] = normal_noise_N;
  root["synthesis"]["channels"]["tangential_noise_N"] = tangential_noise_N;
  return samples::Trial(samples::parse_synth_config(parse_scene_text(YAML::Dump(root), "trial.yaml")));
}

// The load history from the scene alone: Mindlin's limit displacement at Q = μP, the 90 % point where
// Q = μP[1 − (1 − d/δ)^{3/2}] = 0.9 μP, and U_ext = ∫Q dd from 0 to that point.
struct Expected {
  double delta_max_m, t90_s, slip_s, external_J;
};
Expected expected_history() {
  model::CattaneoMindlinParams p;
  p.normal_N = kNormal_N;
  p.tangential_N = kMu * kNormal_N;
  p.radius_m = kRadius_m;
  p.young_Pa = 1.0e6;
  p.poisson = 0.4;
  p.friction = kMu;
  const double delta = model::CattaneoMindlin(p).rigid_shift_m();
  const double d90 = delta * (1.0 - std::pow(0.1, 2.0 / 3.0));
  const double work = kMu * kNormal_N * (d90 - 0.4 * delta * (1.0 - std::pow(0.1, 5.0 / 3.0)));
  return {delta, kShearStart_s + d90 / kSpeed_m_s, kShearStart_s + delta / kSpeed_m_s, work};
}

// Writes the trial's channels with the channel clock `clock_offset_s` behind the camera
// (t_channel = t_camera − offset), optionally a trigger pulse rising at camera time `trigger_camera_s`.
std::string write_channels(const samples::Trial& trial, const fs::path& dir, double clock_offset_s,
                           std::optional<double> trigger_camera_s = {}) {
  const samples::ChannelSeries s = trial.channels();
  std::vector<std::string> names = {"t_s",        "normal_N",   "tangential_N",
                                    "plate_x_mm", "plate_y_mm", "accel_m_s2"};
  if (trigger_camera_s) names.push_back("trigger_V");
  const std::string path = (dir / "channels.csv").string();
  CsvWriter out(path, names);
  for (std::size_t i = 0; i < s.t_s.size(); ++i) {
    std::vector<double> row = {s.t_s[i] - clock_offset_s, s.normal_N[i],   s.tangential_N[i],
                               s.plate_x_mm[i],           s.plate_y_mm[i], s.accel_m_s2[i]};
    if (trigger_camera_s) row.push_back(s.t_s[i] >= *trigger_camera_s ? 5.0 : 0.0);
    out.row(row);
  }
  out.commit();
  return path;
}

// A scene in `dir` whose channels section is `channels_yaml`; the channel file is named relative to it.
Scene channels_scene(const fs::path& dir, const std::string& channels_yaml) {
  YAML::Node root;
  root["compute"].push_back("channels");
  root["channels"] = YAML::Load(channels_yaml);
  return parse_scene_text(YAML::Dump(root), (dir / "scene.yaml").string());
}

constexpr const char* kColumns =
    "columns: {normal_force: normal_N, tangential_force: tangential_N, plate_position_x: plate_x_mm, "
    "plate_position_y: plate_y_mm, accelerometer: accel_m_s2}";

struct StageRun {
  std::unique_ptr<Stage> stage;
  std::string h5_path;
  nlohmann::json summary;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

// Feeds every frame of the trial to the stage as the pipeline would: device times, the tracking stage's
// plate displacement (truth + `plate_noise_px`) and, when given, the strain stage's energy.
StageRun run_stage(const Scene& scene, const samples::Trial& trial, const fs::path& dir,
                   double plate_noise_px,
                   const std::function<std::optional<double>(int, double)>& energy_J = {}) {
  StageRun run;
  run.stage = make_channels_stage(scene);
  run.stage->start(TrialInfo{cv::Size(trial.width(), trial.height()), CV_8U, trial.frames(), &scene});
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, plate_noise_px);
  for (int k = 0; k < trial.frames(); ++k) {
    capture::Frame frame;
    frame.index = k;
    frame.device_time_s = trial.frame_times_s()[static_cast<std::size_t>(k)];
    FrameContext context;
    context.frame = &frame;
    context.usable = true;
    const Vec2 plate = trial.load(k).plate_px;
    context.plate_displacement_px = Vec2{plate.x + (plate_noise_px > 0 ? noise(rng) : 0.0),
                                         plate.y + (plate_noise_px > 0 ? noise(rng) : 0.0)};
    if (energy_J) context.strain_energy_J = energy_J(k, frame.device_time_s);
    run.stage->process(context);
  }
  run.header = run.stage->csv_header();
  for (int k = 0; k < trial.frames(); ++k) {
    std::vector<std::string> cells;
    run.stage->csv_row(static_cast<std::size_t>(k), cells);
    run.rows.push_back(cells);
  }
  run.stage->summarize(run.summary);
  run.h5_path = (dir / "result.h5").string();
  H5Stream out(run.h5_path);
  run.stage->write(out);
  out.commit();
  return run;
}

double scalar(const H5Reader& h5, const std::string& name) {
  const auto v = h5.read_doubles(name);
  EXPECT_EQ(v.size(), 1u) << name;
  return v.empty() ? std::nan("") : v.front();
}

using tirstrain::testing::expect_error;

TEST(ChannelsStage, FrictionEventsAndWorkMatchTheLoadHistory) {
  // Force noise 10 mN (normal) and 5 mN (tangential), as a lab's force plate.
  const samples::Trial trial = make_trial(0.01, 0.005, 0.0);
  const fs::path dir = scratch("history");
  write_channels(trial, dir, 0.0);
  const Scene scene = channels_scene(dir, std::string("{file: channels.csv, ") + kColumns + "}");
  // Strain energy that grows linearly from the onset (so its interpolation at t90 is exact), absent in
  // every fifth frame as when the strain stage skips one.
  const auto energy = [](int k, double t) -> std::optional<double> {
    if (k % 5 == 4) return std::nullopt;
    return 2e-5 * std::max(0.0, t - kShearStart_s);
  };
  const StageRun run = run_stage(scene, trial, dir, 0.0, energy);
  const Expected truth = expected_history();
  H5Reader h5(run.h5_path);

  const double mu_dynamic = scalar(h5, "/friction/mu_dynamic");
  const double onset_s = scalar(h5, "/events/onset_s"), t90_s = scalar(h5, "/events/t90_s");
  const double slip_s = scalar(h5, "/events/full_slip_s"), work_J = scalar(h5, "/work/external_J");
  std::printf(
      "[ measured ] mu_dynamic %.5f (scene %.2f); onset %.4f s; t90 %.5f s (history %.5f); full slip "
      "%.4f s (history %.4f); U_ext %.4e J (history %.4e, %+.2f %%)\n",
      mu_dynamic, kMu, onset_s, t90_s, truth.t90_s, slip_s, truth.slip_s, work_J, truth.external_J,
      100.0 * (work_J / truth.external_J - 1.0));
  // μ noise per sample ≈ 0.011; the plateau mean over ~700 samples has a standard error ≈ 4e-4.
  EXPECT_NEAR(mu_dynamic, kMu, 2e-3);
  // The plate position is noise-free: the onset is the last sample at rest, the stroke's start.
  EXPECT_NEAR(onset_s, kShearStart_s, 1e-9);
  // Q rises at ≈ 7.7 N/s through the 90 % point: 5 mN noise moves the crossing by ≈ 0.7 ms.
  EXPECT_NEAR(t90_s, truth.t90_s, 2e-3);
  // Full slip is detected where Q is within 1 % of the plateau (≈ 95 % of Mindlin's slip distance).
  EXPECT_GT(slip_s, t90_s);
  EXPECT_LE(slip_s, truth.slip_s + 1e-3);
  EXPECT_NEAR(work_J / truth.external_J, 1.0, 0.02);
  // Frame indices: the first frame at or after the event (frames every 10 ms from 0).
  const auto onset_frame = h5.read_integers("/events/onset_frame");
  const auto t90_frame = h5.read_integers("/events/t90_frame");
  EXPECT_EQ(onset_frame.at(0), 20);
  EXPECT_EQ(t90_frame.at(0), static_cast<std::int64_t>(std::ceil(t90_s / 0.01 - 1e-9)));

  // U/U_ext: U interpolated at t90 between frames with energy.
  const double u_t90 = scalar(h5, "/work/strain_energy_at_t90_J");
  EXPECT_NEAR(u_t90, 2e-5 * (t90_s - kShearStart_s), 1e-15);
  EXPECT_NEAR(scalar(h5, "/work/energy_ratio"), u_t90 / work_J, 1e-12);

  // μ at frames: F_t/W of the channels resampled at the frame times, valid wherever W ≥ 0.05 N.
  const auto mu = h5.read_doubles("/friction/mu");
  const auto valid = h5.read_integers("/friction/valid");
  const auto ft = h5.read_doubles("/channels/at_frames/tangential_force_N");
  const auto w = h5.read_doubles("/channels/at_frames/normal_force_N");
  ASSERT_EQ(mu.size(), 100u);
  double plateau_mu = 0.0;
  int plateau_frames = 0;
  for (std::size_t k = 0; k < mu.size(); ++k) {
    EXPECT_EQ(valid[k], 1);
    EXPECT_NEAR(mu[k], ft[k] / w[k], 1e-12);
    if (trial.load(static_cast<int>(k)).full_slip) {
      plateau_mu += mu[k];
      ++plateau_frames;
    }
  }
  EXPECT_NEAR(plateau_mu / plateau_frames, kMu, 5e-3);  // ~72 frames, σ ≈ 0.011 each

  // Cumulative external work at frames reaches U_ext at the 90 % point.
  const auto cumulative = h5.read_doubles("/work/external_cumulative_J");
  const auto t90_k = static_cast<std::size_t>(t90_frame.at(0));
  EXPECT_EQ(cumulative[19], 0.0);
  EXPECT_GE(cumulative[t90_k], work_J);
  EXPECT_LT(cumulative[t90_k - 1], work_J);

  // summary.json carries the same scalars and the offset used.
  const auto& c = run.summary.at("channels");
  EXPECT_EQ(c.at("alignment").at("method"), "explicit");
  EXPECT_EQ(c.at("alignment").at("offset_s"), 0.0);
  EXPECT_DOUBLE_EQ(c.at("mu_dynamic").get<double>(), mu_dynamic);
  EXPECT_DOUBLE_EQ(c.at("events").at("t90_s").get<double>(), t90_s);
  EXPECT_EQ(c.at("events").at("t90_frame").get<std::int64_t>(), t90_frame.at(0));
  EXPECT_DOUBLE_EQ(c.at("external_work_J").get<double>(), work_J);
  EXPECT_DOUBLE_EQ(c.at("energy_ratio").get<double>(), u_t90 / work_J);
  EXPECT_EQ(c.at("frames_in_span").get<int>(), 100);
  EXPECT_EQ(c.at("columns").at("plate_position_x").at("unit"), "mm");
}

TEST(ChannelsStage, ResampledChannelsEqualDirectEvaluation) {
  // Noise-free channels and frame times jittered by 1 ms, so frames fall between channel samples.
  const samples::Trial trial = make_trial(0.0, 0.0, 1e-3);
  const fs::path dir = scratch("resample");
  write_channels(trial, dir, 0.0);
  const Scene scene = channels_scene(dir, std::string("{file: channels.csv, ") + kColumns + "}");
  const StageRun run = run_stage(scene, trial, dir, 0.0);
  H5Reader h5(run.h5_path);
  const auto t_s = h5.read_doubles("/channels/t_s");
  const auto plate = h5.read_doubles("/channels/plate_position_m");
  const auto plate_at = h5.read_doubles("/channels/at_frames/plate_position_m");
  const auto ft_at = h5.read_doubles("/channels/at_frames/tangential_force_N");
  const auto w_at = h5.read_doubles("/channels/at_frames/normal_force_N");
  const auto plate_y_at = h5.read_doubles("/channels/at_frames/plate_position_y_m");
  ASSERT_EQ(plate_at.size(), 100u);
  // Against the interpolant of the raw channel ...
  std::vector<double> frame_t(trial.frame_times_s().begin(), trial.frame_times_s().end());
  const auto direct = signals::resample_linear(t_s, plate, frame_t);
  // ... and against the load history itself: the plate moves along -y, so the stroke coordinate is
  // +(t - t0)·v, linear on each side of the start (a channel sample), so linear interpolation is exact.
  double worst_plate = 0.0, worst_q = 0.0;
  for (std::size_t k = 0; k < plate_at.size(); ++k) {
    const double t = frame_t[k];
    EXPECT_DOUBLE_EQ(plate_at[k], direct[k]);
    worst_plate =
        std::max(worst_plate, std::abs(plate_at[k] - std::max(0.0, t - kShearStart_s) * kSpeed_m_s));
    EXPECT_NEAR(plate_y_at[k], -std::max(0.0, t - kShearStart_s) * kSpeed_m_s, 1e-12);
    EXPECT_NEAR(w_at[k], kNormal_N, 1e-12);
    worst_q = std::max(worst_q, std::abs(ft_at[k] - trial.load(static_cast<int>(k)).tangential_N));
  }
  std::printf("[ measured ] at frames vs history: plate %.3g m, Q %.3g N (frames jittered 1 ms)\n",
              worst_plate, worst_q);
  EXPECT_LE(worst_plate, 1e-12);
  // Q is concave (|Q''| = μP·(3/4)v²/δ²·(1 − d/δ)^{-1/2}); between 1 kHz samples the chord is below the curve
  // by at most |Q''|·dt²/8, ≈ 1e-4 N except in the last millisecond before full slip.
  EXPECT_LE(worst_q, 2e-3 * kMu * kNormal_N);
  // frames.csv columns follow the header, one value per dataset.
  ASSERT_EQ(run.header.front(), "channels_in_span");
  EXPECT_EQ(run.header.back(), "mu");
  EXPECT_EQ(run.rows[37].size(), run.header.size());
  const auto it = std::find(run.header.begin(), run.header.end(), "plate_position_m");
  ASSERT_NE(it, run.header.end());
  EXPECT_DOUBLE_EQ(std::stod(run.rows[37][static_cast<std::size_t>(it - run.header.begin())]), plate_at[37]);
}

TEST(ChannelsStage, CrossCorrelationAlignmentRecoversAFractionalOffset) {
  // The channel clock runs 31.37 ms behind the camera (31.37 channel samples, 3.137 frames).
  const double offset = 0.03137;
  const samples::Trial trial = make_trial(0.01, 0.005, 0.0);
  const fs::path dir = scratch("xcorr");
  write_channels(trial, dir, offset);
  const Scene scene = channels_scene(dir, std::string("{file: channels.csv, ") + kColumns +
                                              ", alignment: {mode: cross_correlation, max_lag_s: 0.1}}");
  // Exact plate displacement from the tracking stage: the offset to a small fraction of a channel sample.
  {
    const StageRun run = run_stage(scene, trial, dir, 0.0);
    const double found = run.summary.at("channels").at("alignment").at("offset_s").get<double>();
    std::printf("[ measured ] cross-correlation, exact plate: offset error %.2g s\n", found - offset);
    EXPECT_NEAR(found, offset, 1e-5);
  }
  // With 0.05 px noise on each axis of the plate displacement. Only the start of the stroke pins the lag
  // (after it, a shift is absorbed by the mean): σ ≈ 0.05 px / (0.26 px/ms · √20 frames at rest) ≈ 0.04 ms,
  // and over seeds the error scatters with σ ≈ 0.06 ms; tolerance 5σ.
  const StageRun run = run_stage(scene, trial, dir, 0.05);
  H5Reader h5(run.h5_path);
  const double found = run.summary.at("channels").at("alignment").at("offset_s").get<double>();
  std::printf(
      "[ measured ] cross-correlation, 0.05 px noise: offset %.6f s (truth %.5f s, error %.2g s = %.3f "
      "channel samples)\n",
      found, offset, found - offset, (found - offset) / 1e-3);
  EXPECT_NEAR(found, offset, 3e-4);
  EXPECT_GT(run.summary.at("channels").at("alignment").at("correlation").get<double>(), 0.9999);
  EXPECT_EQ(run.summary.at("channels").at("alignment").at("frames_compared").get<int>(), 100);
  EXPECT_EQ(h5.attribute_text("/channels", "alignment_method"), "cross-correlation");
  EXPECT_DOUBLE_EQ(h5.attribute_number("/channels", "offset_s"), found);
  // Channel times are written on the camera clock: the first sample was at −offset on the channel clock.
  EXPECT_NEAR(h5.read_doubles("/channels/t_s").front(), found - offset, 1e-12);
  // Events come out on the camera clock: the stroke starts at 0.2 s camera time.
  EXPECT_NEAR(scalar(h5, "/events/onset_s"), kShearStart_s, 3e-4 + 1e-3);
  EXPECT_NEAR(scalar(h5, "/events/t90_s"), expected_history().t90_s, 2e-3);
}

TEST(ChannelsStage, TriggerAlignmentAndFramesOutsideTheRecord) {
  // The channel clock runs 20 ms ahead (t_channel = t_camera + 0.02, offset -0.02 s); a trigger pulse rises
  // at camera time 0.105 s, which the scene states. The record starts after frame 0 on the camera clock.
  const samples::Trial trial = make_trial(0.0, 0.0, 0.0);
  const fs::path dir = scratch("trigger");
  write_channels(trial, dir, -0.02, 0.105);
  const Scene scene =
      channels_scene(dir, std::string("{file: channels.csv, ") +
                              "columns: {normal_force: normal_N, tangential_force: tangential_N, "
                              "plate_position: plate_y_mm, trigger: trigger_V}, "
                              "invert: [plate_position], "
                              "alignment: {mode: trigger, camera_edge_s: 0.105}}");
  const StageRun run = run_stage(scene, trial, dir, 0.0);
  H5Reader h5(run.h5_path);
  // The pulse is a step between the samples at camera times 0.104 and 0.105 s: the 2.5 V crossing is found
  // half a sample early, so the offset is -0.0195 s and the record covers camera times [0.0005, 1.0005] s.
  EXPECT_NEAR(h5.attribute_number("/channels", "offset_s"), -0.02 + 0.0005, 1e-12);
  EXPECT_NEAR(run.summary.at("channels").at("alignment").at("channel_edge_s").get<double>(), 0.1245, 1e-12);
  const auto in_span = h5.read_integers("/channels/at_frames/in_span");
  for (std::size_t k = 0; k < in_span.size(); ++k) EXPECT_EQ(in_span[k], k == 0 ? 0 : 1) << k;
  EXPECT_EQ(h5.read_doubles("/channels/at_frames/normal_force_N")[0], 0.0);
  EXPECT_NEAR(h5.read_doubles("/channels/at_frames/normal_force_N")[1], kNormal_N, 1e-12);
  EXPECT_EQ(h5.read_integers("/friction/valid")[0], 0);
  EXPECT_EQ(run.summary.at("channels").at("frames_outside_span").get<int>(), 1);
  EXPECT_EQ(run.rows[0][0], "0");
  EXPECT_EQ(run.rows[0][1], "");  // no value, not a made-up one
  // plate_y_mm inverted: the 1-D stroke coordinate increases, U_ext is positive and matches the history.
  const double work_J = scalar(h5, "/work/external_J");
  std::printf("[ measured ] noise-free U_ext %.5e J vs history %.5e J (%+.3f %%), t90 %.5f s vs %.5f s\n",
              work_J, expected_history().external_J, 100.0 * (work_J / expected_history().external_J - 1.0),
              scalar(h5, "/events/t90_s"), expected_history().t90_s);
  // Noise-free, U_ext is the history's to the trapezoid rule's accuracy (measured 1e-5 relative); t90 is the
  // history's plus the trigger's half-sample bias in the offset (0.5 ms).
  EXPECT_NEAR(work_J / expected_history().external_J, 1.0, 1e-3);
  EXPECT_NEAR(scalar(h5, "/events/t90_s"), expected_history().t90_s + 0.0005, 1e-4);
}

// A real recording's channel file (offsets, drift, approach, press, two strokes, release; the DAQ's normal
// channel negative-going) under a trial's frames: the stage tares and segments it as `signals friction`
// does, with the scene's `invert` setting the normal force's sign.
TEST(ChannelsStage, RealRecordingIsTaredAndSegmented) {
  const samples::Trial trial = make_trial(0.0, 0.0, 0.0);
  const fs::path dir = scratch("phases");
  signals::testing::SynthRecording c;
  c.strokes = 2;
  c.normal_sign = -1;
  const auto rec = signals::testing::synthesise(c);
  {
    CsvWriter out((dir / "channels.csv").string(), {"t_s", "normal_N", "tangential_N", "plate_m"});
    for (std::size_t i = 0; i < rec.t_s.size(); ++i)
      out.row({rec.t_s[i], rec.normal_N[i], rec.tangential_N[i], rec.position_m[i]});
    out.commit();
  }
  const std::string columns =
      "columns: {normal_force: normal_N, tangential_force: tangential_N, plate_position: plate_m}";
  const auto has = [](const nlohmann::json& warnings, const std::string& text) {
    return std::any_of(warnings.begin(), warnings.end(), [&](const auto& w) {
      return w.template get<std::string>().find(text) != std::string::npos;
    });
  };
  // As recorded: W goes negative on contact, so μ is undefined; the stage says why instead of a number.
  const StageRun raw =
      run_stage(channels_scene(dir, "{file: channels.csv, " + columns + "}"), trial, dir, 0.0);
  const auto& raw_warnings = raw.summary.at("channels").at("warnings");
  EXPECT_TRUE(has(raw_warnings, "friction not measured")) << raw_warnings.dump();
  EXPECT_TRUE(has(raw_warnings, "normal_force_negative")) << raw_warnings.dump();
  EXPECT_FALSE(raw.summary.at("channels").contains("mu_dynamic"));

  const StageRun run = run_stage(
      channels_scene(dir, "{file: channels.csv, " + columns + ", invert: [normal_force]}"), trial, dir, 0.0);
  const auto& ch = run.summary.at("channels");
  EXPECT_TRUE(ch.at("warnings").empty()) << ch.at("warnings").dump();
  const auto& phases = ch.at("phases");
  EXPECT_NEAR(phases.at("contact_start_s").get<double>(), c.contact_s, 0.02);
  EXPECT_NEAR(phases.at("loaded_s").get<double>(), c.loaded_s, 0.02);
  EXPECT_NEAR(phases.at("release_s").get<double>(), c.release_s, 0.02);
  EXPECT_EQ(phases.at("tare").at("model"), "linear");
  ASSERT_EQ(phases.at("strokes").size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_NEAR(phases.at("strokes")[k].at("mu_mean").get<double>() / rec.strokes[k].mu_mean, 1.0, 0.02);
    EXPECT_EQ(phases.at("strokes")[k].at("direction").get<int>(), rec.strokes[k].direction);
  }
  EXPECT_NEAR(ch.at("mu_dynamic").get<double>() / rec.strokes[0].mu_mean, 1.0, 0.02);
  EXPECT_NEAR(ch.at("mu_plateau_start_s").get<double>(), rec.strokes[0].slide_start_s, 0.02);
  EXPECT_NEAR(ch.at("mu_plateau_end_s").get<double>(), rec.strokes[0].slide_end_s, 0.02);
  // Events of the first stroke: the plate starts at its loading, after the press.
  const auto& events = ch.at("events");
  EXPECT_NEAR(events.at("onset_s").get<double>(), c.first_stroke_s, 1e-3);
  EXPECT_GT(events.at("t90_s").get<double>(), events.at("onset_s").get<double>());
  EXPECT_LE(events.at("full_slip_s").get<double>(), rec.strokes[0].slide_end_s);
  // μ at the frames (0–1 s, the approach: W below the minimum) is absent, not a ratio of offsets.
  H5Reader h5(run.h5_path);
  for (const auto v : h5.read_integers("/friction/valid")) EXPECT_EQ(v, 0);
}

// A DAQ recording as MATLAB saves it: one matrix of raw columns (normal force in volts), no time vector;
// the channel config names the columns, gives the sample rate and the load cell's calibration.
TEST(ChannelsStage, MatlabMatrixOfVoltsWithRateAndCalibration) {
  const samples::Trial trial = make_trial(0.0, 0.0, 0.0);
  const samples::ChannelSeries s = trial.channels();
  const fs::path dir = scratch("matlab");
  constexpr double kGain_N_per_V = 2.5, kOffset_N = -0.125;
  const std::size_t n = s.t_s.size();
  std::vector<double> data(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    data[i] = (s.normal_N[i] - kOffset_N) / kGain_N_per_V;
    data[n + i] = s.plate_x_mm[i];
    data[2 * n + i] = s.plate_y_mm[i];
  }
  {
    mat_t* mat = Mat_CreateVer((dir / "rec.mat").c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(mat, nullptr);
    std::size_t dims[2] = {n, 3};
    matvar_t* var = Mat_VarCreate("dataQ", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, data.data(), 0);
    ASSERT_EQ(Mat_VarWrite(mat, var, MAT_COMPRESSION_ZLIB), 0);
    Mat_VarFree(var);
    Mat_Close(mat);
  }
  const Scene scene = channels_scene(
      dir,
      "{file: rec.mat, rate_hz: 1000, mat_column_names: {dataQ: [normal_V, plate_x_mm, plate_y_mm]}, "
      "calibration: {normal_V: {gain: 2.5, offset: -0.125}}, units: {normal_force: N}, "
      "columns: {normal_force: normal_V, plate_position_x: plate_x_mm, plate_position_y: plate_y_mm}}");
  const StageRun run = run_stage(scene, trial, dir, 0.0);
  H5Reader h5(run.h5_path);
  const auto t_s = h5.read_doubles("/channels/t_s");
  const auto normal = h5.read_doubles("/channels/normal_force_N");
  ASSERT_EQ(normal.size(), n);
  double worst_t = 0.0, worst_w = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    worst_t = std::max(worst_t, std::abs(t_s[i] - s.t_s[i]));
    worst_w = std::max(worst_w, std::abs(normal[i] - s.normal_N[i]));
  }
  EXPECT_LE(worst_t, 1e-12);  // i / 1000 Hz against the synthesised sample times
  EXPECT_LE(worst_w, 1e-12);  // volts back to newtons: rounding only
  // Without rate_hz the file has no clock: the error names the file and what to give.
  const Error e = expect_error([&] {
    make_channels_stage(channels_scene(dir,
                                       "{file: rec.mat, mat_column_names: {dataQ: [normal_V, x_mm, y_mm]}, "
                                       "units: {normal_force: N}, columns: {normal_force: normal_V}}"))
        ->start(TrialInfo{});
  });
  EXPECT_NE(std::string(e.what()).find("rec.mat"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("rate_hz"), std::string::npos) << e.what();
}

TEST(ChannelsStage, BadChannelFilesAndScenesAreLocated) {
  const samples::Trial trial = make_trial(0.0, 0.0, 0.0);
  const fs::path dir = scratch("bad");
  const std::string path = write_channels(trial, dir, 0.0);
  const std::string ok = std::string("{file: channels.csv, ") + kColumns + "}";
  // A NaN cell: file, row (header = row 1) and column.
  {
    std::ifstream in(path);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::size_t pos = 0;
    for (int line = 1; line < 57; ++line) pos = text.find('\n', pos) + 1;  // start of row 57
    const std::size_t c1 = text.find(',', pos), c2 = text.find(',', c1 + 1), c3 = text.find(',', c2 + 1);
    text.replace(c2 + 1, c3 - c2 - 1, "nan");  // third column: tangential_N
    std::ofstream(path) << text;
  }
  const Scene scene = channels_scene(dir, ok);
  auto stage = make_channels_stage(scene);
  const Error nan = expect_error([&] { stage->start(TrialInfo{}); });
  EXPECT_EQ(nan.context().file, path);
  EXPECT_EQ(nan.context().row, 57);
  EXPECT_EQ(nan.context().column, "tangential_N");
  std::printf("[ message  ] %s\n", nan.what());

  // A mapped column the file does not have.
  write_channels(trial, dir, 0.0);
  const Error missing = expect_error([&] {
    make_channels_stage(channels_scene(dir, "{file: channels.csv, columns: {normal_force: load_N}}"))
        ->start(TrialInfo{});
  });
  EXPECT_EQ(missing.context().column, "load_N");
  EXPECT_NE(std::string(missing.what()).find("channels.csv"), std::string::npos) << missing.what();

  // Scene errors name the scene file and key.
  const std::string scene_file = (dir / "scene.yaml").string();
  const auto scene_error = [&](const std::string& yaml) {
    return expect_error([&] { make_channels_stage(channels_scene(dir, yaml)); });
  };
  Error e = scene_error("{file: channels.csv, columns: {normal_forse: normal_N}}");
  EXPECT_EQ(e.context().file, scene_file);
  EXPECT_EQ(e.context().key, "channels.columns.normal_forse");
  e = scene_error("{file: channels.csv, columns: {normal_force: normal_N}, colour: red}");
  EXPECT_EQ(e.context().key, "channels.colour");
  e = scene_error("{columns: {normal_force: normal_N}}");
  EXPECT_EQ(e.context().key, "channels.file");
  e = scene_error("{file: channels.csv, columns: {normal_force: load}}");
  EXPECT_EQ(e.context().key, "channels.columns.normal_force");  // unit not in the name
  e = scene_error("{file: channels.csv, columns: {plate_position_x: plate_x_mm}}");
  EXPECT_EQ(e.context().key, "channels.columns.plate_position_y");
  e = scene_error("{file: channels.csv, columns: {normal_force: normal_N}, alignment: {mode: trigger}}");
  EXPECT_EQ(e.context().key, "channels.alignment.mode");  // no trigger column
  e = scene_error(
      "{file: channels.csv, columns: {normal_force: normal_N}, alignment: {offset_s: 0.1, "
      "max_lag_s: 0.2}}");
  EXPECT_EQ(e.context().key, "channels.alignment.max_lag_s");  // belongs to another mode
  e = scene_error("{file: channels.csv, columns: {normal_force: normal_N}, friction: {fraction: 1.5}}");
  EXPECT_EQ(e.context().key, "channels.friction.fraction");
  // A unit given explicitly makes any column name usable.
  EXPECT_NO_THROW(make_channels_stage(
      channels_scene(dir, "{file: channels.csv, columns: {normal_force: load}, units: {normal_force: mN}}")));
  // Cross-correlation without the tracking stage's plate displacement: named, not guessed.
  {
    const Scene s = channels_scene(
        dir, std::string("{file: channels.csv, ") + kColumns + ", alignment: {mode: cross_correlation}}");
    auto stage2 = make_channels_stage(s);
    stage2->start(TrialInfo{});
    capture::Frame frame;
    FrameContext context;
    context.frame = &frame;
    stage2->process(context);
    nlohmann::json summary;
    const Error no_plate = expect_error([&] { stage2->summarize(summary); });
    EXPECT_EQ(no_plate.context().key, "channels.alignment.mode");
    EXPECT_EQ(no_plate.context().file, scene_file);
  }
}

// `tirstrain process` end to end on the default synthetic trial (640x512, 40 frames, 2 N, μ = 1, 5 mm/s,
// sensor and force noise): contact, tracking and strain run for real, and the channels stage aligns the
// channels by cross-correlating the plate position channel with the tracked plate displacement (true offset
// 0: synth writes both on one clock). Needs the stage registered in pipeline/stages.cpp as "channels".
constexpr int kEndToEndFrames = 40;

TEST(ChannelsStage, EndToEndProcessWithTrackingStrainAndCrossCorrelation) {
  const fs::path dir = scratch("e2e");
  const auto cli = [&](const std::string& args) {
    const std::string command =
        std::string(TIRSTRAIN_CLI) + " " + args + " > " + (dir / "log.txt").string() + " 2>&1";
    const int status = std::system(command.c_str());
    std::ifstream log(dir / "log.txt");
    const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
    return std::make_pair(WIFEXITED(status) ? WEXITSTATUS(status) : -1, text);
  };
  const fs::path trial = dir / "trial", out = dir / "out";
  // The default scene cut to 40 frames (0.4 s: the 90 % point at 0.14 s and full slip at 0.17 s are inside).
  {
    YAML::Node base = YAML::LoadFile(std::string(TIRSTRAIN_SOURCE_DIR) + "/samples/scenes/default.yaml");
    base["synthesis"]["timing"]["frames"] = kEndToEndFrames;
    fs::create_directories(dir);
    YAML::Emitter e;
    e << base;
    std::ofstream(dir / "scene.yaml") << e.c_str() << '\n';
  }
  auto [code, log] =
      cli("synth --scene " + (dir / "scene.yaml").string() + " --out " + trial.string() + " --quiet");
  ASSERT_EQ(code, 0) << log;
  YAML::Node scene = YAML::LoadFile((trial / "scene.yaml").string());
  scene["compute"] = YAML::Load("[contact, tracking, strain, channels]");
  scene["channels"] =
      YAML::Load(std::string("{file: channels.csv, ") + kColumns +
                 ", alignment: {mode: cross_correlation, max_lag_s: 0.05}, friction: {baseline_s: 0.04}}");
  {
    YAML::Emitter e;
    e.SetDoublePrecision(17);
    e << scene;
    std::ofstream(trial / "process.yaml") << e.c_str() << '\n';
  }
  std::tie(code, log) = cli("process " + trial.string() + " --scene " + (trial / "process.yaml").string() +
                            " --out " + out.string() + " --overlay none --quiet");
  ASSERT_EQ(code, 0) << log;

  H5Reader h5((out / "result.h5").string());
  const auto frame_t = h5.read_doubles("/frames/t_s");
  const auto t_s = h5.read_doubles("/channels/t_s");
  ASSERT_EQ(frame_t.size(), static_cast<std::size_t>(kEndToEndFrames));
  // One time axis: every channel at the frames is its interpolant at /frames/t_s.
  for (const char* name :
       {"normal_force_N", "tangential_force_N", "plate_position_m", "accelerometer_m_s2"}) {
    const auto at = h5.read_doubles(std::string("/channels/at_frames/") + name);
    const auto direct =
        signals::resample_linear(t_s, h5.read_doubles(std::string("/channels/") + name), frame_t);
    ASSERT_EQ(at.size(), frame_t.size()) << name;
    for (std::size_t k = 0; k < at.size(); ++k)
      EXPECT_NEAR(at[k], direct[k], 1e-12) << name << " frame " << k;
  }
  // History of the scene: P = 2 N, μ = 1, R = 0.02 m, E = 1 MPa, ν = 0.4, stroke from 0.05 s at 5 mm/s.
  model::CattaneoMindlinParams p;
  p.normal_N = 2.0;
  p.tangential_N = 2.0;
  p.radius_m = 0.02;
  p.friction = 1.0;
  const double delta = model::CattaneoMindlin(p).rigid_shift_m();
  const double d90 = delta * (1.0 - std::pow(0.1, 2.0 / 3.0));
  const double t90 = 0.05 + d90 / 5e-3;
  const double work = 2.0 * (d90 - 0.4 * delta * (1.0 - std::pow(0.1, 5.0 / 3.0)));
  const double offset = h5.attribute_number("/channels", "offset_s");
  const double mu_dynamic = scalar(h5, "/friction/mu_dynamic");
  const double t90_s = scalar(h5, "/events/t90_s"), work_J = scalar(h5, "/work/external_J");
  std::printf(
      "[ measured ] end to end: offset %.3g s (truth 0), mu_dynamic %.5f (1), t90 %.5f s (history %.5f), "
      "U_ext %.4e J (history %.4e, %+.2f %%), U/U_ext %.4f\n",
      offset, mu_dynamic, t90_s, t90, work_J, work, 100.0 * (work_J / work - 1.0),
      scalar(h5, "/work/energy_ratio"));
  // The tracked plate displacement pins the offset to a fraction of a channel sample (measured 39 µs).
  EXPECT_NEAR(offset, 0.0, 2e-4);
  // Force noise 10/5 mN plus 30 mN slip fluctuation, ~430 plateau samples: standard error ≈ 2e-3 / 20.
  EXPECT_NEAR(mu_dynamic, 1.0, 3e-3);
  EXPECT_NEAR(t90_s, t90, 2e-3);
  EXPECT_NEAR(work_J / work, 1.0, 0.03);
  // U at t90: the strain stage's per-frame energy (frames.csv) interpolated between the bracketing frames.
  const CsvTable frames = read_numeric_csv((out / "frames.csv").string(), NaNCells::kNotMeasured);
  const auto u = signals::resample_linear(frames.column("t_s"), frames.column("strain_energy_J"), {t90_s});
  EXPECT_NEAR(scalar(h5, "/work/strain_energy_at_t90_J"), u.front(), 1e-12 * std::abs(u.front()));
  EXPECT_GT(u.front(), 0.0);
  EXPECT_NEAR(scalar(h5, "/work/energy_ratio"), u.front() / work_J, 1e-12);
  EXPECT_TRUE(frames.has("mu"));
  EXPECT_TRUE(frames.has("tangential_force_N"));
  std::ifstream summary_file(out / "summary.json");
  const auto summary = nlohmann::json::parse(summary_file);
  EXPECT_DOUBLE_EQ(summary.at("channels").at("alignment").at("offset_s").get<double>(), offset);
  EXPECT_DOUBLE_EQ(summary.at("channels").at("external_work_J").get<double>(), work_J);
  EXPECT_EQ(summary.at("channels").at("frames_with_strain_energy").get<int>(), kEndToEndFrames);
}

}  // namespace
}  // namespace tirstrain::pipeline
