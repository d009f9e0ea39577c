// `tirstrain track`: tracks given points (or a grid) through any image sequence with the flow/ tracker, no
// contact segmentation involved — for textures that are not fingerprints (speckle) and for checking the
// tracker alone. Output: frame,id,X_px,Y_px,x_px,y_px,status,model,model_window_x_px,model_window_y_px
// (reference and current position; a retired track appears once more, in the frame it was retired, at its
// last good position with the reason; model: what the position is, flow::TrackModel; the local fit's window
// per component), and beside it <out>.json: the settings in effect, the texture as judged, and per frame the
// rest test and how many tracks a model stood in for.
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
#include "core/progress.hpp"
#include "core/scene.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "pipeline/output_folder.hpp"
#include "pipeline/tracking_report.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

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

// Where tracking starts: the user's points, or a grid over the region a full subset inside it.
std::vector<Vec2> seed_points(const TrackOptions& o, const flow::TrackerOptions& settings, cv::Size size) {
  std::vector<Vec2> points;
  if (!o.points_csv.empty()) {
    const CsvTable table = read_numeric_csv(o.points_csv);
    const auto& xs = table.column("x_px");
    const auto& ys = table.column("y_px");
    for (std::size_t i = 0; i < xs.size(); ++i) points.push_back({xs[i], ys[i]});
    if (points.empty()) throw Error("no points to track", {.file = o.points_csv});
    return points;
  }
  const cv::Rect r = o.roi.empty() ? cv::Rect(0, 0, size.width, size.height) : parse_roi(o.roi, size);
  // Keep a margin of the refinement subset so every grid point starts with a full subset.
  const double margin =
      settings.refine ? settings.main_match.subset_radius_px + 2.0 : settings.prediction.window_px / 2.0;
  for (double y = r.y + margin; y <= r.y + r.height - 1 - margin; y += o.grid_step_px)
    for (double x = r.x + margin; x <= r.x + r.width - 1 - margin; x += o.grid_step_px)
      points.push_back({x, y});
  if (points.empty())
    throw Error("the grid has no point at least " + std::to_string(static_cast<int>(margin)) +
                    " px inside the tracked region",
                {.key = "--grid"});
  return points;
}

nlohmann::json frame_json(const flow::FrameStats& s) {
  nlohmann::json f = {{"frame", s.frame},
                      {"alive", s.alive},
                      {"fused", s.fused},
                      {"fusion_declined", s.fusion_declined},
                      {"rest_tested", s.rest_tested},
                      {"at_rest", s.at_rest},
                      {"on_rest_fit", s.on_rest_fit},
                      {"local_fit", s.local_fit},
                      {"local_fit_by_component", s.local_fit_by_component},
                      {"affine_fit", s.affine_fit},
                      {"on_affine_fit", s.on_affine_fit},
                      {"unmeasured_direction", s.unmeasured_direction}};
  if (s.rest_tested) {
    f["rest_chi2_per_dof"] =
        std::isfinite(s.rest_chi2_per_dof) ? nlohmann::json(s.rest_chi2_per_dof) : nullptr;
    f["rest_correlation_z"] =
        std::isfinite(s.rest_correlation_z) ? nlohmann::json(s.rest_correlation_z) : nullptr;
    f["rest_pairs"] = s.rest_pairs;
  }
  if (s.affine_tested) {
    f["affine_chi2_per_dof"] =
        std::isfinite(s.affine_chi2_per_dof) ? nlohmann::json(s.affine_chi2_per_dof) : nullptr;
    f["affine_correlation_z"] =
        std::isfinite(s.affine_correlation_z) ? nlohmann::json(s.affine_correlation_z) : nullptr;
    f["affine_hidden_px"] = std::isfinite(s.affine_hidden_px) ? nlohmann::json(s.affine_hidden_px) : nullptr;
  }
  return f;
}

// One run of `track`: frames in, one CSV row per track and frame out, and the JSON report beside it.
class TrackRun {
 public:
  explicit TrackRun(const TrackOptions& o)
      : o_(o),
        out_(o.out, {"frame", "id", "X_px", "Y_px", "x_px", "y_px", "status", "model", "model_window_x_px",
                     "model_window_y_px"}) {}

  void run() {
    open_input();
    start();
    track_frames();
    write_report();
    print_summary();
  }

 private:
  void open_input() {
    Scene scene;
    if (!o_.scene.empty()) scene = load_scene(o_.scene);
    settings_ = flow::parse_tracking_options(scene, o_.preset);
    settings_.births.enabled = false;  // points given by the user are tracked as they are; nothing is born
    source_ = capture::open_source(o_.input, capture::FileSourceOptions{.frame_rate_Hz = o_.frame_rate_Hz});
  }

  // The next frame that decoded; a corrupt or incomplete one is skipped, said and listed in the JSON.
  std::optional<capture::Frame> next_usable_frame() {
    while (std::optional<capture::Frame> f = source_->next()) {
      if (f->status != capture::FrameStatus::kCorrupt && f->status != capture::FrameStatus::kIncomplete)
        return f;
      skipped_.push_back(f->index);
      if (!o_.quiet)
        std::cerr << "tirstrain track: skipping frame " << f->index << " (" << capture::to_string(f->status)
                  << ")\n";
    }
    return std::nullopt;
  }

  void start() {
    std::optional<capture::Frame> first = next_usable_frame();
    if (!first)
      throw Error(
          skipped_.empty() ? "the sequence has no frames" : "no frame of the sequence could be decoded",
          {.file = o_.input});
    const cv::Size size = first->image.size();
    if (!o_.roi.empty()) {
      mask_ = cv::Mat::zeros(size, CV_8U);
      mask_(parse_roi(o_.roi, size)).setTo(1);
    }
    tracker_ = std::make_unique<flow::FeatureTracker>(settings_);
    // The points file's errors name it (file, row, column); the tracker's name the input's frame.
    const std::vector<Vec2> points = seed_points(o_, settings_, size);
    try {
      tracker_->start(first->image, mask_, first->device_time_s, points);
    } catch (const Error& e) {
      throw Error(e.message(), {.file = o_.input, .frame = first->index});
    }
    say_points_not_started(size);
    write_rows(first->index);
  }

  // Points that could not start are retired in frame 0; the run says why, which the status code alone does
  // not: a subset needs a margin inside the frame (or --roi), and texture to match.
  void say_points_not_started(cv::Size size) const {
    const cv::Rect region =
        o_.roi.empty() ? cv::Rect(0, 0, size.width, size.height) : parse_roi(o_.roi, size);
    const double margin =
        settings_.refine ? settings_.main_match.subset_radius_px + 2.0 : settings_.prediction.window_px / 2.0;
    int near_edge = 0, other = 0;
    for (const flow::Track& t : tracker_->tracks()) {
      if (flow::is_alive(t.status)) continue;
      const Vec2& p = t.reference_px;
      const double inside = std::min({p.x - region.x, p.y - region.y, region.x + region.width - 1 - p.x,
                                      region.y + region.height - 1 - p.y});
      ++(inside < margin ? near_edge : other);
    }
    if (near_edge > 0)
      std::cerr << "tirstrain track: warning: " << near_edge << " of the given points lie within "
                << static_cast<int>(margin) << " px of the " << (o_.roi.empty() ? "frame's" : "--roi's")
                << " edge, where a subset does not fit: not tracked (status "
                << static_cast<int>(flow::TrackStatus::kPoorMatch) << " in frame 0)\n";
    if (other > 0)
      std::cerr << "tirstrain track: warning: " << other << " of the " << tracker_->tracks().size()
                << (o_.points_csv.empty() ? " grid" : " given")
                << " points found no converged match in frame 0 (too little texture around them): not "
                   "tracked\n";
  }

  void track_frames() {
    Progress progress("track", source_->frame_count() > 0 ? static_cast<long>(source_->frame_count()) : 1L,
                      o_.quiet);
    while (std::optional<capture::Frame> f = next_usable_frame()) {
      try {
        tracker_->track(f->image, mask_, f->device_time_s);
      } catch (const Error& e) {
        throw Error(e.message(), {.file = o_.input, .frame = f->index});
      }
      write_rows(f->index);
      progress.update(static_cast<long>(f->index) + 1);
    }
    progress.finish();
  }

  // The frame's rows (`frame`: the input's frame index, which counts the skipped frames too): every alive
  // track, and those retired this frame with their reason.
  void write_rows(std::int64_t frame) {
    for (const flow::Track& t : tracker_->tracks()) {
      if (!flow::is_alive(t.status) && t.retired_frame != tracker_->frame_index()) continue;
      const bool local_fit = t.model == flow::TrackModel::kLocalFit;
      out_.row_text({std::to_string(frame), std::to_string(t.id), format_double(t.reference_px.x),
                     format_double(t.reference_px.y), format_double(t.position_px.x),
                     format_double(t.position_px.y), std::to_string(static_cast<int>(t.status)),
                     std::to_string(static_cast<int>(t.model)),
                     local_fit ? format_double(t.model_window_px[0]) : "0",
                     local_fit ? format_double(t.model_window_px[1]) : "0"});
      if (flow::is_alive(t.status)) ++by_model_[static_cast<std::size_t>(t.model)];
    }
    frames_json_.push_back(frame_json(tracker_->stats()));
    unmeasured_direction_ += tracker_->stats().unmeasured_direction;
    ++frames_;
  }

  // Both files are complete before either is renamed into place, so a run that fails leaves the earlier
  // pair as it was.
  void write_report() {
    const nlohmann::json report = {{"settings", pipeline::tracking_settings_json(tracker_->settings())},
                                   {"texture", pipeline::texture_json(*tracker_)},
                                   {"input", o_.input},
                                   {"frames", frames_},
                                   {"frames_skipped", skipped_},
                                   {"track_frames_by_model",
                                    {{"own_match", by_model_[0]},
                                     {"fused", by_model_[1]},
                                     {"rest_fit", by_model_[2]},
                                     {"smoothed_in_time", by_model_[3]},
                                     {"local_fit", by_model_[4]},
                                     {"affine_fit", by_model_[5]}}},
                                   {"unmeasured_direction_track_frames", unmeasured_direction_},
                                   {"per_frame", frames_json_}};
    AtomicFile json(settings_path(o_.out));
    json.append(report.dump(2) + "\n");
    json.make_durable();
    out_.commit();
    json.commit();
  }

  void print_summary() const {
    if (unmeasured_direction_ > 0)
      std::cerr << "tirstrain track: warning: " << unmeasured_direction_
                << " track-frames have a direction the texture does not determine (straight ridges, or no "
                   "texture): their position along it is where the search started, not a measurement "
                   "(per frame: unmeasured_direction in "
                << settings_path(o_.out) << ")\n";
    if (o_.quiet) return;
    long alive = 0;
    for (const flow::Track& t : tracker_->tracks()) alive += flow::is_alive(t.status) ? 1 : 0;
    const std::string json_path = settings_path(o_.out);
    std::cout << "tracked " << tracker_->tracks().size() << " points through " << frames_ << " frames ("
              << alive << " alive at the end, preset " << settings_.preset << "); wrote " << o_.out << " and "
              << json_path << '\n';
    std::cout << "texture: " << pipeline::texture_note(*tracker_) << '\n';
    std::cout << "positions: " << by_model_[0] << " own matches, " << by_model_[1] << " neighbour-fused, "
              << by_model_[2] << " on the rest fit, " << by_model_[5] << " on a moving frame's affine fit, "
              << by_model_[4]
              << " on a local fit of their neighbours (track-frames; columns model and model_window_x_px / "
                 "_y_px, and "
                 "the tests per frame in "
              << json_path << ")\n";
  }

  const TrackOptions& o_;
  flow::TrackerOptions settings_;
  std::unique_ptr<capture::FrameSource> source_;
  std::unique_ptr<flow::FeatureTracker> tracker_;
  cv::Mat mask_;
  CsvWriter out_;
  nlohmann::json frames_json_ = nlohmann::json::array();
  std::array<long, 6> by_model_{};
  long unmeasured_direction_ = 0;  // alive track-frames with a direction no match measured
  int frames_ = 0;
  std::vector<std::int64_t> skipped_;  // input frame indices that could not be decoded
};

void run_track(const TrackOptions& o) {
  check_track_output(o);
  TrackRun(o).run();
}

}  // namespace

void add_track_command(CLI::App& app) {
  auto o = std::make_shared<TrackOptions>();
  CLI::App* cmd = app.add_subcommand(
      "track",
      "Track points (or a grid) through an image sequence: pyramidal Lucas-Kanade between frames, refined\n"
      "against the first frame by subset correlation. Writes frame,id,X_px,Y_px,x_px,y_px,status,model,\n"
      "model_window_x_px,model_window_y_px (model: 0 own match, 1 neighbour-fused, 2 rest fit, 4 local fit\n"
      "of the neighbours' matches, x and y each over a window of that radius (0: that component is the own\n"
      "match's; a component alone may take the whole frame's fit of it), else 0; 5 the affine fit of a\n"
      "moving frame; each only where a test on that frame accepted it)\n"
      "and, beside the CSV, a JSON of the settings in effect, the texture and the per-frame tests.\n"
      "frame is the input's frame index: a frame that cannot be decoded is skipped (listed in the JSON's\n"
      "frames_skipped) and the others keep their numbers.\n"
      "Example: tirstrain track frames/ --grid 10 --out tracks.csv   (writes tracks.csv and tracks.json)");
  cmd->add_option("input", o->input,
                  "Image folder, printf/glob pattern, multi-page TIFF, .cine, .mraw/.cih or video file")
      ->required();
  cmd->add_option("--frame-rate-Hz", o->frame_rate_Hz,
                  "Frame rate (Hz) of a recording whose file holds no timestamps and has no frames.csv "
                  "beside it (a multi-page TIFF, a folder of images)")
      ->check(kPositive);
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
