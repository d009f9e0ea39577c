#include "pipeline/process.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include "capture/frame_source.hpp"
#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/progress.hpp"
#include "core/scene.hpp"
#include "core/version.hpp"
#include "pipeline/output_folder.hpp"
#include "pipeline/prefetch.hpp"
#include "pipeline/process_defaults.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

// Overlay for people: an MP4 through FFmpeg, or a PNG sequence, written into the run's staging folder.
// FFmpeg does not report a failed write, so a full disk is checked for when the video is closed.
class OverlayWriter {
 public:
  OverlayWriter(OverlayMode mode, const std::string& out_dir, std::FILE* log, bool quiet)
      : mode_(mode), out_dir_(out_dir), log_(log), quiet_(quiet) {}

  ~OverlayWriter() {
    if (video_.isOpened()) video_.release();
  }

  void write(const cv::Mat& bgr) {
    if (mode_ == OverlayMode::kMp4 && !video_.isOpened()) open_video(bgr.size());
    if (mode_ == OverlayMode::kMp4) {
      video_.write(bgr);
    } else if (mode_ == OverlayMode::kPng) {
      const fs::path folder = fs::path(out_dir_) / "overlay";
      if (count_ == 0 || !fs::is_directory(folder)) fs::create_directories(folder);
      char name[32];
      std::snprintf(name, sizeof name, "%06lld.png", static_cast<long long>(count_));
      const std::string path = (folder / name).string();
      if (!cv::imwrite(path, bgr, {cv::IMWRITE_PNG_COMPRESSION, 1})) {
        check_writable(out_dir_);  // names the cause when it is the disk
        throw Error("cannot write overlay image", {.file = path});
      }
    }
    ++count_;
  }

  // Closes the overlay; returns its name in the output folder, or "" when nothing was written.
  std::string finish() {
    if (mode_ == OverlayMode::kMp4 && video_.isOpened()) {
      video_.release();
      check_complete_write(video_path_);
      return "overlay.mp4";
    }
    if (mode_ == OverlayMode::kPng && count_ > 0) return "overlay";
    return "";
  }

  bool enabled() const { return mode_ != OverlayMode::kNone; }

 private:
  void open_video(cv::Size size) {
    video_path_ = (fs::path(out_dir_) / "overlay.mp4").string();
    // H.264 ('avc1') is the most widely playable but often missing from Debian's FFmpeg encoders list for
    // OpenCV; MPEG-4 Part 2 ('mp4v') is always there.
    for (const char* code : {"avc1", "mp4v"}) {
      video_.open(video_path_, cv::CAP_FFMPEG, cv::VideoWriter::fourcc(code[0], code[1], code[2], code[3]),
                  25.0, size, true);
      if (video_.isOpened()) return;
    }
    // A folder that cannot take a file is the cause, not a missing encoder.
    check_writable(out_dir_);
    if (!quiet_)
      std::fprintf(
          log_, "tirstrain: warning: no MP4 encoder available; writing the overlay as PNG images instead\n");
    video_path_.clear();
    mode_ = OverlayMode::kPng;
  }

  OverlayMode mode_;
  std::string out_dir_;
  std::FILE* log_;
  bool quiet_;
  cv::VideoWriter video_;
  std::string video_path_;
  std::int64_t count_ = 0;
};

cv::Mat to_display(const cv::Mat& grey, cv::Size size) {
  cv::Mat bgr;
  if (grey.empty()) {
    bgr = cv::Mat(size, CV_8UC3, cv::Scalar(40, 40, 40));
    return bgr;
  }
  cv::Mat eight;
  if (grey.depth() == CV_16U) {
    double max_value = 0.0;
    cv::minMaxLoc(grey, nullptr, &max_value);
    eight = cv::Mat();
    grey.convertTo(eight, CV_8U, 255.0 / std::max(1.0, max_value));
  } else {
    eight = grey;
  }
  cv::cvtColor(eight, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

// The pattern band's rectangle and where it came from, on the overlay.
void draw_band(cv::Mat& bgr, const PatternBandChoice& band) {
  if (!band.roi_px) return;
  const RoiPx& r = *band.roi_px;
  const double scale = std::max(1.0, bgr.cols / 640.0);
  const int thick = static_cast<int>(std::lround(scale));
  cv::rectangle(bgr, cv::Rect(r.x, r.y, r.width, r.height), cv::Scalar(255, 120, 0), thick);
  char text[96];
  if (band.confidence) {
    std::snprintf(text, sizeof text, "pattern band (%s, detected, confidence %.2f)", band.edge.c_str(),
                  *band.confidence);
  } else {
    std::snprintf(text, sizeof text, "pattern band (%s, from the scene)", band.edge.c_str());
  }
  // Along the image's bottom, clear of the status lines at the top: just above the band when it is there.
  const int text_y =
      band.edge == "bottom" ? r.y - static_cast<int>(6 * scale) : bgr.rows - static_cast<int>(8 * scale);
  cv::putText(bgr, text, cv::Point(static_cast<int>(8 * scale) + (band.edge == "left" ? r.width : 0), text_y),
              cv::FONT_HERSHEY_SIMPLEX, 0.45 * scale, cv::Scalar(255, 120, 0), thick, cv::LINE_AA);
}

// A trial folder carries its own scene (`tirstrain synth` writes DIR/scene.yaml next to DIR/frames/):
// without --scene it is the one that describes these frames, so it is used rather than the defaults, which
// would know nothing of the folder's reference-pattern band and segment its dots as contact.
std::optional<std::string> scene_path_for(const ProcessOptions& options) {
  if (options.scene_path) return options.scene_path;
  if (!options.folder_scene) return std::nullopt;
  std::error_code ec;
  const fs::path beside = fs::path(options.input) / "scene.yaml";
  if (fs::is_directory(options.input, ec) && fs::is_regular_file(beside, ec)) return beside.string();
  return std::nullopt;
}

// The scene's compute list, or (without one) every stage whose inputs exist, then --compute's additions.
Scene scene_with_overrides(const ProcessOptions& options, const std::optional<std::string>& scene_path,
                           std::string& stages_reason) {
  Scene scene = scene_path ? load_scene(*scene_path) : Scene{};
  if (scene.compute_given) {
    stages_reason = "the scene's compute list";
  } else {
    scene.compute = default_stages(scene, options.input, stages_reason);
    scene.compute_given = true;  // result.h5's copy of the scene shows the list that ran
  }
  for (const std::string& name : options.compute) {
    const auto& known = known_stages();
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw Error("unknown stage '" + name + "' in --compute");
    if (std::find(scene.compute.begin(), scene.compute.end(), name) == scene.compute.end())
      scene.compute.push_back(name);
  }
  // The scene's module sections are YAML nodes shared by reference: give the overrides fresh maps.
  const auto with_key = [](const YAML::Node& section, const std::string& key, const std::string& value) {
    YAML::Node copy = section && section.IsMap() ? YAML::Clone(section) : YAML::Node(YAML::NodeType::Map);
    copy[key] = value;
    return copy;
  };
  if (!options.tracking_preset.empty())
    scene.tracking = with_key(scene.tracking, "preset", options.tracking_preset);
  if (!options.segmentation_preset.empty())
    scene.segmentation = with_key(scene.segmentation, "preset", options.segmentation_preset);
  if (!options.strain_mode.empty()) scene.strain = with_key(scene.strain, "mode", options.strain_mode);
  return scene;
}

// What the frame loop kept of each frame, for replaying the trial without its images.
struct FrameRows {
  const std::vector<std::int64_t>& index;
  const std::vector<std::int64_t>& device_id;
  const std::vector<std::int64_t>& lost_before;
  const std::vector<double>& t_s;
  const std::vector<std::int32_t>& status;
  const std::vector<char>& usable;
};

// Lets each stage finish; where one revises its results (finish() returns true), the stages after it are
// made afresh and run again over the trial replayed from the stages up to it.
void finish_stages(const Scene& scene, const TrialInfo& trial, const FrameRows& rows,
                   std::vector<std::unique_ptr<Stage>>& stages, const ProcessOptions& options) {
  for (std::size_t s = 0; s < stages.size(); ++s) {
    if (!stages[s]->finish() || s + 1 == stages.size()) continue;
    if (!options.quiet)
      std::fprintf(options.log, "tirstrain: %s revised; running the later stages again\n",
                   stages[s]->name().c_str());
    StagePlan fresh = plan_stages(scene);
    for (std::size_t j = s + 1; j < stages.size(); ++j) {
      stages[j] = std::move(fresh.stages[j]);
      stages[j]->start(trial);
    }
    for (std::size_t row = 0; row < rows.index.size(); ++row) {
      capture::Frame frame;
      frame.index = rows.index[row];
      frame.device_frame_id = rows.device_id[row];
      frame.frames_lost_before = rows.lost_before[row];
      frame.device_time_s = rows.t_s[row];
      frame.status = static_cast<capture::FrameStatus>(rows.status[row]);
      FrameContext context;
      context.frame = &frame;
      context.usable = rows.usable[row] != 0;
      for (std::size_t j = 0; j <= s; ++j) stages[j]->replay(context, row);
      for (std::size_t j = s + 1; j < stages.size(); ++j) stages[j]->process(context);
    }
  }
}

// The stages the scene asks for, made now so that a bad scene section stops the run before any frame is
// read; a stage this build lacks is skipped with a warning (an error with --strict).
template <typename Warn>
StagePlan checked_plan(const Scene& scene, bool strict, const Warn& warn) {
  StagePlan plan = plan_stages(scene);
  for (const auto& name : plan.unavailable) {
    const std::string message = "stage '" + name +
                                "' requested by the scene's compute list is not available in this "
                                "build yet; it is skipped";
    if (strict) throw Error(message + " (--strict)", {.file = scene.file, .key = "compute"});
    warn(message);
  }
  if (plan.stages.empty())
    throw Error("nothing to compute: the scene's compute list has no available stage",
                {.file = scene.file, .key = "compute"});
  return plan;
}

// Where the scene's values came from: the file, the defaults, or what the first frame showed.
void summarize_scene_sources(nlohmann::json& summary, const Scene& scene,
                             const std::vector<std::string>& default_notes, const std::string& stages_reason,
                             const PatternBandChoice& band) {
  summary["px_per_mm_source"] = scene.px_per_mm_given ? "scene" : "default";
  summary["tissue"] = {{"E_Pa", scene.tissue.young_Pa},
                       {"nu", scene.tissue.poisson},
                       {"depth_m", scene.tissue.depth_m},
                       {"source", scene.tissue_given ? "scene" : "default"}};
  summary["defaults_used"] = default_notes;
  summary["stages_source"] = stages_reason;
  summary["reference_pattern"] = band.to_json();
}

// Everything is written into a staging folder beside --out and swapped in when complete: an earlier result
// stays whole until then, and an interrupted run leaves only "<out>.partial".
std::unique_ptr<StagingDirectory> stage_output(const ProcessOptions& options,
                                               const std::optional<std::string>& scene_path) {
  std::vector<std::string> inputs = input_locations(options.input);
  if (scene_path) inputs.push_back(*scene_path);
  check_output_folder(options.out_dir, inputs);
  return std::make_unique<StagingDirectory>(options.out_dir);
}

// A source can change how it times frames partway (a video whose timestamps stop increasing).
template <typename Warn>
void update_time_source(const capture::FrameSource& source, std::string& time_source, const Warn& warn) {
  const auto settings = source.settings();
  if (!settings.count("time_source") || settings.at("time_source") == time_source) return;
  time_source = settings.at("time_source");
  warn("time: " + time_source);
}

}  // namespace

ProcessReport run_process(const ProcessOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  ProcessReport report;
  const auto warn = [&](const std::string& message) {
    report.warnings.push_back(message);
    if (!options.quiet) std::fprintf(options.log, "tirstrain: warning: %s\n", message.c_str());
  };

  const std::optional<std::string> scene_path = scene_path_for(options);
  if (scene_path && !options.scene_path && !options.quiet)
    std::fprintf(options.log, "tirstrain: scene from the input folder: %s (--scene overrides it)\n",
                 scene_path->c_str());
  std::string stages_reason;
  Scene scene = scene_with_overrides(options, scene_path, stages_reason);
  if (!options.quiet) std::fprintf(options.log, "tirstrain: stages: %s\n", stages_reason.c_str());
  const std::vector<std::string> default_notes = default_value_notes(scene);
  for (const std::string& note : default_notes)
    if (!options.quiet) std::fprintf(options.log, "tirstrain: %s\n", note.c_str());
  // Made again once the first frame has told where the pattern band is.
  StagePlan plan = checked_plan(scene, options.strict, warn);

  std::unique_ptr<capture::FrameSource> source = capture::open_source(options.input);
  const auto settings = source->settings();
  const bool time_measured = settings.count("time_measured") == 0 || settings.at("time_measured") == "true";
  std::string time_source = settings.count("time_source") ? settings.at("time_source") : "source timestamps";
  if (!time_measured) {
    if (options.strict)
      throw Error("the input has no timestamps (no frames.csv) (--strict)", {.file = options.input});
    warn("no timestamps for " + options.input + ": " + time_source);
  }

  const std::unique_ptr<StagingDirectory> staging_folder = stage_output(options, scene_path);
  StagingDirectory& staging = *staging_folder;
  const fs::path out(staging.path());
  const fs::path final_out(staging.final_path());

  OverlayWriter overlay(options.overlay, staging.path(), options.log, options.quiet);
  Progress progress("process", source->frame_count() > 0 ? static_cast<long>(source->frame_count()) : 1L,
                    options.quiet, options.log);

  // Per-frame bookkeeping for /frames.
  std::vector<std::int64_t> index, device_id, lost_before;
  std::vector<double> t_s;
  std::vector<std::int32_t> frame_status;
  std::vector<char> usable;
  std::optional<TrialInfo> trial;
  cv::Size display_size;
  PatternBandChoice band;
  // Frames before the first usable one, given again to the stages made once that frame is seen.
  std::vector<capture::Frame> before_first;

  {
    PrefetchingReader reader(*source, 4);
    while (std::optional<capture::Frame> frame = reader.next()) {
      FrameContext context;
      context.frame = &*frame;
      context.usable = !frame->image.empty() && frame->status != capture::FrameStatus::kCorrupt &&
                       frame->status != capture::FrameStatus::kIncomplete;
      if (!context.usable) {
        const std::string what =
            frame->status == capture::FrameStatus::kIncomplete ? "is incomplete" : "could not be decoded";
        if (options.strict)
          throw Error("frame " + what + " (--strict)", {.file = frame->origin, .frame = frame->index});
        warn(format_error("frame " + what + "; marked and skipped",
                          {.file = frame->origin, .frame = frame->index}));
        ++report.frames_skipped;
      } else if (!trial) {
        band = resolve_pattern_band(scene, frame->image);
        if (!options.quiet) std::fprintf(options.log, "tirstrain: %s\n", band.describe().c_str());
        plan = plan_stages(scene);
        trial = TrialInfo{frame->image.size(), frame->image.depth(), source->frame_count(), &scene};
        display_size = frame->image.size();
        for (auto& stage : plan.stages) stage->start(*trial);
        for (const capture::Frame& earlier : before_first) {
          FrameContext unusable;
          unusable.frame = &earlier;
          for (auto& stage : plan.stages) stage->process(unusable);
        }
        before_first.clear();
      }
      if (trial) {
        for (auto& stage : plan.stages) stage->process(context);
      } else {
        capture::Frame kept = *frame;
        kept.image.release();
        before_first.push_back(std::move(kept));
      }

      index.push_back(frame->index);
      device_id.push_back(frame->device_frame_id);
      lost_before.push_back(frame->frames_lost_before);
      t_s.push_back(frame->device_time_s);
      frame_status.push_back(static_cast<std::int32_t>(frame->status));
      usable.push_back(context.usable ? 1 : 0);
      if (context.contact && (context.contact->status & contact::kNoContact) == 0)
        ++report.frames_with_contact;

      if (overlay.enabled() && trial) {
        cv::Mat bgr = to_display(context.usable ? frame->image : cv::Mat(), display_size);
        draw_band(bgr, band);
        for (const auto& stage : plan.stages) stage->draw(bgr, context);
        const double scale = std::max(1.0, bgr.cols / 640.0);
        char text[160];
        std::snprintf(text, sizeof text, "frame %lld  t = %.4f s  %s", static_cast<long long>(frame->index),
                      frame->device_time_s, context.usable ? "" : "(corrupt: skipped)");
        cv::putText(bgr, text, cv::Point(8, static_cast<int>(20 * scale)), cv::FONT_HERSHEY_SIMPLEX,
                    0.5 * scale, cv::Scalar(255, 255, 255), static_cast<int>(std::lround(scale)),
                    cv::LINE_AA);
        overlay.write(bgr);
      }
      ++report.frames;
      progress.update(static_cast<long>(report.frames));
    }
  }
  progress.finish();
  update_time_source(*source, time_source, warn);
  if (!trial) throw Error("no frame of the input could be decoded", {.file = options.input});
  finish_stages(scene, *trial, {index, device_id, lost_before, t_s, frame_status, usable}, plan.stages,
                options);

  const std::size_t n = t_s.size();
  // Outputs in order of increasing importance; result.h5 last, so its presence means a complete run.
  if (const std::string name = overlay.finish(); !name.empty())
    report.outputs.push_back((final_out / name).string());

  {
    std::vector<std::string> header = {"index", "t_s", "frame_status"};
    for (const auto& stage : plan.stages)
      for (const auto& column : stage->csv_header()) header.push_back(column);
    CsvWriter csv((out / "frames.csv").string(), header);
    std::vector<std::string> cells;
    for (std::size_t i = 0; i < n; ++i) {
      cells = {std::to_string(index[i]), format_double(t_s[i]), std::to_string(frame_status[i])};
      for (const auto& stage : plan.stages) stage->csv_row(i, cells);
      csv.row_text(cells);
    }
    csv.commit();
    report.outputs.push_back((final_out / "frames.csv").string());
  }

  nlohmann::json summary;
  summary["software"] = {{"name", "tirstrain"}, {"version", kVersion}};
  summary["input"] = options.input;
  summary["source"] = source->describe();
  summary["time_source"] = time_source;
  summary["time_measured"] = time_measured;
  summary["scene"] = scene.file.empty() ? "defaults" : scene.file;
  summary["px_per_mm"] = scene.px_per_mm;
  summarize_scene_sources(summary, scene, default_notes, stages_reason, band);
  std::vector<std::string> run_names;
  for (const auto& stage : plan.stages) run_names.push_back(stage->name());
  summary["stages_run"] = run_names;
  summary["stages_unavailable"] = plan.unavailable;
  std::map<std::string, std::int64_t> status_counts;
  std::int64_t lost = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ++status_counts[capture::to_string(static_cast<capture::FrameStatus>(frame_status[i]))];
    lost += lost_before[i];
  }
  summary["frames"] = {{"total", n},
                       {"skipped", report.frames_skipped},
                       {"status_counts", status_counts},
                       {"frames_lost", lost},
                       {"width_px", trial->frame_size.width},
                       {"height_px", trial->frame_size.height},
                       {"t_first_s", n ? t_s.front() : 0.0},
                       {"t_last_s", n ? t_s.back() : 0.0}};
  for (const auto& stage : plan.stages) stage->summarize(summary);
  summary["warnings"] = report.warnings;
  summary["wall_time_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  summary["outputs"] = {"result.h5", "frames.csv", "summary.json"};
  write_text_file((out / "summary.json").string(), summary.dump(2) + "\n");
  report.outputs.push_back((final_out / "summary.json").string());

  {
    H5Writer h5((out / "result.h5").string());
    h5.write("/frames/index", std::span<const std::int64_t>(index), {n});
    h5.write("/frames/t_s", std::span<const double>(t_s), {n});
    h5.write("/frames/status", std::span<const std::int32_t>(frame_status), {n});
    h5.write("/frames/device_frame_id", std::span<const std::int64_t>(device_id), {n});
    h5.write("/frames/frames_lost_before", std::span<const std::int64_t>(lost_before), {n});
    h5.attribute("/frames", "time_source", time_source);
    h5.attribute("/frames", "time_measured", time_measured ? 1.0 : 0.0);
    h5.attribute("/frames", "status_codes",
                 "0 ok; 1 incomplete; 2 corrupt (skipped); 3 gap_before; 4 overrun");
    h5.attribute("/frames", "width_px", static_cast<double>(trial->frame_size.width));
    h5.attribute("/frames", "height_px", static_cast<double>(trial->frame_size.height));
    for (const auto& stage : plan.stages) stage->write(h5);
    std::ostringstream scene_yaml;
    scene_yaml << scene_to_yaml(scene);
    h5.attribute("/", "format", "tirstrain result");
    h5.attribute("/", "format_version", 1.0);
    h5.attribute("/", "software_version", std::string("tirstrain ") + kVersion);
    h5.attribute("/", "scene_yaml", scene_yaml.str());
    h5.attribute("/", "scene_file", scene.file.empty() ? std::string("defaults") : scene.file);
    h5.attribute("/", "input", options.input);
    h5.attribute("/", "source", source->describe());
    std::string stages_text;
    for (const auto& name : run_names) {
      if (!stages_text.empty()) stages_text.push_back(',');
      stages_text.append(name);
    }
    h5.attribute("/", "stages", stages_text);
    h5.commit();
    report.outputs.push_back((final_out / "result.h5").string());
  }
  staging.commit();
  return report;
}

}  // namespace tirstrain::pipeline
