#include "pipeline/process.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <memory>

#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "core/archive.hpp"
#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_stream.hpp"
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

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// In the staging folder: the state an interrupted run continues from, and its result file while its
// flushed rows are copied into a fresh one.
constexpr const char* kCheckpointName = "checkpoint.bin";
constexpr const char* kInterruptedResult = "result.h5.interrupted";
// The largest share of a run's wall time that writing checkpoints may take.
constexpr double kCheckpointShare = 0.02;

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
  // A resumed run's overlay: PNG images go on from `frames`; a video holds only the frames from here on.
  void continue_after(std::int64_t frames) {
    count_ = mode_ == OverlayMode::kPng ? frames : 0;
    std::error_code ec;
    fs::remove(fs::path(out_dir_) / "overlay.mp4", ec);
  }
  bool video() const { return mode_ == OverlayMode::kMp4; }

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

// The pattern band's rectangle and where it came from, on the overlay: the label inside the band, at its
// inner edge.
void draw_band(cv::Mat& bgr, const PatternBandChoice& band, const OverlayText& overlay) {
  if (!band.roi_px) return;
  const RoiPx& r = *band.roi_px;
  cv::rectangle(bgr, cv::Rect(r.x, r.y, r.width, r.height), cv::Scalar(255, 120, 0), overlay.thickness());
  char text[96];
  if (band.confidence) {
    std::snprintf(text, sizeof text, "pattern band (%s, detected, confidence %.2f)", band.edge.c_str(),
                  *band.confidence);
  } else {
    std::snprintf(text, sizeof text, "pattern band (%s, from the scene)", band.edge.c_str());
  }
  const int inset = overlay.line_height_px();
  overlay.label(bgr, {r.x + inset / 2, band.edge == "top" ? r.y + r.height - inset / 3 : r.y + inset}, text,
                cv::Scalar(255, 170, 60));
}

// Where the status lines must not go: the pattern band, when there is one.
std::optional<cv::Rect> band_rect(const PatternBandChoice& band) {
  if (!band.roi_px) return std::nullopt;
  return cv::Rect(band.roi_px->x, band.roi_px->y, band.roi_px->width, band.roi_px->height);
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

// A compute list or --compute that asks for the channels of a scene without a channels: section reads the
// channel file beside the frames, as a run without a compute list does (docs/formats.md); without such a
// file the channels stage itself names what is missing.
void use_default_channels_when_asked(Scene& scene, const std::string& input, std::string& stages_reason) {
  const bool asked = std::find(scene.compute.begin(), scene.compute.end(), "channels") != scene.compute.end();
  if (!asked || !scene.channels.empty()) return;
  const std::string file = default_channel_file(input);
  const SceneSection section = default_channels_section(file);
  if (section.empty()) return;
  scene.channels = section;
  stages_reason += "; channels from " + file + " (no channels section in the scene)";
}

// A channel file beside the frames that the compute list leaves out is named, so that it is not missed.
void note_unused_channel_file(const Scene& scene, const std::string& input, std::string& stages_reason) {
  if (std::find(scene.compute.begin(), scene.compute.end(), "channels") != scene.compute.end()) return;
  const std::string file = default_channel_file(input);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return;
  stages_reason += "; " + file + " is not used (no channels in the compute list; --compute channels adds it)";
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
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string listed;
      for (const std::string& stage : known) listed += (listed.empty() ? "" : ", ") + stage;
      throw Error("unknown stage '" + name + "' (known: " + listed + ")", {.key = "--compute"});
    }
    if (std::find(scene.compute.begin(), scene.compute.end(), name) == scene.compute.end())
      scene.compute.push_back(name);
  }
  use_default_channels_when_asked(scene, options.input, stages_reason);
  note_unused_channel_file(scene, options.input, stages_reason);
  if (!options.tracking_preset.empty())
    scene.tracking = scene.tracking.with("preset", options.tracking_preset);
  if (!options.segmentation_preset.empty())
    scene.segmentation = scene.segmentation.with("preset", options.segmentation_preset);
  if (!options.strain_mode.empty()) scene.strain = scene.strain.with("mode", options.strain_mode);
  return scene;
}

// What the frame loop keeps of each frame (a few scalars: /frames, frames.csv, replaying the trial without
// its images).
struct FrameRows {
  std::vector<std::int64_t> index, device_id, lost_before;
  std::vector<double> t_s;
  std::vector<std::int32_t> status;
  std::vector<char> usable;

  void add(const capture::Frame& frame, bool frame_usable) {
    index.push_back(frame.index);
    device_id.push_back(frame.device_frame_id);
    lost_before.push_back(frame.frames_lost_before);
    t_s.push_back(frame.device_time_s);
    status.push_back(static_cast<std::int32_t>(frame.status));
    usable.push_back(frame_usable ? 1 : 0);
  }
  std::size_t size() const { return t_s.size(); }
  void archive(Archive& a) { a(index, device_id, lost_before, t_s, status, usable); }
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

// Every regular file an input names (a folder's, recursively, in order) with its size and modification
// time: a frame replaced or added since an interrupted run makes its checkpoint another input's.
nlohmann::json input_fingerprint(const std::string& input, const std::string& out_dir) {
  nlohmann::json files = nlohmann::json::array();
  const std::string staged = out_dir + ".partial";
  const auto add = [&](const fs::path& file) {
    std::error_code ec;
    const auto size = fs::file_size(file, ec);
    const auto time = fs::last_write_time(file, ec);
    files.push_back({file.string(), ec ? -1 : static_cast<std::int64_t>(size),
                     static_cast<std::int64_t>(time.time_since_epoch().count())});
  };
  for (const std::string& location : input_locations(input)) {
    std::error_code ec;
    if (!fs::is_directory(location, ec)) {
      if (fs::is_regular_file(location, ec)) add(location);
      continue;
    }
    std::vector<fs::path> inside;
    // The output, when it lies inside the input's folder, is not the input.
    for (auto entry = fs::recursive_directory_iterator(location, ec); !ec && entry != fs::end(entry);
         entry.increment(ec)) {
      if (entry->is_directory(ec)) {
        if (path_is_within(entry->path().string(), out_dir) || path_is_within(entry->path().string(), staged))
          entry.disable_recursion_pending();
        continue;
      }
      if (entry->is_regular_file(ec)) inside.push_back(entry->path());
    }
    std::sort(inside.begin(), inside.end());
    for (const fs::path& file : inside) add(file);
  }
  return files;
}

// The interrupted run's flushed rows cannot be read back: a kill while HDF5 rewrote a chunk leaves it
// damaged (the file format is not written crash-safe). The run starts again instead.
class InterruptedRunUnreadable : public Error {
 public:
  using Error::Error;
};

// One run of `process`: the steps of run_process(), sharing what they build.
class ProcessRun {
 public:
  explicit ProcessRun(const ProcessOptions& options) : options_(options) {}

  ProcessReport run() {
    plan_scene();
    open_input();
    open_outputs();
    if (resuming_) resume_from_checkpoint();
    read_frames();
    update_time_source(*source_, time_source_, warn());
    if (!trial_) throw Error("no frame of the input could be decoded", {.file = options_.input});
    finish_stages(scene_, *trial_, rows_, plan_.stages, options_);
    for (const auto& stage : plan_.stages)
      for (const std::string& w : stage->warnings()) warn()(stage->name() + ": " + w);
    warn_if_no_contact();
    // Outputs in order of increasing importance; result.h5 last, so its presence means a complete run.
    overlay_name_ = overlay_->finish();
    if (!overlay_name_.empty()) report_.outputs.push_back((final_out() / overlay_name_).string());
    write_frames_csv();
    write_summary();
    write_result();
    std::error_code ec;
    fs::remove(out() / kCheckpointName, ec);  // the run's own, not a result
    staging_->commit();
    return report_;
  }

 private:
  std::function<void(const std::string&)> warn() {
    return [this](const std::string& message) {
      report_.warnings.push_back(message);
      if (!options_.quiet) std::fprintf(options_.log, "tirstrain: warning: %s\n", message.c_str());
    };
  }
  // A recording without a fingertip in view (or of a texture with no ridges, a DIC speckle) gives an empty
  // result that must not pass for a measurement of nothing moving.
  void warn_if_no_contact() {
    const std::vector<std::string> stages = stage_names();
    if (report_.frames == 0 || report_.frames_with_contact > 0 ||
        std::find(stages.begin(), stages.end(), "contact") == stages.end())
      return;
    warn()(
        "no frame shows ridge texture in contact, so nothing was tracked; `tirstrain track` follows any "
        "texture (a speckle, say) without a contact");
  }
  void note(const std::string& message) const {
    if (!options_.quiet) std::fprintf(options_.log, "tirstrain: %s\n", message.c_str());
  }
  fs::path out() const { return staging_->path(); }
  fs::path final_out() const { return staging_->final_path(); }

  // The scene with the command line's overrides, and the stages it asks for.
  void plan_scene() {
    scene_path_ = scene_path_for(options_);
    if (scene_path_ && !options_.scene_path)
      note("scene from the input folder: " + *scene_path_ + " (--scene overrides it)");
    scene_ = scene_with_overrides(options_, scene_path_, stages_reason_);
    note("stages: " + stages_reason_);
    default_notes_ = default_value_notes(scene_);
    for (const std::string& line : default_notes_) note(line);
    // Made again once the first frame has told where the pattern band is.
    plan_ = checked_plan(scene_, options_.strict, warn());
    identity_ = run_identity();
  }

  // What a checkpoint must have been written by to be continued: the same input (its files as they were:
  // names, sizes and modification times), scene and options.
  std::string run_identity() const {
    const nlohmann::json j = {{"input", options_.input},
                              {"input_files", input_fingerprint(options_.input, options_.out_dir)},
                              {"scene", scene_to_yaml(scene_)},
                              {"frame_rate_Hz", options_.frame_rate_Hz ? *options_.frame_rate_Hz : -1.0},
                              {"strict", options_.strict},
                              {"overlay", static_cast<int>(options_.overlay)}};
    return j.dump();
  }

  void open_input() {
    source_ = capture::open_source(options_.input,
                                   capture::FileSourceOptions{.frame_rate_Hz = options_.frame_rate_Hz});
    const auto settings = source_->settings();
    time_measured_ = settings.count("time_measured") == 0 || settings.at("time_measured") == "true";
    time_source_ = settings.count("time_source") ? settings.at("time_source") : "source timestamps";
    if (time_measured_) return;
    if (options_.strict)
      throw Error("the input has no timestamps (no frames.csv) (--strict)", {.file = options_.input});
    warn()("no timestamps for " + options_.input + ": " + time_source_);
  }

  // The staging folder, and result.h5 in it from the start: per-frame results go there as frames are done.
  void open_outputs() {
    std::string final_dir = fs::path(options_.out_dir).lexically_normal().string();
    while (final_dir.size() > 1 && final_dir.back() == '/') final_dir.pop_back();
    const fs::path checkpoint = fs::path(final_dir + ".partial") / kCheckpointName;
    std::error_code ec;
    resuming_ = options_.resume && fs::is_regular_file(checkpoint, ec);
    if (options_.resume && !resuming_)
      note("no checkpoint of an interrupted run in " + final_dir + ".partial: starting from the first frame");
    if (!resuming_) {
      staging_ = stage_output(options_, scene_path_);
    } else {
      std::vector<std::string> inputs = input_locations(options_.input);
      if (scene_path_) inputs.push_back(*scene_path_);
      check_output_folder(options_.out_dir, inputs);
      open_checkpoint(checkpoint);  // refused before anything is touched
      staging_ = std::make_unique<StagingDirectory>(options_.out_dir, true);
      // The interrupted file's last writes may be cut off: its flushed rows go into a fresh one. A resumed
      // run that failed before copying them left the file under its new name.
      if (!fs::exists(out() / kInterruptedResult, ec))
        fs::rename(out() / "result.h5.partial", out() / kInterruptedResult, ec);
      if (ec)
        throw Error("cannot take over the interrupted run's result file: " + ec.message(),
                    {.file = (out() / "result.h5.partial").string()});
    }
    h5_ = std::make_unique<H5Stream>((out() / "result.h5").string());
    overlay_ =
        std::make_unique<OverlayWriter>(options_.overlay, staging_->path(), options_.log, options_.quiet);
  }

  void read_frames() {
    Progress progress("process", source_->frame_count() > 0 ? static_cast<long>(source_->frame_count()) : 1L,
                      options_.quiet, options_.log);
    PrefetchingReader reader(*source_, 4);
    for (std::int64_t k = 0; k < resumed_from_; ++k)
      if (!reader.next())
        throw Error("the input has fewer frames than the interrupted run processed (" +
                        std::to_string(resumed_from_) + ")",
                    {.file = options_.input});
    progress.update(static_cast<long>(report_.frames));
    while (std::optional<capture::Frame> frame = reader.next()) {
      process_frame(*frame);
      ++report_.frames;
      if (report_.frames % options_.flush_every_frames == 0) mark_progress();
      progress.update(static_cast<long>(report_.frames));
    }
    progress.finish();
    warn_if_fewer_frames_than_announced();
    warn_if_recording_incomplete();
    warn_if_frames_lost();
  }

  // A folder `tirstrain record` wrote (frames.csv with the camera's frame ids) ends with its recording.json,
  // which also says why it stopped: without it the recording was cut short; with a source or write error it
  // may end early.
  void warn_if_recording_incomplete() {
    const fs::path folder(options_.input);
    std::error_code ec;
    if (!fs::is_directory(folder, ec) || !fs::exists(folder / "frames.csv", ec)) return;
    std::ifstream csv(folder / "frames.csv");
    std::string header;
    std::getline(csv, header);
    if (header.find("device_frame_id") == std::string::npos) return;
    std::ifstream json(folder / "recording.json");
    if (!json) {
      warn()(
          "the recording has no recording.json, which `tirstrain record` writes when it stops: it was cut "
          "short (killed, power lost), and its last frames may be missing");
      return;
    }
    const nlohmann::json j = nlohmann::json::parse(json, nullptr, false);
    const std::string reason = j.is_object() ? j.value("stop_reason", std::string()) : std::string();
    if (reason == "source error" || reason == "write error")
      warn()("the recording stopped on a " + reason + " (recording.json): it may end before the trial did");
  }

  // Frames the camera or the recorder lost are gaps in the result; counted in summary.json, and said.
  void warn_if_frames_lost() {
    std::int64_t lost = 0, at_end = 0;
    for (const std::int64_t n : rows_.lost_before) lost += n;
    const auto settings = source_->settings();
    if (const auto after = settings.find("rows_after_last_image"); after != settings.end())
      at_end = std::stoll(after->second);
    if (lost + at_end > 0)
      warn()(std::to_string(lost + at_end) +
             " frames of the recording are missing (lost by the camera or the recorder, or their files are "
             "gone): the result has gaps there (frames.csv and /frames/frames_lost_before say where" +
             (at_end > 0 ? "; " + std::to_string(at_end) + " after the last image, which frames.csv lists"
                         : "") +
             ")");
  }

  // A container whose header announces more frames than could be read is most likely cut short (a copy
  // that did not finish, a full disk while recording): the frames read are processed, and that is said.
  void warn_if_fewer_frames_than_announced() {
    const std::int64_t announced = source_->frame_count();
    const auto read = static_cast<std::int64_t>(report_.frames);
    if (announced > 0 && read < announced)
      warn()("the input announces " + std::to_string(announced) + " frames but only " + std::to_string(read) +
             " could be read: the file may be cut short, and frames " + std::to_string(read) + " to " +
             std::to_string(announced - 1) + " are missing from the result");
  }

  // Flushed now and then, so that a run killed later leaves the frames before it readable, and said to be
  // incomplete both in result.h5.partial (`complete` 0) and in a summary.json of its own.
  void mark_progress() {
    h5_->mark_flushed(rows_.size());
    const auto now = std::chrono::steady_clock::now();
    const double since_s = std::chrono::duration<double>(now - last_checkpoint_).count();
    // A checkpoint grows with the trial (every track and record made so far): spaced so that writing them
    // takes at most kCheckpointShare of the run, however long it gets.
    const double interval_s = std::max(options_.checkpoint_every_s, checkpoint_cost_s_ / kCheckpointShare);
    if (trial_ && (checkpoint_rows_ == 0 || since_s >= interval_s)) {
      write_checkpoint();
      last_checkpoint_ = std::chrono::steady_clock::now();
      checkpoint_cost_s_ = std::chrono::duration<double>(last_checkpoint_ - now).count();
      checkpoint_rows_ = rows_.size();
    }
    const nlohmann::json partial = {{"complete", false},
                                    {"frames_written", rows_.size()},
                                    {"resumable_from_frame", checkpoint_rows_},
                                    {"input", recorded(options_.input)},
                                    {"result", "result.h5.partial"}};
    write_text_file((out() / "summary.json").string(), partial.dump(2) + "\n");
  }

  // What the run carries from frame to frame besides the stages: the frames' rows, the counts and warnings,
  // the pattern band and the trial's image format.
  void archive_run(Archive& a, cv::Size& frame_size, int& depth, std::int64_t& expected_frames) {
    a(rows_, report_.frames, report_.frames_skipped, report_.frames_with_contact, report_.warnings);
    a(band_.source, band_.roi_px, band_.edge, band_.confidence, band_.margin_px, display_size_);
    a(frame_size, depth, expected_frames, time_source_);
  }

  void write_checkpoint() {
    Archive a = Archive::for_writing();
    a(identity_);
    archive_run(a, trial_->frame_size, trial_->depth, trial_->expected_frames);
    for (auto& stage : plan_.stages) stage->archive(a);
    AtomicFile file((out() / kCheckpointName).string());
    file.append(std::string_view(a.bytes().data(), a.bytes().size()));
    file.commit();
  }

  // The checkpoint read, and refused unless the same input, scene and options wrote it.
  void open_checkpoint(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw Error("cannot read the checkpoint", {.file = path.string()});
    checkpoint_.emplace(Archive::for_reading(std::move(bytes)));
    std::string identity;
    (*checkpoint_)(identity);
    if (identity != identity_)
      throw Error(
          "the interrupted run was made from another input, scene or options; run without --resume "
          "to start again (which replaces it)",
          {.file = path.string()});
  }

  // The interrupted run's state put back: the stages made and started as at its first usable frame, then
  // given their state; its flushed rows copied into the fresh result file; its frames skipped in the input
  // (read_frames).
  void resume_from_checkpoint() {
    Archive& a = *checkpoint_;
    cv::Size frame_size;
    int depth = CV_8U;
    std::int64_t expected_frames = -1;
    archive_run(a, frame_size, depth, expected_frames);
    if (band_.source == "detected") {
      scene_.reference_pattern_roi = band_.roi_px;
      scene_.reference_pattern_margin_px = band_.margin_px;
    }
    plan_ = plan_stages(scene_);
    trial_ = TrialInfo{frame_size, depth, expected_frames, &scene_};
    trial_->out = h5_.get();
    for (auto& stage : plan_.stages) stage->start(*trial_);
    for (auto& stage : plan_.stages) stage->archive(a);
    a.expect_end();
    try {
      h5_->copy_rows_from((out() / kInterruptedResult).string(), rows_.size());
    } catch (const Error& e) {
      throw InterruptedRunUnreadable(e.message(), e.context());
    }
    h5_->mark_flushed(rows_.size());  // the checkpoint and the fresh file now agree without the old one
    checkpoint_.reset();
    std::error_code ec;
    fs::remove(out() / kInterruptedResult, ec);
    resumed_from_ = static_cast<std::int64_t>(rows_.size());
    checkpoint_rows_ = rows_.size();
    last_checkpoint_ = std::chrono::steady_clock::now();
    overlay_->continue_after(resumed_from_);
    note("resuming the interrupted run after frame " + std::to_string(resumed_from_) +
         " (its last checkpoint)");
    if (overlay_->video())
      warn()("the overlay video of a resumed run shows the frames from " + std::to_string(resumed_from_) +
             " on only");
  }

  // The frame's row of /frames, written with the stages' rows.
  void write_frame_row(const capture::Frame& frame) {
    const std::size_t r = rows_.size() - 1;
    const std::int32_t status = rows_.status.back();
    h5_->write_row("/frames/index", r, std::span<const std::int64_t>(&frame.index, 1), {}, std::int64_t{-1});
    h5_->write_row("/frames/t_s", r, std::span<const double>(&frame.device_time_s, 1), {}, kNaN);
    h5_->write_row("/frames/status", r, std::span<const std::int32_t>(&status, 1), {}, -1);
    h5_->write_row("/frames/device_frame_id", r, std::span<const std::int64_t>(&frame.device_frame_id, 1), {},
                   std::int64_t{-1});
    h5_->write_row("/frames/frames_lost_before", r,
                   std::span<const std::int64_t>(&frame.frames_lost_before, 1), {}, std::int64_t{0});
  }

  void process_frame(const capture::Frame& frame) {
    FrameContext context;
    context.frame = &frame;
    context.usable = !frame.image.empty() && frame.status != capture::FrameStatus::kCorrupt &&
                     frame.status != capture::FrameStatus::kIncomplete;
    if (!context.usable) {
      skip_frame(frame);
    } else if (!trial_) {
      start_stages(frame);
    }
    if (trial_) {
      for (auto& stage : plan_.stages) stage->process(context);
    } else {
      capture::Frame kept = frame;
      kept.image.release();
      before_first_.push_back(std::move(kept));
    }
    rows_.add(frame, context.usable);
    write_frame_row(frame);
    if (context.contact && (context.contact->status & contact::kNoContact) == 0)
      ++report_.frames_with_contact;
    if (overlay_->enabled() && trial_) draw_overlay(frame, context);
  }

  void skip_frame(const capture::Frame& frame) {
    const std::string what =
        frame.status == capture::FrameStatus::kIncomplete ? "is incomplete" : "could not be decoded";
    if (options_.strict)
      throw Error("frame " + what + " (--strict)", {.file = frame.origin, .frame = frame.index});
    warn()(
        format_error("frame " + what + "; marked and skipped", {.file = frame.origin, .frame = frame.index}));
    ++report_.frames_skipped;
  }

  // The first usable frame tells where the pattern band is: the stages are made now and shown the
  // unusable frames before it.
  void start_stages(const capture::Frame& frame) {
    band_ = resolve_pattern_band(scene_, frame.image);
    note(band_.describe());
    if (!band_.warning.empty()) warn()(band_.warning);
    plan_ = plan_stages(scene_);
    trial_ = TrialInfo{frame.image.size(), frame.image.depth(), source_->frame_count(), &scene_};
    trial_->out = h5_.get();
    display_size_ = frame.image.size();
    for (auto& stage : plan_.stages) stage->start(*trial_);
    for (const capture::Frame& earlier : before_first_) {
      FrameContext unusable;
      unusable.frame = &earlier;
      for (auto& stage : plan_.stages) stage->process(unusable);
    }
    before_first_.clear();
  }

  void draw_overlay(const capture::Frame& frame, const FrameContext& context) {
    cv::Mat bgr = to_display(context.usable ? frame.image : cv::Mat(), display_size_);
    const OverlayText overlay(bgr.size(), band_rect(band_));
    draw_band(bgr, band_, overlay);
    for (const auto& stage : plan_.stages) stage->draw(bgr, context, overlay);
    char text[160];
    std::snprintf(text, sizeof text, "frame %lld  t = %.4f s  %s", static_cast<long long>(frame.index),
                  frame.device_time_s, context.usable ? "" : "(corrupt: skipped)");
    overlay.status_line(bgr, 0, text);
    overlay_->write(bgr);
  }

  void write_frames_csv() {
    std::vector<std::string> header = {"index", "t_s", "frame_status"};
    for (const auto& stage : plan_.stages)
      for (const auto& column : stage->csv_header()) header.push_back(column);
    CsvWriter csv((out() / "frames.csv").string(), header);
    std::vector<std::string> cells;
    for (std::size_t i = 0; i < rows_.size(); ++i) {
      cells = {std::to_string(rows_.index[i]), format_double(rows_.t_s[i]), std::to_string(rows_.status[i])};
      for (const auto& stage : plan_.stages) stage->csv_row(i, cells);
      csv.row_text(cells);
    }
    csv.commit();
    report_.outputs.push_back((final_out() / "frames.csv").string());
  }

  std::vector<std::string> stage_names() const {
    std::vector<std::string> names;
    for (const auto& stage : plan_.stages) names.push_back(stage->name());
    return names;
  }

  void write_summary() {
    const std::size_t n = rows_.size();
    nlohmann::json summary;
    summary["software"] = {{"name", "tirstrain"}, {"version", kVersion}};
    summary["complete"] = true;
    summary["input"] = recorded(options_.input);
    summary["source"] = recorded(source_->describe());
    summary["time_source"] = recorded(time_source_);
    summary["time_measured"] = time_measured_;
    summary["scene"] = scene_.file.empty() ? "defaults" : recorded(scene_.file);
    summary["px_per_mm"] = scene_.px_per_mm;
    summarize_scene_sources(summary, scene_, default_notes_, recorded(stages_reason_), band_);
    summary["stages_run"] = stage_names();
    summary["stages_unavailable"] = plan_.unavailable;
    std::map<std::string, std::int64_t> status_counts;
    std::int64_t lost = 0;
    for (std::size_t i = 0; i < n; ++i) {
      ++status_counts[capture::to_string(static_cast<capture::FrameStatus>(rows_.status[i]))];
      lost += rows_.lost_before[i];
    }
    summary["frames"] = {{"total", n},
                         {"skipped", report_.frames_skipped},
                         {"status_counts", status_counts},
                         {"frames_lost", lost},
                         {"width_px", trial_->frame_size.width},
                         {"height_px", trial_->frame_size.height},
                         {"t_first_s", n ? rows_.t_s.front() : 0.0},
                         {"t_last_s", n ? rows_.t_s.back() : 0.0}};
    for (const auto& stage : plan_.stages) stage->summarize(summary);
    summary["warnings"] = nlohmann::json::array();
    for (const std::string& w : report_.warnings) summary["warnings"].push_back(recorded(w));
    if (resumed_from_ > 0) summary["resumed_from_frame"] = resumed_from_;
    summary["wall_time_s"] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
    summary["outputs"] = {"result.h5", "frames.csv", "summary.json"};
    if (!overlay_name_.empty()) summary["outputs"].push_back(overlay_name_);
    write_text_file((out() / "summary.json").string(), summary.dump(2) + "\n");
    report_.outputs.push_back((final_out() / "summary.json").string());
  }

  void write_result() {
    H5Stream& h5 = *h5_;
    const std::size_t n = rows_.size();
    h5.attribute("/frames", "time_source", recorded(time_source_));
    h5.attribute("/frames", "time_measured", time_measured_ ? 1.0 : 0.0);
    h5.attribute("/frames", "status_codes",
                 "0 ok; 1 incomplete; 2 corrupt (skipped); 3 gap_before; 4 overrun");
    h5.attribute("/frames", "width_px", static_cast<double>(trial_->frame_size.width));
    h5.attribute("/frames", "height_px", static_cast<double>(trial_->frame_size.height));
    for (const auto& stage : plan_.stages) stage->write(h5);
    h5.attribute("/", "format", "tirstrain result");
    h5.attribute("/", "format_version", 1.0);
    h5.attribute("/", "software_version", std::string("tirstrain ") + kVersion);
    h5.attribute("/", "scene_yaml", scene_to_yaml(scene_));
    h5.attribute("/", "scene_file", scene_.file.empty() ? std::string("defaults") : recorded(scene_.file));
    h5.attribute("/", "input", recorded(options_.input));
    h5.attribute("/", "source", recorded(source_->describe()));
    std::string stages_text;
    for (const auto& name : stage_names()) {
      if (!stages_text.empty()) stages_text.push_back(',');
      stages_text.append(name);
    }
    h5.attribute("/", "stages", stages_text);
    h5.attribute("/", "frames_written", static_cast<double>(n));
    h5.commit();
    report_.outputs.push_back((final_out() / "result.h5").string());
  }

  const ProcessOptions& options_;
  const std::chrono::steady_clock::time_point wall_start_ = std::chrono::steady_clock::now();
  // Continuing an interrupted run (--resume): from its checkpoint, frames 0 … resumed_from_ − 1 done.
  std::string identity_;
  bool resuming_ = false;
  std::optional<Archive> checkpoint_;  // being read back, until the stages have their state
  std::int64_t resumed_from_ = 0;
  std::size_t checkpoint_rows_ = 0;  // frames the last checkpoint holds
  std::chrono::steady_clock::time_point last_checkpoint_;
  double checkpoint_cost_s_ = 0.0;  // how long the last one took to write
  ProcessReport report_;
  std::optional<std::string> scene_path_;
  std::string stages_reason_;
  std::string overlay_name_;  // overlay.mp4 or overlay/ once written; empty with --overlay none
  Scene scene_;
  std::vector<std::string> default_notes_;
  StagePlan plan_;
  std::unique_ptr<capture::FrameSource> source_;
  bool time_measured_ = true;
  std::string time_source_;

  // A path as the outputs record it: where it will be once the caller's staging folders are swapped in.
  std::string recorded(const std::string& path) const { return recorded_path(path, options_.staged_folders); }

  // Declared in this order so that an error closes result.h5 and the overlay before the staging folder
  // (destroyed uncommitted) is removed.
  std::unique_ptr<StagingDirectory> staging_;
  std::unique_ptr<H5Stream> h5_;
  std::unique_ptr<OverlayWriter> overlay_;
  FrameRows rows_;
  std::optional<TrialInfo> trial_;
  cv::Size display_size_;
  PatternBandChoice band_;
  // Frames before the first usable one, given again to the stages made once that frame is seen.
  std::vector<capture::Frame> before_first_;
};

}  // namespace

ProcessReport run_process(const ProcessOptions& options) {
  if (options.flush_every_frames < 1)
    throw Error("must be at least 1 (frames between flushes of the partial result)",
                {.key = "--flush-every-frames"});
  try {
    return ProcessRun(options).run();
  } catch (const InterruptedRunUnreadable& e) {
    if (!options.quiet)
      std::fprintf(
          options.log,
          "tirstrain: the interrupted run's result cannot be read back (%s): starting again from the "
          "first frame\n",
          e.what());
    ProcessOptions again = options;
    again.resume = false;
    return ProcessRun(again).run();
  }
}

}  // namespace tirstrain::pipeline
