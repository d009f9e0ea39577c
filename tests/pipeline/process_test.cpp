// `tirstrain process` end to end through the CLI: the documented datasets with the right shapes and
// values, bad input reported with file and frame, and an interrupted run leaving no result.h5.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <sstream>

#include "core/csv.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "samples/generalisation.hpp"
#include "tests/contact/dot_band.hpp"
#include "tests/contact/tir_render.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  return testing::scratch_dir("pipeline", name);
}

struct CliRun {
  int exit_code = -1;
  std::string output;
};

CliRun run_cli(const std::string& arguments) {
  const std::string command = std::string(TIRSTRAIN_CLI) + " " + arguments + " 2>&1";
  CliRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe) != nullptr) run.output += buffer.data();
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

// The contact of frame i drifts right by 2 px per frame; time steps are uneven, as from a real camera.
test::TirScene frame_scene(int i) {
  test::TirScene scene;
  scene.contacts = {{300.0 + 2.0 * i, 256.0, 150.0, 110.0, 0.4}};
  scene.seed = static_cast<std::uint64_t>(i + 1);
  return scene;
}

double frame_time_s(int i) {
  return 0.005 * i + 0.0003 * (i % 3);
}

fs::path write_trial(const std::string& name, int frames, bool with_times = true) {
  const fs::path dir = scratch(name);
  fs::create_directories(dir / "frames");
  std::ofstream times(dir / "frames.csv");
  times << "index,t_s\n";
  for (int i = 0; i < frames; ++i) {
    char file[32];
    std::snprintf(file, sizeof file, "%06d.png", i);
    cv::imwrite((dir / "frames" / file).string(), test::render_tir(frame_scene(i)));
    times << i << ',' << format_double(frame_time_s(i)) << '\n';
  }
  times.close();
  if (!with_times) fs::remove(dir / "frames.csv");
  return dir;
}

TEST(Process, WritesDocumentedResults) {
  constexpr int kFrames = 8;
  const fs::path trial = write_trial("e2e_trial", kFrames);
  const fs::path out = scratch("e2e_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;

  H5Reader h5((out / "result.h5").string());
  const std::size_t n = kFrames;
  EXPECT_EQ(h5.shape("/frames/t_s"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/frames/status"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/status"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/area_mm2"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/hull_px"), (H5Shape{n, 50, 2}));
  EXPECT_EQ(h5.shape("/contact/ellipse"), (H5Shape{n, 5}));
  EXPECT_EQ(h5.shape("/contact/orientation_rad"), (H5Shape{n, 16, 20}));
  EXPECT_EQ(h5.shape("/contact/coherence"), (H5Shape{n, 16, 20}));
  EXPECT_EQ(h5.shape("/contact/texture_snr"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/border_averaged"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/ridge_label_centre"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/border_band_centre"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/contact/ridge_label_shift_px"), (H5Shape{n, 2}));
  EXPECT_EQ(h5.shape("/contact/ridge_label_shape_px"), (H5Shape{n, 3}));
  EXPECT_EQ(h5.shape("/contact/centre_measured_px"), (H5Shape{n, 2}));
  EXPECT_EQ(h5.shape("/contact/centre_smoothed"), (H5Shape{n}));
  EXPECT_NE(h5.attribute_text("/", "software_version").find("tirstrain"), std::string::npos);
  EXPECT_NE(h5.attribute_text("/", "scene_yaml").find("px_per_mm"), std::string::npos);
  EXPECT_NEAR(h5.attribute_number("/contact", "ridge_period_px"), 23.4, 1.0);

  const auto t_s = h5.read_doubles("/frames/t_s");
  const auto status = h5.read_integers("/contact/status");
  const auto ellipse = h5.read_doubles("/contact/ellipse");
  const auto area = h5.read_doubles("/contact/area_mm2");
  // The bench renderer's 2 % noise on 0.45 contrast: SNR 26 (contact_bench), above the border averaging's 20.
  const auto snr = h5.read_doubles("/contact/texture_snr");
  const auto averaged = h5.read_integers("/contact/border_averaged");
  // The centre from the ridge labels, by default on this large, unsaturated, unaveraged contact. The recorded
  // shift is what moved the level edge's centre: taking it back off gives that centre, which on this whorl is
  // further from the rendered contact's (measured RMS 0.38 px with the shifts, 0.86 px without).
  const auto labelled = h5.read_integers("/contact/ridge_label_centre");
  const auto shift = h5.read_doubles("/contact/ridge_label_shift_px");
  // The brackets' size and shape terms, recorded with the shift: a few px at most (bounded by half a ridge
  // period).
  const auto shape = h5.read_doubles("/contact/ridge_label_shape_px");
  const double truth_area_mm2 = M_PI * 150.0 * 110.0 / (52.0 * 52.0);
  double labelled_sq = 0.0, level_edge_sq = 0.0, largest_shift_px = 0.0, largest_shape_px = 0.0;
  for (int i = 0; i < kFrames; ++i) {
    EXPECT_DOUBLE_EQ(t_s[static_cast<std::size_t>(i)], frame_time_s(i));
    EXPECT_EQ(status[static_cast<std::size_t>(i)], 0);
    const double dx = ellipse[static_cast<std::size_t>(i) * 5] - (300.0 + 2.0 * i);
    const double dy = ellipse[static_cast<std::size_t>(i) * 5 + 1] - 256.0;
    // Values, not accuracy (tested in tests/contact): the contact moves over a fixed whorl, so the ridge
    // phase at its border changes per frame (measured 0.5-1.6 px, area +3 %).
    EXPECT_LE(std::hypot(dx, dy), 2.0) << "frame " << i;
    EXPECT_NEAR(ellipse[static_cast<std::size_t>(i) * 5 + 2] / 150.0, 1.0, 0.02);
    EXPECT_NEAR(area[static_cast<std::size_t>(i)] / truth_area_mm2, 1.0, 0.04);
    EXPECT_GT(snr[static_cast<std::size_t>(i)], 20.0) << "frame " << i;
    EXPECT_LT(snr[static_cast<std::size_t>(i)], 40.0) << "frame " << i;
    EXPECT_EQ(averaged[static_cast<std::size_t>(i)], 0) << "frame " << i;
    EXPECT_EQ(labelled[static_cast<std::size_t>(i)], 1) << "frame " << i;
    const double shift_x = shift[static_cast<std::size_t>(i) * 2],
                 shift_y = shift[static_cast<std::size_t>(i) * 2 + 1];
    labelled_sq += dx * dx + dy * dy;
    largest_shift_px = std::max(largest_shift_px, std::hypot(shift_x, shift_y));
    const double shape_px =
        std::hypot(shape[static_cast<std::size_t>(i) * 3], shape[static_cast<std::size_t>(i) * 3 + 1],
                   shape[static_cast<std::size_t>(i) * 3 + 2]);
    EXPECT_LE(shape_px, 0.5 * 23.4) << "frame " << i;
    largest_shape_px = std::max(largest_shape_px, shape_px);
    level_edge_sq += std::pow(dx - shift_x, 2) + std::pow(dy - shift_y, 2);
  }
  // Eight frames are too few to know the centre's noise: none is smoothed in time, and the measured centre is
  // the ellipse's.
  const auto smoothed = h5.read_integers("/contact/centre_smoothed");
  const auto measured = h5.read_doubles("/contact/centre_measured_px");
  for (int i = 0; i < kFrames; ++i) {
    EXPECT_EQ(smoothed[static_cast<std::size_t>(i)], 0);
    EXPECT_EQ(measured[static_cast<std::size_t>(i) * 2], ellipse[static_cast<std::size_t>(i) * 5]);
  }
  const double labelled_rms_px = std::sqrt(labelled_sq / kFrames);
  const double level_edge_rms_px = std::sqrt(level_edge_sq / kFrames);
  std::cout << "  centre RMS " << labelled_rms_px << " px with the recorded shifts, " << level_edge_rms_px
            << " px without\n";
  EXPECT_LT(labelled_rms_px, level_edge_rms_px);
  EXPECT_GT(largest_shift_px, 0.1);
  EXPECT_GT(largest_shape_px, 0.1);

  // Read as text: without a scene the tracking stage runs too, and its plate columns are nan (no band).
  std::ifstream csv_file(out / "frames.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(csv_file, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), n + 1);
  EXPECT_EQ(lines[0].rfind("index,t_s,frame_status,contact_status,area_mm2,cx_px,cy_px,semi_major_px,"
                           "semi_minor_px,angle_rad,",
                           0),
            0u)
      << lines[0];
  EXPECT_EQ(lines[4].rfind("3," + format_double(frame_time_s(3)) + ",", 0), 0u) << lines[4];

  std::ifstream summary_file(out / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary["frames"]["total"], kFrames);
  EXPECT_EQ(summary["contact"]["frames_with_contact"], kFrames);
  EXPECT_EQ(summary["contact"]["frames_border_averaged"], 0);
  EXPECT_EQ(summary["contact"]["frames_ridge_label_centre"], kFrames);
  EXPECT_EQ(summary["contact"]["frames_border_band_centre"], kFrames);  // on by default, on large contacts
  EXPECT_EQ(summary["contact"]["frames_centre_smoothed"], 0);
  EXPECT_GT(summary["contact"]["texture_snr_median"].get<double>(), 20.0);
  EXPECT_EQ(summary["time_measured"], true);

  cv::VideoCapture overlay((out / "overlay.mp4").string());
  ASSERT_TRUE(overlay.isOpened());
  int overlay_frames = 0;
  cv::Mat image;
  while (overlay.read(image)) ++overlay_frames;
  EXPECT_EQ(overlay_frames, kFrames);
  for (const char* leftover : {"result.h5.partial", "frames.csv.partial", "overlay.partial.mp4"})
    EXPECT_FALSE(fs::exists(out / leftover)) << leftover;
}

TEST(Process, CorruptMiddleFrameIsSkippedUnlessStrict) {
  const fs::path trial = write_trial("corrupt_trial", 5);
  std::ofstream(trial / "frames" / "000002.png") << "not an image";
  const fs::path out = scratch("corrupt_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("000002.png: frame 2: frame could not be decoded"), std::string::npos)
      << run.output;
  H5Reader h5((out / "result.h5").string());
  const auto frame_status = h5.read_integers("/frames/status");
  const auto contact_status = h5.read_integers("/contact/status");
  ASSERT_EQ(frame_status.size(), 5u);
  EXPECT_EQ(frame_status[2], 2);     // corrupt
  EXPECT_EQ(contact_status[2], 64);  // frame_skipped
  EXPECT_EQ(frame_status[3], 0);
  EXPECT_EQ(contact_status[3], 0);
  EXPECT_EQ(h5.read_doubles("/contact/area_mm2")[2], 0.0);
  EXPECT_FALSE(fs::exists(out / "overlay.mp4"));

  const fs::path strict_out = scratch("corrupt_strict_out");
  const CliRun strict =
      run_cli("process " + trial.string() + " --out " + strict_out.string() + " --strict --quiet");
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_NE(strict.output.find("000002.png: frame 2:"), std::string::npos) << strict.output;
  EXPECT_FALSE(fs::exists(strict_out / "result.h5"));
}

TEST(Process, BadInputsGiveClearErrorsAndNoResult) {
  const fs::path out = scratch("bad_out");
  const auto expect_failure = [&](const std::string& input, const std::vector<std::string>& needles) {
    const CliRun run = run_cli("process " + input + " --out " + out.string() + " --quiet");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    for (const auto& needle : needles) EXPECT_NE(run.output.find(needle), std::string::npos) << run.output;
    EXPECT_FALSE(fs::exists(out / "result.h5"));
  };
  expect_failure((fs::path(TIRSTRAIN_TEST_TMP) / "pipeline" / "missing_input").string(),
                 {"missing_input", "no such file"});

  const fs::path sizes = write_trial("sizes_trial", 4);
  cv::imwrite((sizes / "frames" / "000003.png").string(), cv::Mat(100, 120, CV_8UC1, cv::Scalar(100)));
  expect_failure(sizes.string(), {"000003.png", "frame 3", "120x100"});

  const fs::path backwards = write_trial("backwards_trial", 4);
  std::ofstream(backwards / "frames.csv") << "index,t_s\n0,0\n1,0.01\n2,0.005\n3,0.02\n";
  expect_failure(backwards.string(), {"frames.csv", "frame 2", "backwards"});

  const fs::path video_dir = scratch("bad_video");
  std::ofstream(video_dir / "trial.mp4") << std::string(2048, '\x42');
  expect_failure((video_dir / "trial.mp4").string(), {"trial.mp4", "video"});
}

TEST(Process, VideoInputUsesContainerTimestamps) {
  const fs::path dir = scratch("video_trial");
  const std::string video = (dir / "trial.avi").string();
  {
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 50.0, {640, 512}, false);
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < 4; ++i) writer.write(test::render_tir(frame_scene(i)));
  }
  const fs::path out = scratch("video_out");
  const CliRun run = run_cli("process " + video + " --out " + out.string() + " --quiet --overlay png");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  H5Reader h5((out / "result.h5").string());
  const auto t_s = h5.read_doubles("/frames/t_s");
  ASSERT_EQ(t_s.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(t_s[i], i / 50.0, 1e-6);
  EXPECT_EQ(h5.read_integers("/contact/status")[1], 0);
  EXPECT_TRUE(fs::exists(out / "overlay" / "000003.png"));
  // summary.json lists every output the folder holds, the overlay too.
  std::ifstream summary_file(out / "summary.json");
  EXPECT_EQ(nlohmann::json::parse(summary_file)["outputs"],
            (std::vector<std::string>{"result.h5", "frames.csv", "summary.json", "overlay"}));
}

// A multi-page TIFF, as several fingertip-imaging pipelines store 1 kHz recordings: every page is a frame,
// timed by --frame-rate-Hz (the file holds no timestamps).
TEST(Process, MultiPageTiffGivesEveryPageAsAFrame) {
  const fs::path dir = scratch("tiff_trial");
  const std::string video = (dir / "video.tif").string();
  std::vector<cv::Mat> pages;
  for (int i = 0; i < 3; ++i) pages.push_back(test::render_tir(frame_scene(i)));
  ASSERT_TRUE(cv::imwritemulti(video, pages));
  const fs::path out = scratch("tiff_out");
  const CliRun run =
      run_cli("process " + video + " --frame-rate-Hz 1000 --out " + out.string() + " --quiet --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  H5Reader h5((out / "result.h5").string());
  const auto t_s = h5.read_doubles("/frames/t_s");
  ASSERT_EQ(t_s.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(t_s[i], static_cast<double>(i) / 1000.0);
}

TEST(Process, StagesAskedForBringWhatTheyNeed) {
  const fs::path trial = write_trial("stages_trial", 3, false);
  const fs::path scene = trial / "scene.yaml";
  std::ofstream(scene) << "calibration:\n  px_per_mm: 52\n  ridge_period_mm: 0.45\ncompute: [strain]\n";
  const fs::path out = scratch("stages_out");
  const CliRun run = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                             out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("no timestamps"), std::string::npos) << run.output;
  std::ifstream summary_file(out / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary["stages_run"], nlohmann::json::array({"contact", "tracking", "strain"}));
  // Frames after the reference one: at most 2 at rest; the settings in effect include the subset stride.
  const nlohmann::json& tracking = summary["tracking"];
  ASSERT_TRUE(tracking.contains("rest_frames_on_fit")) << tracking.dump();
  EXPECT_LE(tracking["rest_frames_on_fit"].get<int>(), 2);
  EXPECT_LE(tracking["rest_frames_averaged"].get<int>(), tracking["rest_frames_on_fit"].get<int>());
  EXPECT_GE(tracking["settings"]["subset_stride"].get<int>(), 1);
  H5Reader h5((out / "result.h5").string());
  EXPECT_DOUBLE_EQ(h5.attribute_number("/contact", "ridge_period_px"), 0.45 * 52.0);
  EXPECT_EQ(h5.attribute_number("/frames", "time_measured"), 0.0);
  EXPECT_TRUE(h5.has("/tracks/position_px"));
  EXPECT_TRUE(h5.has("/strain/total"));
  EXPECT_EQ(h5.shape("/energy/total_J"), (H5Shape{3}));
  const CliRun strict = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                                out.string() + " --strict --quiet");
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_NE(strict.output.find("no timestamps"), std::string::npos) << strict.output;
  // --segmentation replaces the scene's segmentation preset: fast turns the ridge labels and the band off.
  const fs::path fast_out = scratch("stages_fast_out");
  const CliRun fast = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                              fast_out.string() + " --overlay none --quiet --segmentation fast");
  ASSERT_EQ(fast.exit_code, 0) << fast.output;
  std::ifstream fast_file(fast_out / "summary.json");
  const nlohmann::json fast_summary = nlohmann::json::parse(fast_file);
  EXPECT_EQ(summary["contact"]["settings"]["border_band_centre"], true);
  EXPECT_EQ(summary["contact"]["frames_border_band_centre"], 3);
  EXPECT_EQ(fast_summary["contact"]["settings"]["border_band_centre"], false);
  EXPECT_EQ(fast_summary["contact"]["settings"]["flat_field"], false);
  EXPECT_EQ(fast_summary["contact"]["frames_border_band_centre"], 0);
  EXPECT_EQ(fast_summary["contact"]["frames_ridge_label_centre"], 0);
  const CliRun quick =
      run_cli("process " + trial.string() + " --out " + out.string() + " --segmentation quick");
  EXPECT_NE(quick.exit_code, 0);
  EXPECT_NE(quick.output.find("quick"), std::string::npos) << quick.output;
  // --compute adds stages to the scene's list; an unknown name is an error.
  const CliRun unknown =
      run_cli("process " + trial.string() + " --out " + out.string() + " --compute straim");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.output.find("straim"), std::string::npos) << unknown.output;
}

// A trial folder's own scene.yaml (as `tirstrain synth` writes) is used without --scene, and --scene
// overrides it. The two scenes differ only in px_per_mm (ridge period the same in pixels), so the same
// contact pixels must give areas in the ratio (60 / 40)^2.
TEST(Process, UsesTheInputFoldersSceneUnlessGivenOne) {
  const fs::path trial = write_trial("own_scene_trial", 2);
  std::ofstream(trial / "scene.yaml") << "calibration: {px_per_mm: 40, ridge_period_mm: 0.585}\n"
                                         "compute: [contact]\n";
  const fs::path other = scratch("own_scene_other") / "other.yaml";
  std::ofstream(other) << "calibration: {px_per_mm: 60, ridge_period_mm: 0.39}\ncompute: [contact]\n";
  const auto run = [&](const std::string& name, const std::string& scene_option) {
    const fs::path out = scratch(name);
    const CliRun r =
        run_cli("process " + trial.string() + scene_option + " --out " + out.string() + " --overlay none");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::ifstream summary_file(out / "summary.json");
    return std::make_pair(r.output, nlohmann::json::parse(summary_file));
  };
  const auto [own_log, own] = run("own_scene_out", "");
  EXPECT_NE(own_log.find("scene from the input folder"), std::string::npos) << own_log;
  EXPECT_EQ(own["scene"], (trial / "scene.yaml").string());
  EXPECT_EQ(own["px_per_mm"].get<double>(), 40.0);
  const auto [given_log, given] = run("own_scene_given_out", " --scene " + other.string());
  EXPECT_EQ(given_log.find("scene from the input folder"), std::string::npos) << given_log;
  EXPECT_EQ(given["scene"], other.string());
  EXPECT_EQ(given["px_per_mm"].get<double>(), 60.0);
  const double own_area = own["contact"]["area_mm2_mean"].get<double>();
  const double given_area = given["contact"]["area_mm2_mean"].get<double>();
  ASSERT_GT(given_area, 0.0);
  EXPECT_NEAR(own_area / given_area, 2.25, 2.25e-3);
}

// Distance from p to a closed polygon's edges.
double distance_to_outline(const cv::Point2d& p, const std::vector<cv::Point2d>& polygon) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const cv::Point2d a = polygon[i], b = polygon[(i + 1) % polygon.size()];
    const cv::Point2d ab = b - a;
    const double t = std::clamp((p - a).dot(ab) / std::max(1e-12, ab.dot(ab)), 0.0, 1.0);
    best = std::min(best, cv::norm(p - (a + t * ab)));
  }
  return best;
}

// The tracker works inside the measured contact inset by `tracking.contact_inset_px` (1 px unless the scene
// says otherwise): its seeds keep border_margin_px from the inset mask, so from the outline they keep that
// plus the inset. With the inset at 0 the seeds come closer to the outline.
TEST(Process, TrackingKeepsClearOfTheMeasuredOutline) {
  const fs::path trial = write_trial("inset_trial", 2);
  double nearest_px[2] = {0.0, 0.0};
  for (const int inset : {0, 1}) {
    const fs::path scene = trial / ("scene_inset_" + std::to_string(inset) + ".yaml");
    std::ofstream(scene) << "calibration: {px_per_mm: 52, ridge_period_mm: 0.45}\ncompute: [tracking]\n"
                         << "tracking: {contact_inset_px: " << inset << "}\n";
    const fs::path out = scratch("inset_out_" + std::to_string(inset));
    const CliRun run = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                               out.string() + " --overlay none --quiet");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    std::ifstream summary_file(out / "summary.json");
    const nlohmann::json summary = nlohmann::json::parse(summary_file);
    EXPECT_EQ(summary["tracking"]["settings"]["contact_inset_px"].get<double>(), inset);
    const double margin_px = summary["tracking"]["settings"]["border_exclusion_px"].get<double>();
    H5Reader h5((out / "result.h5").string());
    const auto hull = h5.read_doubles("/contact/hull_px");  // row 0: the reference frame
    std::vector<cv::Point2d> outline;
    for (std::size_t k = 0; k < 50; ++k) outline.emplace_back(hull[2 * k], hull[2 * k + 1]);
    const auto reference = h5.read_doubles("/tracks/reference_px");
    const auto born = h5.read_integers("/tracks/born_frame");
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < born.size(); ++k)
      if (born[k] == 0)
        nearest = std::min(nearest, distance_to_outline({reference[2 * k], reference[2 * k + 1]}, outline));
    std::printf("  contact_inset_px %d: nearest seed %.2f px from the outline (border margin %.0f px)\n",
                inset, nearest, margin_px);
    // The 50-point hull cuts corners of the filled outline by a fraction of a pixel; the mask's pixel centres
    // lie within half a pixel of the polygon.
    EXPECT_GE(nearest, margin_px + inset - 1.0);
    nearest_px[inset] = nearest;
  }
  EXPECT_GT(nearest_px[1], nearest_px[0] + 0.3);
}

nlohmann::json read_summary(const fs::path& out) {
  std::ifstream file(out / "summary.json");
  return nlohmann::json::parse(file);
}

// A video cut short (a copy that did not finish): its header still announces every frame. The frames that
// decode are processed, and the run says that the others are missing.
TEST(Process, VideoCutShortIsProcessedAndSaidToBeShort) {
  const fs::path dir = scratch("cut_video_trial");
  const std::string video = (dir / "trial.avi").string();
  {
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 50.0, {640, 512}, false);
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < 8; ++i) writer.write(test::render_tir(frame_scene(i % 4)));
  }
  fs::resize_file(video, fs::file_size(video) * 6 / 10);
  const fs::path out = scratch("cut_video_out");
  const CliRun run =
      run_cli("process " + video + " --out " + out.string() + " --overlay none --compute contact");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json summary = read_summary(out);
  const int frames = summary["frames"]["total"].get<int>();
  EXPECT_LT(frames, 8);
  EXPECT_GE(frames, 2);
  const std::string expected = "the input announces 8 frames but only " + std::to_string(frames);
  bool said = false;
  for (const auto& w : summary["warnings"]) said = said || w.get<std::string>().find(expected) == 0;
  EXPECT_TRUE(said) << summary["warnings"].dump();
  EXPECT_NE(run.output.find(expected), std::string::npos) << run.output;
}

// Frames of a recording as a real one comes: a folder of frames and frames.csv, no scene. `contact_at(i)`
// says whether frame i shows the fingertip (else the glass alone); `band` (when not empty) is the plate's
// dot band, moving with the plate by `plate_px_per_frame` along x.
fs::path write_recording(const std::string& name, int frames, const std::function<bool(int)>& contact_at,
                         const cv::Rect& band = {}, double plate_px_per_frame = 0.0) {
  const fs::path dir = scratch(name);
  fs::create_directories(dir / "frames");
  std::ofstream times(dir / "frames.csv");
  times << "index,t_s\n";
  for (int i = 0; i < frames; ++i) {
    test::TirScene scene = frame_scene(i);
    if (!contact_at(i)) scene.contacts = {{-1000.0, -1000.0, 1.0, 1.0, 0.0}};
    cv::Mat image = test::render_tir(scene);
    if (!band.empty()) test::add_dots(image, band, 0.6, 7, {plate_px_per_frame * i, 0.0});
    char file[32];
    std::snprintf(file, sizeof file, "%06d.png", i);
    cv::imwrite((dir / "frames" / file).string(), image);
    times << i << ',' << format_double(frame_time_s(i)) << '\n';
  }
  return dir;
}

// A recording `tirstrain record` did not finish (no recording.json) and one with a frame file gone:
// processed, and each said to be incomplete on the console and in summary.json.
TEST(Process, ARecordingCutShortOrWithLostFramesIsSaidToBe) {
  const fs::path rec = write_recording("cut_recording", 4, [](int) { return true; });
  {
    std::ofstream times(rec / "frames.csv");
    times << "index,t_s,device_frame_id\n";
    for (int i = 0; i < 4; ++i) times << i << ',' << format_double(frame_time_s(i)) << ',' << i << '\n';
  }
  fs::remove(rec / "frames" / "000002.png");
  const fs::path out = scratch("cut_recording_out");
  const CliRun run =
      run_cli("process " + rec.string() + " --out " + out.string() + " --overlay none --compute contact");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("the recording has no recording.json"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("1 frames of the recording are missing"), std::string::npos) << run.output;
  EXPECT_EQ(read_summary(out)["warnings"].size(), 2u) << read_summary(out)["warnings"].dump();
  // The last frame's file gone too: frames 2 and 3 now lie after the last image, which frames.csv lists.
  fs::remove(rec / "frames" / "000003.png");
  const fs::path out_end = scratch("cut_recording_end_out");
  const CliRun end =
      run_cli("process " + rec.string() + " --out " + out_end.string() + " --overlay none --compute contact");
  ASSERT_EQ(end.exit_code, 0) << end.output;
  EXPECT_NE(end.output.find("2 frames of the recording are missing"), std::string::npos) << end.output;
  EXPECT_NE(end.output.find("2 after the last image"), std::string::npos) << end.output;
}

// No scene: every stage the images feed runs (contact, tracking, strain), no channel file so no channels;
// the defaults used are said once each on the console and in summary.json; no band is found on frames that
// have none.
TEST(Process, WithoutASceneRunsEveryStageTheImagesFeed) {
  constexpr int kFrames = 5;
  const fs::path trial = write_recording("defaults_trial", kFrames, [](int) { return true; });
  const fs::path out = scratch("defaults_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json summary = read_summary(out);
  EXPECT_EQ(summary["stages_run"], (std::vector<std::string>{"contact", "tracking", "strain"}));
  EXPECT_NE(summary["stages_source"].get<std::string>().find("no compute list"), std::string::npos);
  EXPECT_EQ(summary["px_per_mm_source"], "default");
  EXPECT_EQ(summary["tissue"]["source"], "default");
  EXPECT_EQ(summary["defaults_used"].size(), 2u);
  for (const char* line :
       {"px_per_mm = 52 is the default", "E = 1e+06 Pa, nu = 0.4, depth = 0.002 m are the"})
    EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
  EXPECT_NE(summary["stages_source"].get<std::string>().find("no channels (no channels section, no "),
            std::string::npos)
      << summary["stages_source"];
  EXPECT_EQ(summary["reference_pattern"]["source"], "none");
  EXPECT_TRUE(summary["reference_pattern"]["roi_px"].is_null());
  EXPECT_EQ(summary["contact"]["frames_with_contact"], kFrames);
  // The contact drifts right by 2 px a frame (frame_scene): the tracks follow it.
  H5Reader h5((out / "result.h5").string());
  EXPECT_EQ(h5.attribute_text("/", "stages"), "contact,tracking,strain");
  const H5Shape shape = h5.shape("/tracks/position_px");
  ASSERT_EQ(shape.size(), 3u);
  EXPECT_EQ(shape[0], static_cast<std::size_t>(kFrames));
  EXPECT_GT(shape[1], 200u);
}

// A fingertip contact larger than the view, no scene: ridges fill every frame (the generalisation suite's
// fingerprint at 0.5 % noise, stretched along x to 45 %), so the contact is the whole frame, and the strain
// comes out as from any contact. Measured: every frame in contact, 344 valid triangles in the last frame,
// E_xx median 0.5516 against the exact 0.5513, RMS errors (xx, yy, xy) 0.003, 0.002, 0.002.
TEST(Process, RidgesFillingTheFrameAreTrackedAndStrainedWithoutAScene) {
  const samples::GeneralisationCase sequence(samples::generalisation_config(
      samples::GeneralisationField::kStretch, samples::GeneralisationTexture::kFingerprint, 0.005, true));
  const fs::path trial = scratch("whole_frame_trial");
  fs::create_directories(trial / "frames");
  {
    std::ofstream times(trial / "frames.csv");
    times << "index,t_s\n";
    for (int k = 0; k < sequence.frames(); ++k) {
      char file[32];
      std::snprintf(file, sizeof file, "%06d.png", k);
      cv::imwrite((trial / "frames" / file).string(), sequence.add_noise(sequence.render_clean(k), k));
      times << k << ',' << format_double(0.01 * k) << '\n';
    }
  }
  const fs::path out = scratch("whole_frame_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(read_summary(out)["contact"]["frames_with_contact"], sequence.frames());

  const int last = sequence.frames() - 1;
  const samples::FieldValue exact = sequence.field({0.5 * sequence.width(), 0.5 * sequence.height()}, last);
  const Gradient2& g = exact.gradient;  // uniform stretch: the same everywhere
  const double F[2][2] = {{1.0 + g.xx, g.xy}, {g.yx, 1.0 + g.yy}};
  const double truth[3] = {0.5 * (F[0][0] * F[0][0] + F[1][0] * F[1][0] - 1.0),
                           0.5 * (F[0][1] * F[0][1] + F[1][1] * F[1][1] - 1.0),
                           0.5 * (F[0][0] * F[0][1] + F[1][0] * F[1][1])};
  H5Reader h5((out / "result.h5").string());
  const std::vector<double> strain = h5.read_row_doubles("/strain/total", static_cast<std::size_t>(last));
  std::vector<double> xx;
  double sum2[3] = {0.0, 0.0, 0.0};
  for (std::size_t t = 0; t + 2 < strain.size(); t += 3) {
    if (!std::isfinite(strain[t]) || !std::isfinite(strain[t + 1]) || !std::isfinite(strain[t + 2])) continue;
    xx.push_back(strain[t]);
    for (int c = 0; c < 3; ++c) sum2[c] += (strain[t + c] - truth[c]) * (strain[t + c] - truth[c]);
  }
  ASSERT_GT(xx.size(), 100u);
  std::nth_element(xx.begin(), xx.begin() + xx.size() / 2, xx.end());
  const double n = static_cast<double>(xx.size());
  std::printf("[ measured ] %zu triangles, E_xx median %.4f (exact %.4f), RMS %.4f %.4f %.4f\n", xx.size(),
              xx[xx.size() / 2], truth[0], std::sqrt(sum2[0] / n), std::sqrt(sum2[1] / n),
              std::sqrt(sum2[2] / n));
  EXPECT_NEAR(xx[xx.size() / 2], truth[0], 0.005);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::sqrt(sum2[c] / n), 0.015) << c;
}

// The plate's dot band along the bottom, no scene: found there (rectangle inside it, within 4 px), left out
// of the contact (which is the fingertip's alone: no multiple_blobs, no touches_edge), and the plate
// displacement measured in it (the pattern moves 1.5 px a frame along x).
TEST(Process, FindsTheBandExcludesItAndMeasuresThePlate) {
  constexpr int kFrames = 5;
  const cv::Rect band(0, 456, 640, 56);
  const fs::path trial = write_recording(
      "band_trial", kFrames, [](int) { return true; }, band, 1.5);
  const fs::path out = scratch("band_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json summary = read_summary(out);
  const nlohmann::json& found = summary["reference_pattern"];
  EXPECT_EQ(found["source"], "detected");
  EXPECT_EQ(found["edge"], "bottom");
  ASSERT_TRUE(found["roi_px"].is_array());
  // Inside the band, short of it by the detector's 1 px inset plus at most 3 px.
  EXPECT_GE(found["roi_px"][1].get<int>(), band.y);
  EXPECT_LE(found["roi_px"][1].get<int>(), band.y + 4);
  EXPECT_EQ(found["roi_px"][1].get<int>() + found["roi_px"][3].get<int>(), band.y + band.height);
  EXPECT_EQ(found["roi_px"][2].get<int>(), band.width);
  EXPECT_GE(found["confidence"].get<double>(), 0.8);
  EXPECT_EQ(found["contact_exclusion_margin_px"], 4);
  EXPECT_NE(run.output.find("detected along the bottom edge"), std::string::npos) << run.output;
  H5Reader h5((out / "result.h5").string());
  const auto status = h5.read_integers("/contact/status");
  const auto ellipse = h5.read_doubles("/contact/ellipse");
  const auto plate = h5.read_doubles("/plate/displacement_px");
  for (int i = 0; i < kFrames; ++i) {
    const auto k = static_cast<std::size_t>(i);
    EXPECT_EQ(status[k], 0) << "frame " << i;
    EXPECT_LE(std::hypot(ellipse[k * 5] - (300.0 + 2.0 * i), ellipse[k * 5 + 1] - 256.0), 2.0)
        << "frame " << i;
    EXPECT_NEAR(plate[k * 2], 1.5 * i, 0.05) << "frame " << i;
    EXPECT_NEAR(plate[k * 2 + 1], 0.0, 0.05) << "frame " << i;
  }
}

// The same recording with a scene whose band lies at the top, where there is no dot pattern (another rig's
// scene, or frames turned upside down): the band is used as given, but both where the images show the band
// and that the plate was hardly ever matched are said, and the plate is not reported as measured.
TEST(Process, ASceneBandAwayFromTheDotsIsSaid) {
  constexpr int kFrames = 6;
  const fs::path trial = write_recording(
      "band_elsewhere_trial", kFrames, [](int) { return true; }, cv::Rect(0, 456, 640, 56), 1.5);
  const fs::path scene = scratch("band_elsewhere_scene") / "scene.yaml";
  std::ofstream(scene) << "reference_pattern: {roi_px: [0, 0, 640, 56]}\n";
  const fs::path out = scratch("band_elsewhere_out");
  const CliRun run = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                             out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("is not where the images show the printed dot band: the first frame has one "
                            "along the bottom edge"),
            std::string::npos)
      << run.output;
  const nlohmann::json summary = read_summary(out);
  std::string warnings;
  for (const auto& w : summary["warnings"]) warnings += w.get<std::string>() + "\n";
  EXPECT_NE(warnings.find("not where the images show"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("the plate was matched into its dot pattern in only"), std::string::npos)
      << warnings;
  EXPECT_EQ(summary["tracking"]["plate_measured"], false);
}

// A fingertip whose contact fills the right edge of the frame, with no band there: its ridges are not
// taken for the plate's dots, so the contact is tracked (and strained) and no plate motion is reported.
TEST(Process, AContactAlongAnEdgeIsNotTakenForTheDotBand) {
  const fs::path dir = scratch("edge_contact");
  std::ofstream(dir / "scene.yaml")
      << "calibration: {px_per_mm: 40, ridge_period_mm: 0.5, ridge_polarity: bright}\n"
         "synthesis:\n"
         "  seed: 3\n"
         "  image: {width_px: 320, height_px: 256, bit_depth: 16}\n"
         "  timing: {frames: 3, frame_rate_hz: 100}\n"
         "  contact: {shape: hertz, normal_N: 1.0, radius_m: 0.02, centre_px: [290, 128]}\n"
         "  loading: {field: affine, gradient: [0.05, 0.0, 0.0, 0.0]}\n"
         "  fingerprint: {background: 0.15}\n"
         "  sensor: {read_noise: 0.005}\n";
  const CliRun synth = run_cli("synth --scene " + (dir / "scene.yaml").string() + " --out " +
                               (dir / "trial").string() + " --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const fs::path out = scratch("edge_contact_out");
  const CliRun run = run_cli("process " + (dir / "trial").string() + " --no-scene --out " + out.string() +
                             " --overlay none --compute contact,tracking,strain");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("reference pattern band: none found"), std::string::npos) << run.output;
  const nlohmann::json summary = read_summary(out);
  EXPECT_EQ(summary["tracking"]["plate_measured"], false);
  EXPECT_GT(summary["tracking"]["tracks_total"].get<int>(), 100);
}

// A recording that starts before the finger touches, and one where it lifts off mid-way and comes back:
// contact is none on those frames, tracking starts at the first frame with contact, and strain is computed.
TEST(Process, ContactComingLateAndLiftingOff) {
  constexpr int kFrames = 8;
  struct Case {
    std::string name;
    std::function<bool(int)> contact_at;
  };
  for (const Case& c : {Case{"late", [](int i) { return i >= 3; }},
                        Case{"lift_off", [](int i) { return i < 3 || i >= 6; }}}) {
    const fs::path trial = write_recording("contact_" + c.name, kFrames, c.contact_at);
    const fs::path out = scratch("contact_" + c.name + "_out");
    const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
    ASSERT_EQ(run.exit_code, 0) << c.name << "\n" << run.output;
    H5Reader h5((out / "result.h5").string());
    const auto status = h5.read_integers("/contact/status");
    for (int i = 0; i < kFrames; ++i)
      EXPECT_EQ((status[static_cast<std::size_t>(i)] & 1) != 0, !c.contact_at(i)) << c.name << " frame " << i;
    const nlohmann::json summary = read_summary(out);
    EXPECT_EQ(summary["stages_run"], (std::vector<std::string>{"contact", "tracking", "strain"})) << c.name;
    EXPECT_EQ(summary["contact"]["frames_with_contact"], 5) << c.name;
    const H5Shape shape = h5.shape("/tracks/position_px");
    ASSERT_EQ(shape.size(), 3u);
    EXPECT_GT(shape[1], 200u) << c.name;
  }
}

// A recording in which the finger never touches: nothing is tracked, so the fit stage has no track to read
// back. Every frame is reported not fitted (no contact) and the run succeeds.
TEST(Process, FitStageOnARecordingWithNoContact) {
  constexpr int kFrames = 4;
  const fs::path trial = write_recording("no_contact_fit", kFrames, [](int) { return false; });
  const fs::path out = scratch("no_contact_fit_out");
  const CliRun run =
      run_cli("process " + trial.string() + " --compute fit --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json summary = read_summary(out);
  EXPECT_EQ(summary["fit"]["frames_not_fitted"], kFrames) << summary.dump();
  H5Reader h5((out / "result.h5").string());
  const auto status = h5.read_integers("/fit/status");
  ASSERT_EQ(status.size(), static_cast<std::size_t>(kFrames));
  for (const auto s : status) EXPECT_EQ(s, 1);  // no_contact
  // `tirstrain fit` on it has nothing to write: an error that says why, and no output folder.
  const fs::path fit_out = scratch("no_contact_fit_fit");
  fs::remove_all(fit_out);
  const CliRun fit = run_cli("fit " + out.string() + " --out " + fit_out.string());
  EXPECT_EQ(fit.exit_code, 1) << fit.output;
  EXPECT_NE(fit.output.find("no frame could be fitted: 4 frames, 4 with no contact"), std::string::npos)
      << fit.output;
  EXPECT_FALSE(fs::exists(fit_out));
}

// A channels.csv beside the frames with tirstrain synth's column names: without a scene the channels stage
// runs on it (its columns mapped by name, in SI); one with unknown names is left out and the reason said.
TEST(Process, ChannelsFileBesideTheFramesIsRead) {
  constexpr int kFrames = 3;
  const fs::path trial = write_recording("channels_trial", kFrames, [](int) { return true; });
  {
    std::ofstream csv(trial / "channels.csv");
    csv << "t_s,normal_N,tangential_N,plate_x_mm,plate_y_mm\n";
    for (int i = 0; i <= 40; ++i)
      csv << format_double(0.001 * i) << ",1.5,0.25," << format_double(0.01 * i) << ",0\n";
  }
  const fs::path out = scratch("channels_out");
  const CliRun run = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  nlohmann::json summary = read_summary(out);
  EXPECT_EQ(summary["stages_run"], (std::vector<std::string>{"contact", "tracking", "strain", "channels"}));
  H5Reader h5((out / "result.h5").string());
  const auto normal = h5.read_doubles("/channels/normal_force_N");
  ASSERT_EQ(normal.size(), 41u);
  EXPECT_DOUBLE_EQ(normal[7], 1.5);
  const auto plate_x = h5.read_doubles("/channels/plate_position_x_m");
  EXPECT_NEAR(plate_x[10], 1e-4, 1e-12);  // 0.1 mm
  // The channels' warnings (here: the plate moves from the record's first sample) are the run's too,
  // printed and in summary.json's top-level list.
  ASSERT_FALSE(summary["channels"]["warnings"].empty()) << summary["channels"].dump();
  for (const auto& w : summary["channels"]["warnings"]) {
    const std::string line = "channels: " + w.get<std::string>();
    EXPECT_NE(std::find(summary["warnings"].begin(), summary["warnings"].end(), line),
              summary["warnings"].end())
        << line;
    EXPECT_NE(run.output.find("tirstrain: warning: " + line), std::string::npos) << line;
  }

  // A scene whose compute list leaves the channels out: the file beside the frames is named as not used.
  const fs::path scene = scratch("channels_scene") / "scene.yaml";
  std::ofstream(scene) << "compute: [contact, tracking, strain]\n";
  const CliRun listed = run_cli("process " + trial.string() + " --scene " + scene.string() + " --out " +
                                out.string() + " --overlay none");
  ASSERT_EQ(listed.exit_code, 0) << listed.output;
  EXPECT_NE(read_summary(out)["stages_source"].get<std::string>().find("channels.csv is not used"),
            std::string::npos);

  std::ofstream(trial / "channels.csv") << "time,force\n0,1\n0.001,1\n";
  const CliRun other = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(other.exit_code, 0) << other.output;
  summary = read_summary(out);
  EXPECT_EQ(summary["stages_run"], (std::vector<std::string>{"contact", "tracking", "strain"}));
  EXPECT_NE(summary["stages_source"].get<std::string>().find("no channels"), std::string::npos);

  // Known columns but a sample that is not a number: found before any frame is read, the channels left out
  // and the reason (file, row, column) said on the first line, not the run stopped.
  std::ofstream(trial / "channels.csv") << "t_s,normal_N,tangential_N\n0,1,0.1\n0.001,nan,0.1\n0.002,1,0.1\n";
  const CliRun nan = run_cli("process " + trial.string() + " --out " + out.string() + " --overlay none");
  ASSERT_EQ(nan.exit_code, 0) << nan.output;
  summary = read_summary(out);
  EXPECT_EQ(summary["stages_run"], (std::vector<std::string>{"contact", "tracking", "strain"}));
  const std::string why = summary["stages_source"].get<std::string>();
  EXPECT_NE(why.find("no channels"), std::string::npos) << why;
  EXPECT_NE(why.find("normal_N"), std::string::npos) << why;
  EXPECT_NE(nan.output.find(why), std::string::npos) << nan.output;
}

// `scene init` on a recording with the band along the left and the finger arriving at frame 2: the band's
// rectangle (inside it, within 4 px), the polarity, the frame rate from frames.csv's median interval (5.3
// ms), the first contact frame, placeholders for calibration and tissue; the file reads back as a scene.
TEST(SceneInit, WritesAStartingSceneFromTheImages) {
  const cv::Rect band(0, 0, 48, 512);
  const fs::path trial = write_recording(
      "init_trial", 6, [](int i) { return i >= 2; }, band);
  const fs::path out = scratch("init_out") / "scene.yaml";
  const CliRun run = run_cli("scene init " + trial.string() + " --out " + out.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const Scene scene = load_scene(out.string());
  ASSERT_TRUE(scene.reference_pattern_roi.has_value());
  EXPECT_EQ(scene.reference_pattern_roi->x, 0);
  EXPECT_LE(scene.reference_pattern_roi->width, band.width);
  EXPECT_GE(scene.reference_pattern_roi->width, band.width - 4);
  EXPECT_EQ(scene.reference_pattern_roi->height, band.height);
  EXPECT_EQ(scene.ridge_polarity, "dark");
  EXPECT_TRUE(scene.compute_given);
  EXPECT_DOUBLE_EQ(scene.px_per_mm, 52.0);
  std::ifstream file(out);
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  for (const char* expected : {"640 x 512 px, 8-bit", "frame rate 188.68 Hz", "first in frame 2",
                               "PLACEHOLDER: image scale", "detected along the left edge"})
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n" << text;
  // A second run does not replace the file (it may hold a measured calibration by now) unless told to.
  std::ofstream(out) << "calibration: {px_per_mm: 61.3}\n";
  const CliRun again = run_cli("scene init " + trial.string() + " --out " + out.string());
  EXPECT_EQ(again.exit_code, 1) << again.output;
  EXPECT_NE(again.output.find("exists and is not replaced"), std::string::npos) << again.output;
  std::ifstream kept(out);
  std::string kept_line;
  std::getline(kept, kept_line);
  EXPECT_EQ(kept_line, "calibration: {px_per_mm: 61.3}");
  const CliRun replace = run_cli("scene init " + trial.string() + " --out " + out.string() + " --overwrite");
  EXPECT_EQ(replace.exit_code, 0) << replace.output;
  EXPECT_DOUBLE_EQ(load_scene(out.string()).px_per_mm, 52.0);
}

TEST(Process, KilledHalfwayLeavesNoResult) {
  constexpr int kFrames = 60;
  const fs::path trial = write_trial("kill_trial", kFrames);
  const fs::path out = scratch("kill_out");
  int pipe_fds[2];
  ASSERT_EQ(pipe(pipe_fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    dup2(pipe_fds[1], STDERR_FILENO);
    close(pipe_fds[0]);
    const std::string in = trial.string(), dir = out.string();
    execl(TIRSTRAIN_CLI, TIRSTRAIN_CLI, "process", in.c_str(), "--out", dir.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  close(pipe_fds[1]);
  // Progress lines come every 10 %; kill once 30 % of the frames are done.
  FILE* err = fdopen(pipe_fds[0], "r");
  std::string seen;
  std::array<char, 512> line{};
  bool reached = false;
  while (std::fgets(line.data(), line.size(), err) != nullptr) {
    seen += line.data();
    if (seen.find("(30%)") != std::string::npos) {
      reached = true;
      break;
    }
  }
  kill(pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  fclose(err);
  ASSERT_TRUE(reached) << seen;
  EXPECT_TRUE(WIFSIGNALED(status));
  EXPECT_FALSE(fs::exists(out / "result.h5"));
  EXPECT_FALSE(fs::exists(out / "frames.csv"));
  EXPECT_FALSE(fs::exists(out / "summary.json"));
  EXPECT_FALSE(fs::exists(out / "overlay.mp4"));
}

}  // namespace
}  // namespace tirstrain
