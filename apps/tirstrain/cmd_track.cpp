// `tirstrain track`: tracks given points (or a grid) through any image sequence with the flow/ tracker, no
// contact segmentation involved — for textures that are not fingerprints (speckle) and for checking the
// tracker alone. Output: frame,id,X_px,Y_px,x_px,y_px,status,model (reference and current position; a
// retired track appears once more, in the frame it was retired, at its last good position with the reason;
// model: what the position is, flow::TrackModel), and beside it <out>.json: the settings in effect, the
// texture as judged, and per frame the rest test and how many tracks a model stood in for.
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "pipeline/output_folder.hpp"
#include "pipeline/tracking_report.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {
namespace {

struct TrackOptions {
  std::string input;
  std::optional<double> frame_rate_Hz;  // of a recording without timestamps, Hz; unset: none
  std::string points_csv;
  double grid_step_px = 0.0;
  std::string roi;
  std::string preset;
  std::string scene;
  std::string out;
  bool quiet = false;
};

cv::Rect parse_roi(const std::string& text, const cv::Size& frame) {
  std::vector<int> v;
  std::stringstream in(text);
  std::string cell;
  while (std::getline(in, cell, ',')) {
    try {
      std::size_t used = 0;
      v.push_back(std::stoi(cell, &used));
      if (used != cell.size()) throw std::invalid_argument(cell);
    } catch (const std::exception&) {
      throw Error("expected x,y,w,h in pixels, got '" + text + "'", {.key = "--roi"});
    }
  }
  if (v.size() != 4 || v[2] <= 0 || v[3] <= 0 || v[0] < 0 || v[1] < 0)
    throw Error("expected x,y,w,h with w, h > 0, got '" + text + "'", {.key = "--roi"});
  const cv::Rect r(v[0], v[1], v[2], v[3]);
  if ((r & cv::Rect(0, 0, frame.width, frame.height)) != r)
    throw Error("the ROI " + text + " does not fit in the " + std::to_string(frame.width) + "x" +
                    std::to_string(frame.height) + " frame",
                {.key = "--roi"});
  return r;
}

// t.csv -> t.json beside it.
std::string settings_path(const std::string& csv) {
  const std::size_t dot = csv.find_last_of('.');
  const std::size_t slash = csv.find_last_of('/');
  const bool has_extension = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_extension ? csv.substr(0, dot) : csv) + ".json";
}

// Writing beside or over an input would change it: the CSV and its settings file must lie outside every
// input (the frames' folder or file, the scene, the points).
void check_track_output(const TrackOptions& o) {
  std::vector<std::string> inputs = pipeline::input_locations(o.input);
  for (const std::string* path : {&o.scene, &o.points_csv})
    if (!path->empty()) inputs.push_back(*path);
  for (const std::string& output : {o.out, settings_path(o.out)})
    for (const std::string& input : inputs)
      if (path_is_within(output, input))
        throw Error(output + (output == input || path_is_within(input, output) ? " is" : " lies inside") +
                        " the input " + input + "; write the tracks elsewhere",
                    {.key = "--out"});
}

void run_track(const TrackOptions& o) {
  check_track_output(o);
  Scene scene;
  if (!o.scene.empty()) scene = load_scene(o.scene);
  flow::TrackerSettings settings = flow::parse_tracking_settings(scene, o.preset);
  // Points given by the user are tracked as they are; nothing is born.
  settings.births = false;

  std::unique_ptr<capture::FrameSource> source =
      capture::open_source(o.input, capture::FileSourceOptions{.frame_rate_Hz = o.frame_rate_Hz});
  std::optional<capture::Frame> first = source->next();
  if (!first) throw Error("the sequence has no frames", {.file = o.input});
  const cv::Size size = first->image.size();

  cv::Mat mask;
  if (!o.roi.empty()) {
    mask = cv::Mat::zeros(size, CV_8U);
    mask(parse_roi(o.roi, size)).setTo(1);
  }
  std::vector<Vec2> points;
  if (!o.points_csv.empty()) {
    const CsvTable table = read_numeric_csv(o.points_csv);
    const auto& xs = table.column("x_px");
    const auto& ys = table.column("y_px");
    for (std::size_t i = 0; i < xs.size(); ++i) points.push_back({xs[i], ys[i]});
    if (points.empty()) throw Error("no points to track", {.file = o.points_csv});
  } else {
    const cv::Rect r = o.roi.empty() ? cv::Rect(0, 0, size.width, size.height) : parse_roi(o.roi, size);
    // Keep a margin of the refinement subset so every grid point starts with a full subset.
    const double margin = settings.refine ? settings.subset_radius_px + 2.0 : settings.window_px / 2.0;
    for (double y = r.y + margin; y <= r.y + r.height - 1 - margin; y += o.grid_step_px)
      for (double x = r.x + margin; x <= r.x + r.width - 1 - margin; x += o.grid_step_px)
        points.push_back({x, y});
    if (points.empty())
      throw Error("the grid has no point at least " + std::to_string(static_cast<int>(margin)) +
                      " px inside the tracked region",
                  {.key = "--grid"});
  }

  flow::FeatureTracker tracker(settings);
  CsvWriter out(o.out, {"frame", "id", "X_px", "Y_px", "x_px", "y_px", "status", "model"});
  nlohmann::json frames_json = nlohmann::json::array();
  std::array<long, 4> by_model{};
  const auto write = [&](int frame) {
    for (const flow::Track& t : tracker.tracks()) {
      if (!flow::is_alive(t.status) && t.retired_frame != frame) continue;
      out.row_text({std::to_string(frame), std::to_string(t.id), format_double(t.reference_px.x),
                    format_double(t.reference_px.y), format_double(t.position_px.x),
                    format_double(t.position_px.y), std::to_string(static_cast<int>(t.status)),
                    std::to_string(static_cast<int>(t.model))});
      if (flow::is_alive(t.status)) ++by_model[static_cast<std::size_t>(t.model)];
    }
  };
  const auto record_frame = [&](const flow::FrameStats& s) {
    nlohmann::json f = {{"frame", s.frame},
                        {"alive", s.alive},
                        {"fused", s.fused},
                        {"fusion_declined", s.fusion_declined},
                        {"rest_tested", s.rest_tested},
                        {"at_rest", s.at_rest},
                        {"on_rest_fit", s.on_rest_fit}};
    if (s.rest_tested) {
      f["rest_chi2_per_dof"] =
          std::isfinite(s.rest_chi2_per_dof) ? nlohmann::json(s.rest_chi2_per_dof) : nullptr;
      f["rest_correlation_z"] =
          std::isfinite(s.rest_correlation_z) ? nlohmann::json(s.rest_correlation_z) : nullptr;
      f["rest_pairs"] = s.rest_pairs;
    }
    frames_json.push_back(f);
  };
  try {
    tracker.start(first->image, mask, first->device_time_s, points);
  } catch (const Error& e) {
    throw Error(e.message(), {.file = o.input, .frame = 0});
  }
  write(0);
  record_frame(tracker.stats());
  int frames = 1;
  while (std::optional<capture::Frame> f = source->next()) {
    if (f->status == capture::FrameStatus::kCorrupt || f->status == capture::FrameStatus::kIncomplete) {
      if (!o.quiet)
        std::cerr << "tirstrain track: skipping frame " << f->index << " (" << capture::to_string(f->status)
                  << ")\n";
      continue;
    }
    try {
      tracker.track(f->image, mask, f->device_time_s);
    } catch (const Error& e) {
      throw Error(e.message(), {.file = o.input, .frame = f->index});
    }
    write(tracker.frame_index());
    record_frame(tracker.stats());
    ++frames;
  }
  const std::string json_path = settings_path(o.out);
  nlohmann::json report = {{"settings", pipeline::tracking_settings_json(tracker.settings())},
                           {"texture", pipeline::texture_json(tracker)},
                           {"input", o.input},
                           {"frames", frames},
                           {"track_frames_by_model",
                            {{"own_match", by_model[0]},
                             {"fused", by_model[1]},
                             {"rest_fit", by_model[2]},
                             {"smoothed_in_time", by_model[3]}}},
                           {"per_frame", frames_json}};
  // Both files are complete before either is renamed into place, so a run that fails leaves the earlier
  // pair as it was.
  AtomicFile json(json_path);
  json.append(report.dump(2) + "\n");
  json.make_durable();
  out.commit();
  json.commit();
  long alive = 0;
  for (const flow::Track& t : tracker.tracks()) alive += flow::is_alive(t.status) ? 1 : 0;
  if (!o.quiet) {
    std::cout << "tracked " << tracker.tracks().size() << " points through " << frames << " frames (" << alive
              << " alive at the end, preset " << settings.preset << "); wrote " << o.out << " and "
              << json_path << '\n';
    std::cout << "texture: " << pipeline::texture_note(tracker) << '\n';
    std::cout << "positions: " << by_model[0] << " own matches, " << by_model[1] << " neighbour-fused, "
              << by_model[2]
              << " on the rest fit (track-frames; column model, and the rest test per frame in " << json_path
              << ")\n";
  }
}

}  // namespace

void add_track_command(CLI::App& app) {
  auto o = std::make_shared<TrackOptions>();
  CLI::App* cmd = app.add_subcommand(
      "track",
      "Track points (or a grid) through an image sequence: pyramidal Lucas-Kanade between frames, refined\n"
      "against the first frame by subset correlation. Writes frame,id,X_px,Y_px,x_px,y_px,status,model\n"
      "(model: 0 own match, 1 neighbour-fused, 2 rest fit; each only where a test on that frame accepted "
      "it)\n"
      "and, beside the CSV, a JSON of the settings in effect, the texture and the per-frame tests.\n"
      "Example: tirstrain track frames/ --grid 10 --out tracks.csv   (writes tracks.csv and tracks.json)");
  cmd->add_option("input", o->input,
                  "Image folder, printf/glob pattern, multi-page TIFF, .cine, .mraw/.cih or video file")
      ->required();
  cmd->add_option("--frame-rate-Hz", o->frame_rate_Hz,
                  "Frame rate (Hz) of a recording whose file holds no timestamps and has no frames.csv "
                  "beside it (a multi-page TIFF)")
      ->check(CLI::PositiveNumber);
  CLI::Option* points =
      cmd->add_option("--points", o->points_csv, "CSV with columns x_px,y_px (first frame)");
  CLI::Option* grid = cmd->add_option("--grid", o->grid_step_px, "Track a grid with this spacing (px)")
                          ->check(CLI::Range(1.0, 1e4));
  points->excludes(grid);
  cmd->add_option("--roi", o->roi, "Region to track in, x,y,w,h (px); the grid fills it");
  cmd->add_option("--preset", o->preset, "Tracking preset: auto or delhaye2016 (overrides the scene's)");
  cmd->add_option("--scene", o->scene, "Scene file (calibration and the tracking: section)");
  cmd->add_option("--out", o->out, "Output CSV")->required();
  cmd->add_flag("--quiet", o->quiet, "No summary line");
  cmd->callback([o, points, grid] {
    if (!*points && !*grid) throw Error("give either --points FILE.csv or --grid STEP", {.key = "--grid"});
    run_track(*o);
  });
}

}  // namespace tirstrain::cli
