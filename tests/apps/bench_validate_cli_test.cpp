// `tirstrain bench --quick` and `tirstrain validate` through the real binary: the table and files they write,
// with numbers that are finite and in range (the figures themselves are in BENCHMARKS.md).
#include <H5Cpp.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/h5_file.hpp"
#include "tests/apps/cli_support.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;
using testing::fresh_dir;
using testing::run_cli;

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream in(line);
  std::string cell;
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(BenchCli, QuickRunWritesTheTableAndThePlot) {
  const std::string out = fresh_dir("bench_quick");
  const auto run = run_cli("bench --quick --configs default --out " + out);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("frames/s"), std::string::npos) << run.output;
  // The plot: an HTML page whose data holds this run's one point, tagged with the front it alone forms.
  const std::string page = read_text(out + "/bench.html");
  EXPECT_NE(page.find("<figure id=\"speed-error\""), std::string::npos);
  EXPECT_NE(page.find("\"config\":\"default\""), std::string::npos);
  EXPECT_NE(page.find("\"front\":true"), std::string::npos);
  std::ifstream csv(out + "/bench.csv");
  std::string header_line, row_line, extra;
  std::getline(csv, header_line);
  std::getline(csv, row_line);
  EXPECT_FALSE(std::getline(csv, extra) && !extra.empty()) << "one row expected";
  const std::vector<std::string> header = split(header_line), row = split(row_line);
  ASSERT_EQ(header.size(), row.size()) << row_line;
  const auto value = [&](const std::string& name) {
    for (std::size_t j = 0; j < header.size(); ++j)
      if (header[j] == name) return row[j];
    ADD_FAILURE() << "no column " << name;
    return std::string();
  };
  EXPECT_EQ(value("scene"), "quick");
  EXPECT_EQ(value("config"), "default");
  EXPECT_EQ(value("error"), "");
  for (const char* column :
       {"frames_per_s", "disp_rms_px", "strain_rms", "strain_rms_exx", "energy_err_pct", "peak_mb"}) {
    const double v = std::strtod(value(column).c_str(), nullptr);
    EXPECT_TRUE(std::isfinite(v) && v > 0.0) << column << " = " << v;
  }
  EXPECT_EQ(value("frames"), "12");
  // Displacement and strain errors of the automatic preset on this trial (measured 0.13 px and 0.007): well
  // below a pixel and 5 % strain.
  EXPECT_LT(std::strtod(value("disp_rms_px").c_str(), nullptr), 0.5);
  EXPECT_LT(std::strtod(value("strain_rms").c_str(), nullptr), 0.05);

  // The runs were made inside the staging folder; what they record names where they are now.
  EXPECT_EQ(read_text(out + "/runs/quick/default/repeat0/result/summary.json").find(".partial"),
            std::string::npos);

  // Unknown configuration names are errors, not silently skipped; the failed run leaves the earlier output
  // whole (its cached trial too) and no staging folder behind.
  const std::string earlier_csv = read_text(out + "/bench.csv");
  const auto bad = run_cli("bench --quick --configs fastest --out " + out);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("fastest"), std::string::npos) << bad.output;
  EXPECT_EQ(read_text(out + "/bench.csv"), earlier_csv);
  EXPECT_TRUE(fs::exists(fs::path(out) / "trials" / "quick" / "truth.h5"));
  EXPECT_FALSE(fs::exists(out + ".partial"));
}

TEST(BenchCli, GeneralisationSuiteWritesOneRowPerCaseTextureNoiseAndPreset) {
  // The chirp at its test size, the automatic preset: 2 textures x 2 noise levels = 4 rows.
  const std::string out = fresh_dir("bench_generalisation");
  const auto run = run_cli("bench --suite generalisation --quick --cases chirp --configs auto --out " + out);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("res_px"), std::string::npos) << run.output;
  std::ifstream csv(out + "/generalisation.csv");
  std::string header_line, line;
  std::getline(csv, header_line);
  const std::vector<std::string> header = split(header_line);
  int rows = 0;
  while (std::getline(csv, line)) {
    if (line.empty()) continue;
    ++rows;
    const std::vector<std::string> row = split(line);
    ASSERT_EQ(row.size(), header.size()) << line;
    EXPECT_EQ(row[0], "chirp") << line;
    EXPECT_EQ(row[3], "auto") << line;
  }
  EXPECT_EQ(rows, 4);
  EXPECT_TRUE(fs::exists(fs::path(out) / "generalisation_frames.csv"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "generalisation_chirp.csv"));

  const std::string earlier_csv = read_text(out + "/generalisation.csv");
  const auto bad_case = run_cli("bench --suite generalisation --quick --cases wobble --out " + out);
  EXPECT_EQ(bad_case.exit_code, 1);
  EXPECT_NE(bad_case.output.find("wobble"), std::string::npos) << bad_case.output;
  // The failed run leaves the earlier output whole and no staging folder behind.
  EXPECT_EQ(read_text(out + "/generalisation.csv"), earlier_csv);
  EXPECT_FALSE(fs::exists(out + ".partial"));
  // The folder is replaced as a whole: one holding anything else is refused, and nothing is deleted.
  std::ofstream(out + "/notes.txt") << "mine\n";
  const auto foreign =
      run_cli("bench --suite generalisation --quick --cases chirp --configs auto --out " + out);
  EXPECT_EQ(foreign.exit_code, 1);
  EXPECT_NE(foreign.output.find("notes.txt"), std::string::npos) << foreign.output;
  EXPECT_EQ(read_text(out + "/notes.txt"), "mine\n");
  fs::remove(out + "/notes.txt");
  const auto bad_config = run_cli("bench --suite generalisation --quick --configs fastest --out " + out);
  EXPECT_EQ(bad_config.exit_code, 1);
  EXPECT_NE(bad_config.output.find("fastest"), std::string::npos) << bad_config.output;
}

TEST(BenchCli, GeneralisationSequencesAsRecordingsThatProcessReads) {
  // The stretch at its test size written out as recordings (2 textures x 2 noise levels), each read back
  // by `process` with no scene: the fingerprint's ridges fill the frame, so every frame is in contact.
  const std::string out = fresh_dir("bench_recordings");
  const auto run = run_cli(
      "bench --suite generalisation --quick --cases stretch --configs auto --recordings --out " + out);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const fs::path recordings = fs::path(out) / "recordings";
  for (const char* name :
       {"stretch_speckle_0.5", "stretch_speckle_2", "stretch_fingerprint_0.5", "stretch_fingerprint_2"}) {
    EXPECT_TRUE(fs::exists(recordings / name / "frames.csv")) << name;
    EXPECT_EQ(std::distance(fs::directory_iterator(recordings / name / "frames"), fs::directory_iterator{}),
              6)
        << name;
  }
  const std::string result = fresh_dir("bench_recordings_process");
  const auto process = run_cli("process " + (recordings / "stretch_fingerprint_0.5").string() + " --out " +
                               result + " --overlay none");
  ASSERT_EQ(process.exit_code, 0) << process.output;
  EXPECT_NE(process.output.find("processed 6 frames (6 with contact)"), std::string::npos) << process.output;
  // scene init describes that contact as it is: no ellipse, cut by the frame.
  const std::string scene = fresh_dir("bench_recordings_scene.yaml");
  const auto init =
      run_cli("scene init " + (recordings / "stretch_fingerprint_0.5").string() + " --out " + scene);
  ASSERT_EQ(init.exit_code, 0) << init.output;
  EXPECT_NE(read_text(scene).find("(no ellipse: too little of its outline is inside the frame), cut by the "
                                  "frame's edge"),
            std::string::npos)
      << read_text(scene);
  // The speckle has no ridges: no contact, and the run says so rather than passing for a still skin.
  const std::string speckle = fresh_dir("bench_recordings_speckle");
  const auto none = run_cli("process " + (recordings / "stretch_speckle_0.5").string() + " --out " + speckle +
                            " --overlay none");
  ASSERT_EQ(none.exit_code, 0) << none.output;
  EXPECT_NE(none.output.find("processed 6 frames (0 with contact)"), std::string::npos) << none.output;
  EXPECT_NE(none.output.find("warning: no frame shows ridge texture in contact"), std::string::npos)
      << none.output;
  EXPECT_NE(read_text(speckle + "/summary.json").find("tirstrain track"), std::string::npos);
  // No triangle, so no strain energy: null, not a measured 0 J.
  EXPECT_NE(read_text(speckle + "/summary.json").find("\"strain_energy_max_J\": null"), std::string::npos)
      << read_text(speckle + "/summary.json");
  // U is the meshed area's only, which summary.json says beside it.
  EXPECT_NE(read_text(speckle + "/summary.json").find("the meshed triangles only: a lower bound"),
            std::string::npos);
  const std::string speckle_scene = fresh_dir("bench_recordings_speckle_scene.yaml");
  const auto speckle_init =
      run_cli("scene init " + (recordings / "stretch_speckle_0.5").string() + " --out " + speckle_scene);
  ASSERT_EQ(speckle_init.exit_code, 0) << speckle_init.output;
  EXPECT_NE(speckle_init.output.find("no contact seen"), std::string::npos) << speckle_init.output;
  EXPECT_NE(speckle_init.output.find("warning: no frame of 6 read shows ridge texture in contact"),
            std::string::npos)
      << speckle_init.output;
}

// The one data row of a bench.csv, by column name.
std::map<std::string, std::string> single_row(const std::string& csv_path) {
  std::ifstream csv(csv_path);
  std::string header_line, row_line;
  std::getline(csv, header_line);
  std::getline(csv, row_line);
  const std::vector<std::string> header = split(header_line), row = split(row_line);
  std::map<std::string, std::string> values;
  for (std::size_t j = 0; j < header.size() && j < row.size(); ++j) values[header[j]] = row[j];
  return values;
}

// A shipped 60-frame scene cut to `frames` frames, with `extra` YAML lines appended, written into `dir`.
fs::path shortened_scene(const fs::path& dir, const std::string& shipped, int frames,
                         const std::string& extra = "") {
  fs::create_directories(dir);
  const fs::path path = dir / "short.yaml";
  std::ifstream in(std::string(TIRSTRAIN_SOURCE_SCENES_DIR) + "/" + shipped + ".yaml");
  std::ofstream scene(path);
  std::string line;
  while (std::getline(in, line)) {
    const auto at = line.find("frames: 60");
    if (at != std::string::npos) line.replace(at, 10, "frames: " + std::to_string(frames));
    scene << line << "\n";
  }
  scene << extra;
  return path;
}

// `tirstrain bench --configs default` on a shipped 60-frame scene cut to `frames` frames (in a fresh
// directory `dir_name`); the one row of its bench.csv, empty if the run failed.
std::map<std::string, std::string> bench_shortened(const std::string& dir_name, const std::string& shipped,
                                                   int frames) {
  const std::string out = fresh_dir(dir_name);
  const fs::path scenes = shortened_scene(fs::path(out) / "scenes", shipped, frames).parent_path();
  const auto run = run_cli("bench --scenes-dir " + scenes.string() +
                           " --scenes short --configs default --out " + out + "/bench");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  if (run.exit_code != 0) return {};
  auto values = single_row(out + "/bench/bench.csv");
  EXPECT_EQ(values["frames"], std::to_string(frames)) << "the scene was not cut";
  return values;
}

TEST(BenchCli, NoiseFreeRigidTranslationReportsNearZeroError) {
  // The benchmark's error figures against a case whose answer is known: the shipped noise-free rigid
  // translation scene (12, −30) px, cut to 12 frames. A wrong reference, sign or frame pairing in the error
  // computation would show as errors of pixels and strains of percent; the truth here is zero strain and a
  // displacement any tracker follows to a few hundredths of a pixel (measured 0.046 px, strain 0.0022).
  auto values = bench_shortened("bench_rigid", "rigid_translation", 12);
  ASSERT_FALSE(values.empty());
  const auto number = [&](const char* column) { return std::strtod(values[column].c_str(), nullptr); };
  EXPECT_LT(number("disp_rms_px"), 0.1);
  EXPECT_GT(number("disp_rms_px"), 0.0);
  for (const char* column : {"strain_rms", "strain_rms_exx", "strain_rms_eyy", "strain_rms_exy"})
    EXPECT_LT(number(column), 0.005) << column;
  EXPECT_LT(number("plate_rms_px"), 0.05);
  // The contact does not move in the image; its ellipse centre and hull against the truth's (measured on the
  // 12 frames: 0.88 px RMS, worst IoU 0.975).
  EXPECT_LT(number("contact_centre_rms_px"), 1.2);
  EXPECT_GT(number("contact_iou_min"), 0.96);
  // No strain energy in a rigid motion: its relative error is undefined and says so.
  EXPECT_EQ(values["energy_err_pct"], "nan");
}

TEST(BenchCli, RigidRotationHasNoRelativeEnergyError) {
  // A 10° rotation: the true Green–Lagrange strain is zero, but computed from cos and sin it is rounding
  // (true energy ~1e-30 J), and relative to that the energy error read 1e28 %. Below the energy of a
  // uniform 1e-4 strain the relative error is not computed.
  auto values = bench_shortened("bench_rotation", "rigid_rotation", 6);
  ASSERT_FALSE(values.empty());
  EXPECT_LT(std::strtod(values["disp_rms_px"].c_str(), nullptr), 0.05);
  EXPECT_EQ(values["energy_err_pct"], "nan");
}

// `tirstrain validate` on a shortened shipped scene (with `extra` YAML appended): validation.csv's rms
// column by "quantity,reference,mode" (e.g. "displacement,tracks,", "U,same triangles,exact").
std::map<std::string, double> validate_shortened(const std::string& dir_name, const std::string& shipped,
                                                 int frames, const std::string& extra) {
  const std::string out = fresh_dir(dir_name);
  const fs::path scene = shortened_scene(fs::path(out) / "scene", shipped, frames, extra);
  const auto run = run_cli("validate --scene " + scene.string() + " --out " + out + "/v --quiet --no-maps");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  std::map<std::string, double> rms;
  std::ifstream csv(out + "/v/validation.csv");
  std::string line;
  std::getline(csv, line);
  while (std::getline(csv, line)) {
    const std::vector<std::string> cells = split(line);
    if (cells.size() > 4)
      rms[cells[0] + "," + cells[1] + "," + cells[2]] = std::strtod(cells[4].c_str(), nullptr);
  }
  return rms;
}

// A trial at 100 px/mm validated as a recording without a scene is processed (52 px/mm by default): the
// contact's area is judged in the pixels it was measured in (within 2 %, not the (100/52)^2 of the
// calibration), and the run says which rows still carry the result's own calibration.
TEST(ValidateCli, ProcessDefaultsJudgeTheMeasurementAndNameTheCalibration) {
  const std::string out = fresh_dir("validate_defaults");
  fs::create_directories(out);
  std::ofstream(out + "/scene.yaml")
      << "calibration: {px_per_mm: 100, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
         "synthesis:\n"
         "  seed: 9\n"
         "  image: {width_px: 320, height_px: 256, bit_depth: 8}\n"
         "  timing: {frames: 4, frame_rate_hz: 100}\n"
         "  contact: {shape: hertz, normal_N: 0.1, radius_m: 0.02}\n"
         "  loading: {field: affine, gradient: [0.04, 0.02, 0.0, -0.03]}\n"
         "  sensor: {read_noise: 0.005}\n";
  const auto run =
      run_cli("validate --scene " + out + "/scene.yaml --process-defaults --out " + out + "/v --no-maps");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("warning: the result was processed with px_per_mm 52 where the trial's is 100"),
            std::string::npos)
      << run.output;
  std::ifstream csv(out + "/v/validation.csv");
  std::string line;
  double area_rms_pct = -1.0;
  while (std::getline(csv, line)) {
    const std::vector<std::string> cells = split(line);
    if (cells.size() > 4 && cells[0] == "contact_area") area_rms_pct = std::strtod(cells[4].c_str(), nullptr);
  }
  EXPECT_GE(area_rms_pct, 0.0);
  EXPECT_LT(area_rms_pct, 2.0);
}

// A result is validated against its own trial only, and a validation shown beside its own result only:
// validate refuses a --result of another trial that is still there, and report a --validation that
// describes another result run (validation.json records which).
// Frames in which nothing was measured (here the trial's frames replaced by a flat grey, as a 16-bit video
// cut to 8 bits once gave): every row has 0 samples, which is a failure, not a validation.
TEST(ValidateCli, AResultWithNothingMeasuredIsAFailure) {
  const std::string out = fresh_dir("validate_nothing");
  const fs::path scene = shortened_scene(fs::path(out), "default", 3);
  const std::string trial = out + "/trial";
  ASSERT_EQ(run_cli("synth --scene " + scene.string() + " --out " + trial + " --quiet").exit_code, 0);
  const std::string flat = out + "/flat";
  fs::copy(trial, flat, fs::copy_options::recursive);
  for (const auto& entry : fs::directory_iterator(flat + "/frames")) {
    const cv::Mat image = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
    cv::imwrite(entry.path().string(), cv::Mat(image.size(), image.type(), cv::Scalar(100)));
  }
  ASSERT_EQ(run_cli("process " + flat + " --out " + out + "/r --overlay none --quiet").exit_code, 0);
  const auto v =
      run_cli("validate --trial " + flat + " --result " + out + "/r --out " + out + "/v --no-maps");
  EXPECT_EQ(v.exit_code, 1) << v.output;
  EXPECT_NE(v.output.find("nothing could be validated"), std::string::npos) << v.output;
}

TEST(ValidateCli, AResultAndAValidationOfAnotherTrialAreRefused) {
  const std::string out = fresh_dir("validate_provenance");
  std::string trials[2];
  const char* shipped[2] = {"default", "direction_radial"};
  for (int i = 0; i < 2; ++i) {
    const fs::path scene = shortened_scene(fs::path(out) / shipped[i], shipped[i], 4);
    trials[i] = out + "/" + shipped[i] + "/trial";
    ASSERT_EQ(run_cli("synth --scene " + scene.string() + " --out " + trials[i] + " --quiet").exit_code, 0);
    ASSERT_EQ(
        run_cli("process " + trials[i] + " --out " + trials[i] + "_result --overlay none --quiet").exit_code,
        0);
  }
  const auto other = run_cli("validate --trial " + trials[0] + " --result " + trials[1] + "_result --out " +
                             out + "/v_other --quiet --no-maps");
  EXPECT_EQ(other.exit_code, 1) << other.output;
  EXPECT_NE(other.output.find("is a result of the trial"), std::string::npos) << other.output;
  EXPECT_FALSE(fs::exists(out + "/v_other"));
  const auto own = run_cli("validate --trial " + trials[0] + " --result " + trials[0] + "_result --out " +
                           out + "/v0 --quiet --no-maps");
  ASSERT_EQ(own.exit_code, 0) << own.output;
  EXPECT_NE(read_text(out + "/v0/validation.json").find("\"result_run\""), std::string::npos);
  const auto mixed =
      run_cli("report " + trials[1] + "_result --validation " + out + "/v0 --out " + out + "/mixed.html");
  EXPECT_EQ(mixed.exit_code, 1) << mixed.output;
  EXPECT_NE(mixed.output.find("describes another result run"), std::string::npos) << mixed.output;
  EXPECT_FALSE(fs::exists(out + "/mixed.html"));
  const auto right =
      run_cli("report " + trials[0] + "_result --validation " + out + "/v0 --out " + out + "/right.html");
  EXPECT_EQ(right.exit_code, 0) << right.output;
}

TEST(ValidateCli, SmoothingInTimeOnNoisyTextureLowersTheErrors) {
  // The shipped heavy-noise scene (ridge SNR 1.9), its first 30 frames (rest, load, part of the
  // hold): the tracks smoothed in time, as the automatic preset does on noisy texture, against the same run
  // without. The strain stage runs again on the smoothed tracks, so the stick radius follows them (it
  // would not move otherwise). Measured: displacement 0.137 -> 0.109 px, c 9.0 -> 6.7 %, U 5.7 -> 4.9 %.
  auto smoothed = validate_shortened("validate_smoothed", "hard_heavy_noise", 30, "");
  auto raw =
      validate_shortened("validate_unsmoothed", "hard_heavy_noise", 30, "tracking: {smooth_in_time: off}\n");
  const std::string displacement = "displacement,tracks,", c = "stick_radius_c,model,",
                    u = "U,same triangles,exact";
  ASSERT_TRUE(smoothed.count(displacement) && raw.count(displacement) && smoothed.count(c) && raw.count(c));
  std::cout << "  hard_heavy_noise, 30 frames: displacement " << raw[displacement] << " -> "
            << smoothed[displacement] << " px, c error " << raw[c] << " -> " << smoothed[c] << " %, U error "
            << raw[u] << " -> " << smoothed[u] << " %\n";
  EXPECT_LT(smoothed[displacement], 0.88 * raw[displacement]);
  EXPECT_LT(smoothed[c], raw[c]);
  EXPECT_LT(smoothed[u], raw[u]);
  // summary.json says which run was smoothed.
  const auto summary_says = [](const std::string& dir, const std::string& text) {
    std::ifstream in(std::string(TIRSTRAIN_TEST_TMP) + "/" + dir + "/v/result/summary.json");
    const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return json.find(text) != std::string::npos;
  };
  EXPECT_TRUE(summary_says("validate_smoothed", "\"smoothed_in_time\": true"));
  EXPECT_TRUE(summary_says("validate_unsmoothed", "\"smoothed_in_time\": false"));
}

TEST(ValidateCli, NoisyAndLowContrastScenesMeetTheDisplacementTarget) {
  // The target for the noisy and low-contrast hard cases, end to end on the shipped 60-frame
  // scenes: displacement RMS over every alive track and frame <= 0.10 px. Measured 0.0931 and 0.0983 px
  // (the same to every digit in the Release and the sanitizer build); 0.136 / 0.148 px before the tracks
  // were smoothed in time.
  for (const char* scene : {"hard_heavy_noise", "hard_low_contrast"}) {
    auto rms = validate_shortened(std::string("target_") + scene, scene, 60, "");
    ASSERT_TRUE(rms.count("displacement,tracks,")) << scene;
    std::cout << "  " << scene << ": displacement " << rms["displacement,tracks,"] << " px RMS, U error "
              << rms["U,same triangles,exact"] << " %, c error " << rms["stick_radius_c,model,"] << " %\n";
    EXPECT_LE(rms["displacement,tracks,"], 0.10) << scene;
  }
}

// The default scene cut to `frames` frames, synthesised into DIR/trial (its scene in DIR/scene.yaml).
void synth_default_cut(const std::string& dir, int frames, const std::string& read_noise = "") {
  fs::create_directories(dir);
  std::string scene = read_text(std::string(TIRSTRAIN_SOURCE_SCENES_DIR) + "/default.yaml");
  const std::size_t at = scene.find("frames: 60");
  ASSERT_NE(at, std::string::npos);
  scene.replace(at, 10, "frames: " + std::to_string(frames));
  if (!read_noise.empty()) {
    const std::size_t noise = scene.find("read_noise: 0.006");
    ASSERT_NE(noise, std::string::npos);
    scene.replace(noise, 17, "read_noise: " + read_noise);
  }
  std::ofstream(dir + "/scene.yaml") << scene;
  ASSERT_EQ(run_cli("synth --scene " + dir + "/scene.yaml --out " + dir + "/trial --quiet").exit_code, 0);
}

// `--threads` sets how many threads the image loops use (trials side by side in a study run one each); the
// result is the same to the last bit whatever the count: each track's work is done by one thread.
TEST(ProcessCli, ThreadCountChangesNothingButTheTime) {
  const std::string dir = fresh_dir("process_threads");
  ASSERT_NO_FATAL_FAILURE(synth_default_cut(dir, 8));
  for (const char* threads : {"1", "2"}) {
    const auto run = run_cli(std::string("--threads ") + threads + " process " + dir + "/trial --out " + dir +
                             "/result_" + threads + " --overlay none --quiet");
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }
  const H5Reader one(dir + "/result_1/result.h5"), two(dir + "/result_2/result.h5");
  for (const char* name :
       {"/tracks/position_px", "/strain/total", "/contact/ellipse", "/plate/displacement_px"}) {
    const std::vector<double> a = one.read_doubles(name), b = two.read_doubles(name);
    ASSERT_EQ(a.size(), b.size()) << name;
    ASSERT_GT(a.size(), 8u) << name;
    int differing = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
      differing += !(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i])));
    EXPECT_EQ(differing, 0) << name;
  }
  EXPECT_EQ(run_cli("--threads -1 process " + dir + "/trial --out " + dir + "/bad").exit_code, 2);
  EXPECT_FALSE(fs::exists(dir + "/bad"));
}

// `process` with the fit stage on the default trial cut to 16 frames (six at rest, then partial slip to
// Q = 0.99 μP): the fitted tangential force and stick radius against the trial's true load, and the same fit
// as `tirstrain fit` on the result, the second pass at the trial's μP included.
TEST(ProcessCli, FitStageRecoversTheLoadAndMatchesTheFitCommand) {
  constexpr std::size_t kFrames = 16;
  const std::string dir = fresh_dir("process_fit_stage");
  ASSERT_NO_FATAL_FAILURE(synth_default_cut(dir, kFrames));
  const auto run =
      run_cli("process " + dir + "/trial --out " + dir + "/result --compute fit --overlay none --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto fit = run_cli("fit " + dir + "/result --out " + dir + "/fit --quiet");
  ASSERT_EQ(fit.exit_code, 0) << fit.output;

  const H5Reader result(dir + "/result/result.h5"), truth(dir + "/trial/truth.h5"),
      alone(dir + "/fit/fit.h5");
  const std::vector<double> q_fit = result.read_doubles("/fit/tangential_N");
  const std::vector<double> q_true = truth.read_doubles("/load/tangential_N");
  const std::vector<double> p_true = truth.read_doubles("/load/normal_N");
  const std::vector<double> c_fit = result.read_doubles("/fit/c_mm"),
                            a_fit = result.read_doubles("/fit/a_mm");
  const std::vector<double> c_true = truth.read_doubles("/load/stick_radius_m");
  ASSERT_EQ(q_fit.size(), kFrames);
  ASSERT_EQ(q_true.size(), kFrames);
  int loaded = 0;
  double c_sum2 = 0.0;
  for (std::size_t i = 0; i < q_fit.size(); ++i) {
    const double mu_p = 1.0 * p_true[i];  // the scene's friction is 1
    if (q_true[i] == 0.0 && std::isfinite(q_fit[i])) {
      EXPECT_LE(std::abs(q_fit[i]), 0.02 * mu_p) << "frame " << i;  // measured <= 0.0002 muP
    }
    if (q_true[i] > 0.1 * mu_p && q_true[i] < 0.95 * mu_p) {
      ++loaded;
      ASSERT_TRUE(std::isfinite(q_fit[i])) << "frame " << i;
      EXPECT_LE(std::abs(q_fit[i] - q_true[i]), 0.05 * mu_p) << "frame " << i;  // measured <= 0.036 muP
      const double c_error = (c_fit[i] - 1e3 * c_true[i]) / a_fit[i];
      EXPECT_LE(std::abs(c_error), 0.04) << "frame " << i;  // measured <= 0.027 a
      c_sum2 += c_error * c_error;
    }
  }
  EXPECT_GE(loaded, 8);
  EXPECT_LE(std::sqrt(c_sum2 / loaded), 0.03);  // issue 41's target for c; measured 0.011 a
  // The trial's μP was measured and held in the frames below the limit, which say so.
  EXPECT_NEAR(result.attribute_number("/fit", "trial_limit_N"), 1.0 * p_true.back(), 0.02 * p_true.back());
  const std::vector<std::int64_t> from_trial = result.read_integers("/fit/limit_from_trial");
  EXPECT_GE(std::count(from_trial.begin(), from_trial.end(), 1), 8);
  // The stage and the command fit the same tracks and ellipses: the same numbers.
  for (const char* name : {"/fit/tangential_N", "/fit/c_mm", "/fit/direction_deg", "/fit/model",
                           "/fit/c_mm_sd", "/fit/limit_from_trial", "/fit/tracked_radius", "/fit/limit_N"}) {
    const std::vector<double> a = result.read_doubles(name), b = alone.read_doubles(name);
    ASSERT_EQ(a.size(), b.size()) << name;
    for (std::size_t i = 0; i < a.size(); ++i)
      EXPECT_TRUE(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i]))) << name << " frame " << i;
  }
  std::ifstream summary_file(dir + "/result/summary.json");
  const std::string summary((std::istreambuf_iterator<char>(summary_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(summary.find("\"frames_by_model\""), std::string::npos);
  EXPECT_NE(read_text(dir + "/result/frames.csv").find("fit_tangential_N"), std::string::npos);
}

// A result processed without a scene has process's default calibration and tissue: fit says its loads and
// radii scale with them; with the trial's scene it says nothing of the kind.
TEST(ProcessCli, FitOfAResultWithDefaultCalibrationSaysSo) {
  const std::string dir = fresh_dir("fit_defaults");
  ASSERT_NO_FATAL_FAILURE(synth_default_cut(dir, 8));
  for (const char* how : {" --no-scene", ""}) {
    const std::string result = dir + (*how ? "/defaults" : "/scene");
    ASSERT_EQ(
        run_cli("process " + dir + "/trial --out " + result + " --overlay none --quiet" + how).exit_code, 0);
    const auto fit = run_cli("fit " + result + " --out " + result + "_fit --quiet");
    ASSERT_EQ(fit.exit_code, 0) << fit.output;
    EXPECT_EQ(fit.output.find("processed without a scene") != std::string::npos, *how != '\0') << fit.output;
  }
}

// On noisy texture the tracking stage smooths its tracks in time after the trial and the later stages run
// again over the revised tracks: the fit stage still sees each frame's contact (it fitted none before) and
// gives the numbers `tirstrain fit` gives.
TEST(ProcessCli, FitStageAfterTheTracksAreRevisedMatchesTheFitCommand) {
  const std::string dir = fresh_dir("process_fit_revised");
  ASSERT_NO_FATAL_FAILURE(synth_default_cut(dir, 10, "0.03"));
  const auto run = run_cli("process " + dir + "/trial --out " + dir + "/result --compute fit --overlay none");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  ASSERT_NE(run.output.find("tracking revised"), std::string::npos) << run.output;
  ASSERT_EQ(run_cli("fit " + dir + "/result --out " + dir + "/fit --quiet").exit_code, 0);
  const H5Reader result(dir + "/result/result.h5"), alone(dir + "/fit/fit.h5");
  const std::vector<std::int64_t> status = result.read_integers("/fit/status");
  EXPECT_EQ(std::count(status.begin(), status.end(), 0), static_cast<long>(status.size()));
  for (const char* name : {"/fit/tangential_N", "/fit/c_mm", "/fit/model", "/fit/limit_N"}) {
    const std::vector<double> a = result.read_doubles(name), b = alone.read_doubles(name);
    ASSERT_EQ(a.size(), b.size()) << name;
    for (std::size_t i = 0; i < a.size(); ++i)
      EXPECT_TRUE(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i]))) << name << " frame " << i;
  }
}

TEST(ValidateCli, ComparesAnExistingTrialAndNamesMissingInputs) {
  const std::string out = fresh_dir("validate_cli");
  // The quick benchmark's cached trial is a real synthesised trial folder.
  const std::string trial = fresh_dir("bench_quick_trial");
  const auto synth = run_cli("bench --quick --configs default --out " + trial);
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const auto run = run_cli("validate --trial " + trial + "/trials/quick --out " + out + " --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* name :
       {"validation.csv", "validation_frames.csv", "maps_E_xx.png", "maps_E_yy.png", "maps_E_xy.png"})
    EXPECT_TRUE(fs::exists(fs::path(out) / name)) << name;
  EXPECT_NE(run.output.find("E_xx"), std::string::npos) << run.output;

  // The paths the result records name where the files are, not the staging folder they were built in.
  EXPECT_EQ(read_text(out + "/result/summary.json").find(".partial"), std::string::npos);

  // A failed rerun leaves the earlier output whole and no staging folder behind.
  const std::string earlier_csv = read_text(out + "/validation.csv");
  const std::string empty_result = fresh_dir("validate_cli_empty_result");
  fs::create_directories(empty_result);
  const auto failed = run_cli("validate --trial " + trial + "/trials/quick --result " + empty_result +
                              " --out " + out + " --quiet");
  EXPECT_EQ(failed.exit_code, 1) << failed.output;
  EXPECT_NE(failed.output.find("result.h5"), std::string::npos) << failed.output;
  EXPECT_EQ(read_text(out + "/validation.csv"), earlier_csv);
  EXPECT_FALSE(fs::exists(out + ".partial"));
  // An output folder holding the input, or anything validate does not write, is refused (the swap would
  // delete it).
  const auto holds_input = run_cli("validate --trial " + trial + "/trials/quick --out " + trial + " --quiet");
  EXPECT_EQ(holds_input.exit_code, 1);
  EXPECT_NE(holds_input.output.find("contains the --trial input"), std::string::npos) << holds_input.output;
  EXPECT_TRUE(fs::exists(fs::path(trial) / "trials" / "quick" / "truth.h5"));
  std::ofstream(out + "/notes.txt") << "mine\n";
  const auto foreign = run_cli("validate --trial " + trial + "/trials/quick --out " + out + " --quiet");
  EXPECT_EQ(foreign.exit_code, 1);
  EXPECT_NE(foreign.output.find("notes.txt"), std::string::npos) << foreign.output;
  fs::remove(out + "/notes.txt");

  // A map frame past the trial's last (the quick trial has 12 frames) is named, not replaced by the last.
  const auto past =
      run_cli("validate --trial " + trial + "/trials/quick --result " + out +
              "/result --no-maps --map-frame 999 --out " + fresh_dir("validate_cli_map") + " --quiet");
  EXPECT_EQ(past.exit_code, 2) << past.output;
  EXPECT_NE(past.output.find("--map-frame"), std::string::npos) << past.output;
  EXPECT_NE(past.output.find("past the trial's last frame"), std::string::npos) << past.output;
  EXPECT_EQ(run_cli("validate --trial " + trial + "/trials/quick --map-frame -3 --out " + out).exit_code, 2);

  const auto neither = run_cli("validate --out " + out);
  EXPECT_EQ(neither.exit_code, 2);
  EXPECT_NE(neither.output.find("--scene"), std::string::npos) << neither.output;
  const auto not_a_trial = run_cli("validate --trial " + out + " --out " + out + "/x");
  EXPECT_EQ(not_a_trial.exit_code, 1);
  EXPECT_NE(not_a_trial.output.find("scene.yaml"), std::string::npos) << not_a_trial.output;

  // The truth is recomputed from the trial's scene: one edited since synthesis (here the pattern band two
  // rows shorter, which moves the contact's centre the truth is built around by one row) is refused with the
  // quantity that no longer matches truth.h5, and nothing is written.
  const std::string edited = fresh_dir("validate_cli_edited_trial");
  fs::copy(fs::path(trial) / "trials" / "quick", edited, fs::copy_options::recursive);
  std::string scene = read_text(edited + "/scene.yaml");
  const std::size_t roi = scene.find("roi_px: [0, 0, 640, 56]");
  ASSERT_NE(roi, std::string::npos) << scene;
  scene.replace(roi, std::string("roi_px: [0, 0, 640, 56]").size(), "roi_px: [0, 0, 640, 54]");
  std::ofstream(edited + "/scene.yaml") << scene;
  const std::string edited_out = fresh_dir("validate_cli_edited_out");
  const auto refused = run_cli("validate --trial " + edited + " --out " + edited_out + " --quiet");
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.output.find("differs from the scene its frames were made with"), std::string::npos)
      << refused.output;
  EXPECT_NE(refused.output.find("--process-scene"), std::string::npos) << refused.output;
  EXPECT_FALSE(fs::exists(edited_out));
  // Any edit, also one no recorded quantity depends on (the plate's speed), and a trial without truth.h5.
  std::string slower = read_text(fs::path(trial) / "trials" / "quick" / "scene.yaml");
  const std::size_t speed = slower.find("plate_speed_mm_s: ");
  ASSERT_NE(speed, std::string::npos) << slower;
  slower.insert(speed + std::string("plate_speed_mm_s: ").size(), "1");
  std::ofstream(edited + "/scene.yaml") << slower;
  const auto speed_edit = run_cli("validate --trial " + edited + " --out " + edited_out + " --quiet");
  EXPECT_EQ(speed_edit.exit_code, 1) << speed_edit.output;
  EXPECT_NE(speed_edit.output.find("differs from the scene"), std::string::npos) << speed_edit.output;
  fs::copy_file(fs::path(trial) / "trials" / "quick" / "scene.yaml", edited + "/scene.yaml",
                fs::copy_options::overwrite_existing);
  fs::remove(edited + "/truth.h5");
  const auto no_truth = run_cli("validate --trial " + edited + " --out " + edited_out + " --quiet");
  EXPECT_EQ(no_truth.exit_code, 1) << no_truth.output;
  EXPECT_NE(no_truth.output.find("no truth.h5"), std::string::npos) << no_truth.output;
  EXPECT_FALSE(fs::exists(edited_out));

  // A result of another trial (frames of another size) is refused before anything is compared.
  const std::string other = fresh_dir("validate_cli_other_result");
  fs::copy(out + "/result", other, fs::copy_options::recursive);
  {
    H5::H5File h5(other + "/result.h5", H5F_ACC_RDWR);
    const double width_px = 480.0;
    h5.openGroup("/frames").openAttribute("width_px").write(H5::PredType::NATIVE_DOUBLE, &width_px);
  }
  const auto mismatch = run_cli("validate --trial " + trial + "/trials/quick --result " + other + " --out " +
                                fresh_dir("validate_cli_other_out") + " --quiet");
  EXPECT_EQ(mismatch.exit_code, 1) << mismatch.output;
  EXPECT_NE(mismatch.output.find("480 x 512 px but the trial's 640 x 512: a result of another trial"),
            std::string::npos)
      << mismatch.output;
}

}  // namespace
}  // namespace tirstrain

namespace tirstrain {
namespace {

TEST(LiveCli, HeadlessViewRunsTheScenesStages) {
  const std::string dir = testing::fresh_dir("live_trial");
  const auto synth = testing::run_cli("bench --quick --configs default --out " + dir);
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string trial = dir + "/trials/quick";
  const auto run =
      testing::run_cli("live " + trial + " --scene " + trial + "/scene.yaml --no-window --frames 12 --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("12 frames received"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("analysis stages: contact, tracking, strain"), std::string::npos) << run.output;
  // At least the first frame is analysed (the display thread takes the newest frame when it is free).
  EXPECT_EQ(run.output.find("(0 frames analysed)"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace tirstrain
