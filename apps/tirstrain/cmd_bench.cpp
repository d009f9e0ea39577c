// `tirstrain bench`: speed against error. Every configuration processes the same synthesised trials (exact
// truth) in a child process (`tirstrain validate`), so each row has its own wall time and peak memory;
// frames/s is the median over repeats, errors are measured against the truth.
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fcntl.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/median.hpp"
#include "core/yaml_reader.hpp"
#include "pipeline/generalisation.hpp"
#include "report/speed_error_page.hpp"
#include "samples/generalisation.hpp"
#include "tirstrain/commands.hpp"

extern char** environ;

namespace tirstrain::cli {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Config {
  std::string name;
  std::string tracking;      // YAML map merged into the scene's tracking: section
  std::string segmentation;  // YAML map for the segmentation: section
};

// The presets and a sweep of the settings that matter, each changing one thing from the automatic default.
const std::vector<Config>& all_configs() {
  static const std::vector<Config> configs = {
      {"delhaye2016", "{preset: delhaye2016}", ""},
      {"default", "{preset: auto}", ""},
      {"auto_window_15", "{preset: auto, window_px: 15}", ""},
      {"auto_window_41", "{preset: auto, window_px: 41}", ""},
      {"auto_levels_0", "{preset: auto, pyramid_levels: 0}", ""},
      {"auto_levels_3", "{preset: auto, pyramid_levels: 3}", ""},
      {"auto_grid_6", "{preset: auto, grid_step_px: 6}", ""},
      {"auto_grid_12", "{preset: auto, grid_step_px: 12}", ""},
      {"auto_cap_1000", "{preset: auto, max_features: 1000}", ""},
      {"auto_affine", "{preset: auto, refine: affine}", ""},
      {"auto_subset_9", "{preset: auto, subset_radius_px: 9}", ""},
      {"auto_segment_full_res", "{preset: auto}", "{downsample: 1}"},
      {"auto_segment_balanced", "{preset: auto}", "{preset: balanced}"},
      {"auto_segment_fast", "{preset: auto}", "{preset: fast}"},
  };
  return configs;
}

struct Row {
  std::string scene, config, error;
  int frames = 0;
  double frames_per_s = kNaN, contact_ms = kNaN, track_ms = kNaN, strain_ms = kNaN, peak_mb = kNaN;
  double tracks_mean = kNaN, disp_rms_px = kNaN, strain_rms[3] = {kNaN, kNaN, kNaN}, strain_rms_all = kNaN;
  double energy_err_pct = kNaN, plate_rms_px = kNaN;
  double contact_centre_rms_px = kNaN, contact_iou_min = kNaN;  // ellipse centre, hull against the truth
  // Coverage of the true contact by valid strain (mean and worst frame, %), and by ring of r/a
  // (pipeline/validate_rings.hpp): coverage %, displacement RMS (px), strain RMS (pooled components).
  double coverage_pct = kNaN, coverage_min_pct = kNaN;
  std::map<std::string, double> ring_coverage_pct, ring_disp_px, ring_strain;
  double c_of_a_rms_pct = kNaN;  // stick radius c against the model, in % of the contact radius
};

std::string self_exe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("cannot find the tirstrain executable (/proc/self/exe): " + ec.message());
  return p.string();
}

// Runs `tirstrain ARGS...`, returns the exit code and the child's peak resident memory (MB).
int run_child(const std::vector<std::string>& args, const std::string& log_path, double* peak_mb) {
  std::vector<char*> argv;
  const std::string exe = self_exe();
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) throw Error("cannot start " + exe + ": " + std::strerror(spawned));
  int status = 0;
  rusage usage{};
  if (wait4(pid, &status, 0, &usage) < 0) throw Error("wait for the benchmark child failed");
  *peak_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A free-text cell without the separators that would split it.
std::string csv_safe(std::string text) {
  std::replace(text.begin(), text.end(), ',', ';');
  std::replace(text.begin(), text.end(), '"', '\'');
  return text;
}

std::string tail_of(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

// validation.csv → the numbers a row needs.
// validation.csv's coverage and ring rows (cells: quantity, reference, mode, unit, rms, max_abs, mean, n).
void read_ring_row(const std::string& q, const std::vector<std::string>& cells, Row& row) {
  const auto number = [&](std::size_t i) { return std::strtod(cells[i].c_str(), nullptr); };
  const auto suffix = [&](const std::string& prefix) {
    return q.rfind(prefix, 0) == 0 ? q.substr(prefix.size()) : std::string();
  };
  if (q == "coverage_deficit_contact") {
    row.coverage_pct = 100.0 - number(6);
    row.coverage_min_pct = 100.0 - number(5);
  } else if (const std::string ring = suffix("coverage_deficit_ring_"); !ring.empty()) {
    row.ring_coverage_pct[ring] = 100.0 - number(6);
  } else if (const std::string ring_d = suffix("displacement_ring_"); !ring_d.empty()) {
    row.ring_disp_px[ring_d] = number(4);
  } else if (q == "stick_radius_c_of_a") {
    row.c_of_a_rms_pct = number(4);
  } else {
    for (const char* component : {"E_xx_ring_", "E_yy_ring_", "E_xy_ring_"})
      if (const std::string ring_e = suffix(component); !ring_e.empty()) {
        const double rms = number(4);
        row.ring_strain[ring_e] += std::isfinite(rms) ? rms * rms : rms;
      }
  }
}

void read_validation(const fs::path& dir, Row& row) {
  std::ifstream in(dir / "validation.csv");
  std::string line;
  std::getline(in, line);
  double sum2 = 0.0;
  int components = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      cells.push_back(line.substr(start, comma - start));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    if (cells.size() < 8) continue;
    const std::string& q = cells[0];
    const std::string& reference = cells[1];
    const std::string& mode = cells[2];
    const double rms = std::strtod(cells[4].c_str(), nullptr);
    if (reference == "point" && mode == "exact") {
      for (int c = 0; c < 3; ++c)
        if (q == std::vector<std::string>{"E_xx", "E_yy", "E_xy"}[static_cast<std::size_t>(c)]) {
          row.strain_rms[c] = rms;
          sum2 += rms * rms;
          ++components;
        }
    }
    if (q == "displacement" && reference == "tracks") row.disp_rms_px = rms;
    if (q == "plate_displacement") row.plate_rms_px = rms;
    if (q == "U" && mode == "exact") row.energy_err_pct = rms;
    if (q == "contact_centre") row.contact_centre_rms_px = rms;
    if (q == "contact_1-IoU") row.contact_iou_min = 1.0 - std::strtod(cells[5].c_str(), nullptr);
    read_ring_row(q, cells, row);
  }
  for (auto& [ring, sum2] : row.ring_strain) sum2 = std::sqrt(sum2 / 3.0);
  if (components == 3) row.strain_rms_all = std::sqrt(sum2 / 3.0);
}

// The scene the configuration processes with: the trial's own plus the configuration's sections.
std::string write_config_scene(const fs::path& trial, const Config& config, const fs::path& out) {
  SceneSection scene = SceneSection::load((trial / "scene.yaml").string());
  scene = scene.with("tracking", SceneSection::parse(config.tracking, "bench configuration"));
  if (!config.segmentation.empty())
    scene = scene.with("segmentation", SceneSection::parse(config.segmentation, "bench configuration"));
  write_text_file(out.string(), scene.to_yaml() + "\n");
  return out.string();
}

// The speed-against-error plot as an HTML page (Vega-Lite, report/speed_error_page.hpp).
void write_plot(const std::vector<Row>& rows, const std::string& path) {
  std::vector<report::SpeedErrorPoint> points;
  for (const Row& r : rows) points.push_back({r.scene, r.config, r.frames_per_s, r.strain_rms_all});
  AtomicFile out(path);
  out.append(report::speed_error_page(points, ""));
  out.commit();
}

void print_generalisation_header() {
  std::printf("%-15s %-11s %6s %-11s %6s %8s %8s %8s %8s %6s %8s %7s %7s %8s %8s %4s %6s %8s\n", "case",
              "texture", "noise%", "preset", "alive", "rms_px", "edge_px", "bias_px", "max_px", ">1px",
              "res_px", "res_r", "gain_l", "long_px", "long_u", "rest", "affine", "ms/frame");
}

// The chirp's resolution: its wavelength, or ">L" when not even the longest window L reaches the gain.
std::string resolution_cell(const pipeline::GeneralisationResult& r) {
  char text[32];
  if (std::isfinite(r.resolution_px))
    std::snprintf(text, sizeof text, "%.1f", r.resolution_px);
  else if (std::isfinite(r.longest_wavelength_px))
    std::snprintf(text, sizeof text, ">%.0f", r.longest_wavelength_px);
  else
    std::snprintf(text, sizeof text, "-");
  return text;
}

void print_generalisation_row(const pipeline::GeneralisationResult& r) {
  std::printf(
      "%-15s %-11s %6.1f %-11s %6.0f %8.4f %8.4f %8.4f %8.3f %6d %8s %7.2f %7.3f %8.4f %8.4f %4d %6d %8.1f\n",
      r.field.c_str(), r.texture.c_str(), 100.0 * r.noise_fraction, r.preset.c_str(), r.alive_mean, r.rms_px,
      r.edge_rms_px, r.bias_px, r.max_px, r.over_1px, resolution_cell(r).c_str(), r.resolution_radii,
      r.longest_gain, r.long_wave_rms_px, r.long_wave_u_rms_px, r.rest_frames, r.affine_fit_frames,
      r.ms_per_frame);
  std::fflush(stdout);
}

void write_generalisation_csv(const std::vector<pipeline::GeneralisationResult>& results,
                              const fs::path& out) {
  static const std::vector<std::string> columns = {"case",
                                                   "texture",
                                                   "noise_fraction",
                                                   "preset",
                                                   "width_px",
                                                   "height_px",
                                                   "frames",
                                                   "seeded",
                                                   "alive_mean",
                                                   "rms_px",
                                                   "edge_rms_px",
                                                   "interior_rms_px",
                                                   "edge_band_px",
                                                   "bias_px",
                                                   "max_px",
                                                   "over_1px",
                                                   "radius_px",
                                                   "resolution_px",
                                                   "resolution_radii",
                                                   "longest_wavelength_px",
                                                   "longest_gain",
                                                   "long_wave_rms_px",
                                                   "long_wave_u_rms_px",
                                                   "rest_frames",
                                                   "affine_fit_frames",
                                                   "ms_per_frame"};
  CsvWriter summary((out / "generalisation.csv").string(), columns);
  for (const pipeline::GeneralisationResult& r : results)
    summary.row_text({r.field,
                      r.texture,
                      format_double(r.noise_fraction),
                      r.preset,
                      std::to_string(r.width_px),
                      std::to_string(r.height_px),
                      std::to_string(r.frames),
                      std::to_string(r.seeded),
                      format_double(r.alive_mean),
                      format_double(r.rms_px),
                      format_double(r.edge_rms_px),
                      format_double(r.interior_rms_px),
                      format_double(r.edge_band_px),
                      format_double(r.bias_px),
                      format_double(r.max_px),
                      std::to_string(r.over_1px),
                      format_double(r.radius_px),
                      format_double(r.resolution_px),
                      format_double(r.resolution_radii),
                      format_double(r.longest_wavelength_px),
                      format_double(r.longest_gain),
                      format_double(r.long_wave_rms_px),
                      format_double(r.long_wave_u_rms_px),
                      std::to_string(r.rest_frames),
                      std::to_string(r.affine_fit_frames),
                      format_double(r.ms_per_frame)});
  summary.commit();
  CsvWriter frames((out / "generalisation_frames.csv").string(),
                   {"case", "texture", "noise_fraction", "preset", "frame", "alive", "rms_px", "bias_x_px",
                    "bias_y_px", "max_px", "at_rest", "affine_fit", "affine_hidden_px", "track_ms"});
  for (const pipeline::GeneralisationResult& r : results)
    for (const pipeline::GeneralisationFrame& f : r.per_frame)
      frames.row_text({r.field, r.texture, format_double(r.noise_fraction), r.preset, std::to_string(f.frame),
                       std::to_string(f.alive), format_double(f.rms_px), format_double(f.bias_px.x),
                       format_double(f.bias_px.y), format_double(f.max_px), f.at_rest ? "1" : "0",
                       f.affine_fit ? "1" : "0", format_double(f.affine_hidden_px),
                       format_double(f.track_ms)});
  frames.commit();
  CsvWriter chirp(
      (out / "generalisation_chirp.csv").string(),
      {"texture", "noise_fraction", "preset", "centre_px", "wavelength_px", "gain", "quadrature", "tracks"});
  for (const pipeline::GeneralisationResult& r : results)
    for (const pipeline::ChirpWindow& w : r.chirp.windows)
      chirp.row_text({r.texture, format_double(r.noise_fraction), r.preset, format_double(w.centre_px),
                      format_double(w.wavelength_px), format_double(w.gain), format_double(w.quadrature),
                      std::to_string(w.tracks)});
  chirp.commit();
}

// A sequence as a recording `tirstrain process` or `track` reads: OUT/recordings/CASE_TEXTURE_NOISE/ with
// frames/NNNNNN.png (16-bit) and frames.csv (index, t_s at 100 frames/s), no scene.
void write_recording(const fs::path& out, const samples::GeneralisationCase& sequence,
                     const std::vector<cv::Mat>& frames) {
  const samples::GeneralisationConfig& c = sequence.config();
  char name[96];
  std::snprintf(name, sizeof name, "%s_%s_%g", samples::to_string(c.field).c_str(),
                samples::to_string(c.texture).c_str(), 100.0 * c.noise_fraction);
  const fs::path dir = out / "recordings" / name;
  fs::create_directories(dir / "frames");
  CsvWriter times((dir / "frames.csv").string(), {"index", "t_s"});
  for (std::size_t k = 0; k < frames.size(); ++k) {
    char file[32];
    std::snprintf(file, sizeof file, "%06zu.png", k);
    if (!cv::imwrite((dir / "frames" / file).string(), frames[k]))
      throw Error("cannot write the frame", {.file = (dir / "frames" / file).string()});
    times.row_text({std::to_string(k), format_double(0.01 * static_cast<double>(k))});
  }
  times.commit();
}

// `--suite generalisation`: the tracker alone on exact-truth textures and fields it was not tuned on.
void run_generalisation_bench(const fs::path& out, bool quick, const std::vector<std::string>& presets,
                              const std::vector<std::string>& cases, bool recordings) {
  pipeline::GeneralisationSuite suite;
  if (recordings)
    suite.on_sequence = [&out](const samples::GeneralisationCase& sequence,
                               const std::vector<cv::Mat>& frames) {
      write_recording(out, sequence, frames);
    };
  suite.small = quick;
  if (!presets.empty()) suite.presets = presets;
  if (!cases.empty()) {
    suite.fields.clear();
    for (const std::string& name : cases)
      suite.fields.push_back(samples::generalisation_field_from_string(name));
  }
  for (const std::string& p : suite.presets)
    pipeline::generalisation_settings(p);  // unknown names throw here
  print_generalisation_header();
  const std::vector<pipeline::GeneralisationResult> results =
      pipeline::run_generalisation_suite(suite, print_generalisation_row);
  write_generalisation_csv(results, out);
  std::cerr << "bench: wrote generalisation.csv, generalisation_frames.csv and generalisation_chirp.csv\n";
}

// The files and folders a bench run writes into its output folder.
const std::vector<std::string>& bench_output_names() {
  static const std::vector<std::string> names = {"bench.csv",
                                                 "bench.html",
                                                 "bench.png",  // written by earlier versions: replaceable
                                                 "runs",
                                                 "trials",
                                                 "generalisation.csv",
                                                 "generalisation_frames.csv",
                                                 "generalisation_chirp.csv",
                                                 "recordings"};
  return names;
}

// The trials an earlier run synthesised (OUT/trials), reused by this one: hard links into the staging
// folder, so the earlier output stays whole until the swap (trial files are replaced, never modified in
// place); a copy where links cannot be made.
void carry_over_trials(const fs::path& earlier_out, const fs::path& staging) {
  std::error_code ec;
  const fs::path trials = earlier_out / "trials";
  if (!fs::is_directory(trials, ec)) return;
  fs::copy(trials, staging / "trials", fs::copy_options::recursive | fs::copy_options::create_hard_links, ec);
  if (!ec) return;
  fs::remove_all(staging / "trials", ec);
  fs::copy(trials, staging / "trials", fs::copy_options::recursive, ec);
  if (ec) throw Error("cannot reuse the earlier run's trials: " + ec.message(), {.file = trials.string()});
}

struct BenchArgs {
  std::string out = "bench-output", scenes_dir = TIRSTRAIN_SCENES_DIR, suite = "pipeline";
  std::vector<std::string> scenes, configs, cases;
  int repeats = 3;
  bool quick = false, fresh = false, recordings = false;
};

// The configurations named (all when none is), refusing an unknown name.
std::vector<Config> select_configs(const std::vector<std::string>& names) {
  std::vector<Config> configs;
  for (const Config& c : all_configs())
    if (names.empty() || std::find(names.begin(), names.end(), c.name) != names.end()) configs.push_back(c);
  for (const std::string& name : names)
    if (std::none_of(configs.begin(), configs.end(), [&](const Config& c) { return c.name == name; }))
      throw Error("unknown configuration '" + name + "'");
  return configs;
}

// The scene's trial in OUT/trials/SCENE, synthesised in a child process unless cached (or --fresh).
fs::path synthesise_trial(const BenchArgs& args, const fs::path& out, const std::string& scene_name) {
  const fs::path trial = out / "trials" / scene_name;
  if (!args.fresh && fs::exists(trial / "truth.h5")) return trial;
  fs::path scene_file = fs::path(args.scenes_dir) / (scene_name + ".yaml");
  fs::create_directories(out / "trials");
  if (scene_name == "quick") {
    // The default scene cut to 12 frames: five at rest, then partial slip.
    const SceneSection s = SceneSection::load((fs::path(args.scenes_dir) / "default.yaml").string());
    const SceneSection synthesis = s.at("synthesis");
    const SceneSection quick =
        s.with("synthesis", synthesis.with("timing", synthesis.at("timing").with("frames", "12")));
    scene_file = out / "trials" / "quick.yaml";
    write_text_file(scene_file.string(), quick.to_yaml() + "\n");
  }
  if (!fs::exists(scene_file)) throw Error("no such scene", {.file = scene_file.string()});
  std::cerr << "bench: synthesising " << scene_name << " -> " << trial.string() << "\n";
  double peak = 0.0;
  const std::string log = (out / "trials" / (scene_name + ".log")).string();
  if (run_child({"synth", "--scene", scene_file.string(), "--out", trial.string(), "--quiet"}, log, &peak) !=
      0)
    throw Error("synthesis failed: " + tail_of(log), {.file = scene_file.string()});
  return trial;
}

// One configuration on one trial, REPEATS child runs of `tirstrain validate`: medians of the speeds, the
// errors of the first run (they are deterministic).
Row measure_config(const fs::path& out, const StagedFolder& staged, const fs::path& trial,
                   const std::string& scene_name, const Config& config, int repeats, std::size_t& run_index,
                   std::size_t total_runs) {
  Row row;
  row.scene = scene_name;
  row.config = config.name;
  const fs::path run_dir = out / "runs" / scene_name / config.name;
  fs::create_directories(run_dir);
  const std::string scene_file = write_config_scene(trial, config, run_dir / "scene.yaml");
  std::vector<double> fps, contact_ms, track_ms, strain_ms, tracks;
  for (int r = 0; r < repeats; ++r) {
    ++run_index;
    const fs::path rep = run_dir / ("repeat" + std::to_string(r));
    double peak = 0.0;
    const std::string log = (run_dir / ("repeat" + std::to_string(r) + ".log")).string();
    const int code = run_child(
        {"validate", "--trial", trial.string(), "--process-scene", scene_file, "--out", rep.string(),
         "--no-maps", "--quiet", "--staged-in", staged.staging + "=" + staged.final_path},
        log, &peak);
    std::cerr << "bench: [" << run_index << "/" << total_runs << "] " << scene_name << " " << config.name
              << " repeat " << r + 1 << (code == 0 ? "" : " FAILED") << "\n";
    if (code != 0) {
      row.error = tail_of(log);
      break;
    }
    row.peak_mb = std::isfinite(row.peak_mb) ? std::max(row.peak_mb, peak) : peak;
    std::ifstream summary_file(rep / "result" / "summary.json");
    const nlohmann::json summary = nlohmann::json::parse(summary_file);
    row.frames = summary["frames"]["total"].get<int>();
    fps.push_back(row.frames / summary["wall_time_s"].get<double>());
    contact_ms.push_back(summary["contact"]["segment_ms_per_frame"].get<double>());
    track_ms.push_back(summary["tracking"]["track_ms_per_frame"].get<double>());
    strain_ms.push_back(summary["strain"]["strain_ms_per_frame"].get<double>());
    tracks.push_back(summary["tracking"]["tracks_alive_mean"].get<double>());
    if (r == 0) read_validation(rep, row);
  }
  row.frames_per_s = median(fps);
  row.contact_ms = median(contact_ms);
  row.track_ms = median(track_ms);
  row.strain_ms = median(strain_ms);
  row.tracks_mean = median(tracks);
  return row;
}

// The ring the table's "rim" column shows: where slip begins, inside the last few pixels of the border.
constexpr const char* kRim = "0.85-0.95";

double ring_value(const std::map<std::string, double>& values, const std::string& ring) {
  const auto it = values.find(ring);
  return it == values.end() ? kNaN : it->second;
}

void print_rows(const std::vector<Row>& rows) {
  std::printf("%-24s %-22s %8s %8s %7s %8s %8s %8s %7s %9s %9s %9s %9s %8s %7s %8s\n", "scene", "config",
              "frames/s", "contact", "ctr_px", "track", "strain", "peak_MB", "tracks", "disp_px", "E_xx",
              "E_yy", "E_xy", "U_err%", "cover%", "rim_px");
  for (const Row& r : rows) {
    if (!r.error.empty()) {
      std::printf("%-24s %-22s failed: %s\n", r.scene.c_str(), r.config.c_str(), r.error.c_str());
      continue;
    }
    std::printf(
        "%-24s %-22s %8.3g %8.3g %7.2f %8.3g %8.3g %8.0f %7.0f %9.4f %9.5f %9.5f %9.5f %8.2f %7.1f %8.3f\n",
        r.scene.c_str(), r.config.c_str(), r.frames_per_s, r.contact_ms, r.contact_centre_rms_px, r.track_ms,
        r.strain_ms, r.peak_mb, r.tracks_mean, r.disp_rms_px, r.strain_rms[0], r.strain_rms[1],
        r.strain_rms[2], r.energy_err_pct, r.coverage_pct, ring_value(r.ring_disp_px, kRim));
  }
}

void write_bench_csv(const std::vector<Row>& rows, const fs::path& path) {
  CsvWriter csv(path.string(), {"scene",
                                "config",
                                "frames",
                                "frames_per_s",
                                "contact_ms",
                                "track_ms",
                                "strain_ms",
                                "peak_mb",
                                "tracks_mean",
                                "disp_rms_px",
                                "strain_rms",
                                "strain_rms_exx",
                                "strain_rms_eyy",
                                "strain_rms_exy",
                                "energy_err_pct",
                                "plate_rms_px",
                                "contact_centre_rms_px",
                                "contact_iou_min",
                                "coverage_pct",
                                "coverage_min_pct",
                                "c_of_a_rms_pct",
                                "coverage_ring_0.85-0.95_pct",
                                "coverage_ring_0.95-1_pct",
                                "disp_ring_0.85-0.95_px",
                                "disp_ring_0.95-1_px",
                                "strain_ring_0.85-0.95",
                                "strain_ring_0.95-1",
                                "error"});
  for (const Row& r : rows)
    csv.row_text({r.scene,
                  r.config,
                  std::to_string(r.frames),
                  format_double(r.frames_per_s),
                  format_double(r.contact_ms),
                  format_double(r.track_ms),
                  format_double(r.strain_ms),
                  format_double(r.peak_mb),
                  format_double(r.tracks_mean),
                  format_double(r.disp_rms_px),
                  format_double(r.strain_rms_all),
                  format_double(r.strain_rms[0]),
                  format_double(r.strain_rms[1]),
                  format_double(r.strain_rms[2]),
                  format_double(r.energy_err_pct),
                  format_double(r.plate_rms_px),
                  format_double(r.contact_centre_rms_px),
                  format_double(r.contact_iou_min),
                  format_double(r.coverage_pct),
                  format_double(r.coverage_min_pct),
                  format_double(r.c_of_a_rms_pct),
                  format_double(ring_value(r.ring_coverage_pct, "0.85-0.95")),
                  format_double(ring_value(r.ring_coverage_pct, "0.95-1")),
                  format_double(ring_value(r.ring_disp_px, "0.85-0.95")),
                  format_double(ring_value(r.ring_disp_px, "0.95-1")),
                  format_double(ring_value(r.ring_strain, "0.85-0.95")),
                  format_double(ring_value(r.ring_strain, "0.95-1")),
                  csv_safe(r.error)});
  csv.commit();
}

// The pipeline suite: every scene x configuration through `tirstrain validate`, a table, bench.csv and the
// Pareto plot.
void run_pipeline_bench(const BenchArgs& args, const fs::path& out, const StagedFolder& staged) {
  std::vector<std::string> scenes = args.scenes;
  std::vector<std::string> config_names = args.configs;
  int repeats = args.repeats;
  if (args.quick) {
    if (scenes.empty()) scenes = {"quick"};
    if (config_names.empty()) config_names = {"delhaye2016", "default"};
    repeats = 1;
  }
  if (scenes.empty())
    scenes = {"default", "paper_camera_1280", "hard_heavy_noise", "hard_low_contrast",
              "hard_large_displacement"};
  const std::vector<Config> configs = select_configs(config_names);
  std::vector<Row> rows;
  const std::size_t total_runs = scenes.size() * configs.size() * static_cast<std::size_t>(repeats);
  std::size_t run_index = 0;
  for (const std::string& scene_name : scenes) {
    const fs::path trial = synthesise_trial(args, out, scene_name);
    for (const Config& config : configs)
      rows.push_back(measure_config(out, staged, trial, scene_name, config, repeats, run_index, total_runs));
  }
  print_rows(rows);
  write_bench_csv(rows, out / "bench.csv");
  write_plot(rows, (out / "bench.html").string());
  std::cerr << "bench: wrote bench.csv and bench.html\n";
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* sub = app.add_subcommand(
      "bench", "Speed against error: the whole pipeline on synthetic trials with exact truth");
  sub->footer(
      "For each scene x configuration: synthesise the trial once (cached in OUT/trials), then process and "
      "validate\n"
      "it in a child process (`tirstrain validate`), REPEATS times. Prints one row per configuration and "
      "scene:\n"
      "frames/s end to end (median of repeats; decode, contact, tracking, strain, energy, result writing), "
      "per-stage\n"
      "ms/frame, peak memory (MB, the child's maximum resident set), displacement RMS error of all tracks "
      "(px),\n"
      "strain RMS error per component in the contact interior (exact mode, against the exact strain at "
      "triangle\n"
      "centroids), and the total strain energy error U (% RMS over frames with >= 10 % of the peak energy).\n"
      "Writes OUT/bench.csv and OUT/bench.html (strain error against frames/s, Pareto front marked).\n"
      "Configurations: delhaye2016 (the paper's preset), default (automatic), and one-setting sweeps of the\n"
      "automatic preset (window, pyramid levels, grid spacing, feature cap, shape function, subset radius,\n"
      "full-resolution segmentation, the balanced and fast segmentation presets).\n"
      "Scenes (samples/scenes): default (640x512 CM), paper_camera_1280 (1280x1024, ~3000 tracks),\n"
      "hard_heavy_noise, hard_low_contrast, hard_large_displacement.\n"
      "--quick: a 12-frame cut of the default scene, the two presets, one repeat (a CI smoke run, < 1 min).\n"
      "\n"
      "--suite generalisation: the tracker alone (flow::FeatureTracker, as `tirstrain track --grid 10`\n"
      "runs it without a scene) on exact-truth sequences it was not tuned on (docs/generalisation.md):\n"
      "speckle and fingerprint textures x subpixel_shift, integer_shift, chirp, step, stretch, rotation,\n"
      "creep (--cases picks them) x noise 0.5 and 2 % of full scale (16-bit frames) x presets auto and\n"
      "delhaye2016 (--configs picks them; also auto_no_rest: auto without its rest handling,\n"
      "auto_no_affine_fit: auto without the moving frame's affine fit, auto_no_local_fit: auto without\n"
      "its local fit (docs/flow.md), auto_own_matches: without either, and auto_low_snr: ridges of any\n"
      "SNR on the low-SNR path). Per row:\n"
      "tracks alive (mean), displacement error RMS (all tracks; edge_px: the grid's two outermost rows and\n"
      "columns), the largest per-frame bias |mean error| and max (px),\n"
      "track-frames more than 1 px off (>1px); for the chirp (u = 0.1 px sin, wavelength 1000 -> 20 px\n"
      "along x): res_px, the shortest wavelength reproduced with >= 90 % of its amplitude ('>L': not even\n"
      "the longest window L the frame holds), res_r the same in radii (the subset radius, or half the LK\n"
      "window for delhaye2016), gain_l the gain at that longest window, long_px the RMS of the error\n"
      "vector over wavelengths >= 10 radii, long_u that of its component u alone; rest: frames the tracker "
      "declared at rest; affine: moving frames whose affine fit\n"
      "stood in for the matches within their noise; ms per tracked frame\n"
      "(FeatureTracker::track).\n"
      "Writes OUT/generalisation.csv, generalisation_frames.csv (per frame) and generalisation_chirp.csv\n"
      "(the chirp's windows). With --quick: the small test sizes (192x128, chirp 512x96), a few seconds.\n"
      "With --recordings: each sequence also as a recording, OUT/recordings/CASE_TEXTURE_NOISE/ (frames/,\n"
      "frames.csv; no scene), for `tirstrain process` or `track` (the fields: docs/generalisation.md).\n"
      "Example: tirstrain bench --suite generalisation --out gen-output");
  sub->add_option("--out", args->out,
                  "Output folder (default bench-output; replaced as a whole when the run completes, its "
                  "cached trials reused)");
  sub->add_option("--scenes-dir", args->scenes_dir, "Folder of the scene files")
      ->check(CLI::ExistingDirectory);
  sub->add_option("--scenes", args->scenes, "Scene names (files in --scenes-dir without .yaml)")
      ->delimiter(',');
  sub->add_option("--configs", args->configs, "Configuration names (default: all)")->delimiter(',');
  sub->add_option("--repeats", args->repeats, "Repeats per row; frames/s is their median")
      ->check(CLI::Range(1, 50));
  sub->add_flag("--quick", args->quick, "A quick smoke run (see above)");
  sub->add_flag("--fresh", args->fresh, "Synthesise the trials again even if cached");
  sub->add_option("--suite", args->suite,
                  "pipeline (default: the whole pipeline on the shipped scenes) or generalisation (the "
                  "tracker on exact-truth speckle and fingerprint fields)")
      ->check(CLI::IsMember({"pipeline", "generalisation"}));
  sub->add_option("--cases", args->cases, "With --suite generalisation: the cases to run (default: all)")
      ->delimiter(',');
  sub->add_flag("--recordings", args->recordings,
                "With --suite generalisation: also write each sequence as a recording (OUT/recordings/)");
  sub->callback([args] {
    // Built in "<out>.partial" and swapped in whole: a failed or killed run leaves the earlier output as it
    // was.
    check_replaceable_output(args->out, bench_output_names(), "bench");
    StagingDirectory staging(args->out);
    const fs::path out(staging.path());
    if (args->suite == "generalisation") {
      run_generalisation_bench(out, args->quick, args->configs, args->cases, args->recordings);
    } else {
      if (!args->fresh) carry_over_trials(args->out, out);
      run_pipeline_bench(*args, out, staging.folder());
    }
    staging.commit();
    std::cerr << "bench: results in " << staging.final_path() << "\n";
  });
}

}  // namespace tirstrain::cli
