// `tirstrain live URI [--scene FILE.yaml] [--record DIR] [--no-window]`: the camera on screen with frame
// rate and losses, optionally recording at the same time without the display slowing the recording.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "capture/live.hpp"
#include "core/error.hpp"
#include "core/overlay_text.hpp"
#include "core/scene.hpp"
#include "pipeline/output_folder.hpp"
#include "pipeline/process_defaults.hpp"
#include "pipeline/stage.hpp"
#include "tirstrain/camera_options.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

// The scene's analysis stages (contact, tracking, strain; not channels, which need recorded files, nor fit,
// which fits a finished trial) run on the frames the display shows and draw onto them. Stages keep only the
// newest frame (TrialInfo::keep_history).
class LiveAnalysis {
 public:
  explicit LiveAnalysis(Scene scene) : scene_(std::move(scene)) {
    for (const char* offline : {"channels", "fit"})
      scene_.compute.erase(std::remove(scene_.compute.begin(), scene_.compute.end(), offline),
                           scene_.compute.end());
    if (!scene_.compute.empty()) plan_ = pipeline::plan_stages(scene_);
  }

  void run(const capture::Frame& frame, cv::Mat& canvas) {
    pipeline::FrameContext context;
    context.frame = &frame;
    context.usable = !frame.image.empty() && frame.status != capture::FrameStatus::kCorrupt &&
                     frame.status != capture::FrameStatus::kIncomplete;
    if (!started_) {
      if (!context.usable) return;
      pipeline::check_pattern_band(scene_, frame.image.size());
      info_ = pipeline::TrialInfo{frame.image.size(), frame.image.depth(), -1, &scene_, false};
      for (auto& stage : plan_.stages) stage->start(info_);
      started_ = true;
    }
    if (context.usable && frame.image.size() != info_.frame_size) return;  // a camera reconfigured mid-run
    for (auto& stage : plan_.stages) stage->process(context);
    std::optional<cv::Rect> band;
    if (const auto& r = scene_.reference_pattern_roi) band = cv::Rect(r->x, r->y, r->width, r->height);
    const OverlayText overlay(canvas.size(), band);
    for (const auto& stage : plan_.stages) stage->draw(canvas, context, overlay);
    ++analysed_;
  }

  std::string describe() const {
    std::string names;
    for (const auto& stage : plan_.stages) names += (names.empty() ? "" : ", ") + stage->name();
    return names.empty() ? "none" : names;
  }
  std::int64_t analysed() const { return analysed_; }

 private:
  Scene scene_;
  pipeline::StagePlan plan_;
  pipeline::TrialInfo info_;
  bool started_ = false;
  std::int64_t analysed_ = 0;
};

struct LiveArgs {
  std::string uri, scene, record, format = "tiff";
  std::optional<double> frame_rate_Hz;
  std::int64_t frames = -1;
  double seconds = -1;
  bool no_window = false, quiet = false, overwrite = false, recorded_rate = false;
};

void print_status(const capture::LiveStatus& s) {
  std::fprintf(stderr,
               "live: %6.1f s  %lld frames  %.1f fps received  %.1f fps shown  lost %lld  incomplete %lld  "
               "latency %.1f ms\n",
               s.elapsed_s, static_cast<long long>(s.frames_received), s.receive_rate_hz, s.show_rate_hz,
               static_cast<long long>(s.frames_lost), static_cast<long long>(s.frames_incomplete),
               s.latency_ms);
}

capture::LiveOptions live_options(const LiveArgs& args, const std::shared_ptr<LiveAnalysis>& analysis) {
  capture::LiveOptions options;
  options.window = !args.no_window;
  options.record_dir = args.record;
  options.record.format = capture::parse_image_format(args.format, "--format");
  options.record.overwrite = args.overwrite;
  options.record.input_paths = pipeline::input_locations(args.uri);
  options.max_frames = args.frames;
  options.max_seconds = args.seconds;
  options.play_at_recorded_rate = args.recorded_rate;
  if (analysis) {
    options.overlay = [analysis](const capture::Frame& frame, cv::Mat& canvas) {
      analysis->run(frame, canvas);
    };
    options.on_analysis_error = [](const std::string& message) {
      std::fprintf(stderr, "live: analysis stopped: %s; capture and recording go on\n", message.c_str());
    };
  }
  install_interrupt_handler();
  options.stop = &interrupt_flag();
  if (!args.quiet) options.on_status = print_status;
  return options;
}

// What was received, shown, lost and saved, and one line with the capture -> display latency of the whole
// run (median / p95 / max, ms).
void print_summary(const capture::LiveReport& report, const LiveArgs& args, const LiveAnalysis* analysis) {
  const capture::LiveStatus& s = report.status;
  std::cerr << "live: " << s.frames_received << " frames received, " << s.frames_shown << " shown, "
            << s.frames_lost << " lost, " << s.frames_incomplete << " incomplete";
  if (report.recorded) std::cerr << "; " << report.record.counts.frames_saved << " saved to " << args.record;
  std::cerr << "\n";
  auto latency = [](const char* name, const capture::LatencySummary& l) {
    return cv::format("%s %.2f / %.2f / %.2f ms (%lld frames)", name, l.median_ms, l.p95_ms, l.max_ms,
                      static_cast<long long>(l.frames));
  };
  std::string line = "live: latency median / p95 / max: " +
                     latency("host receive -> overlay ready", report.receive_to_ready);
  if (report.receive_to_shown.frames > 0)
    line += "; " + latency("host receive -> imshow returned", report.receive_to_shown);
  if (report.device_to_ready.frames > 0)
    line += "; " + latency("device timestamp -> overlay ready", report.device_to_ready);
  std::cerr << line << "\n";
  if (analysis)
    std::cerr << "live: analysis stages: " << analysis->describe() << " (" << analysis->analysed()
              << " frames analysed)\n";
}

void run_live_command(const LiveArgs& args, const CameraArgs& camera) {
  // Loaded (and its stages built) now, so a bad scene fails before the camera starts.
  std::shared_ptr<LiveAnalysis> analysis;
  std::optional<Scene> scene;
  if (!args.scene.empty()) {
    scene = load_scene(args.scene);
    analysis = std::make_shared<LiveAnalysis>(*scene);
  }
  if (!args.no_window) capture::check_display();  // before the camera starts
  const capture::CameraSettings settings = camera_settings(camera, scene ? &*scene : nullptr);
  capture::LiveOptions options = live_options(args, analysis);
  std::unique_ptr<capture::FrameSource> source = capture::open_source(
      args.uri, settings, capture::FileSourceOptions{.frame_rate_Hz = args.frame_rate_Hz});
  if (source->is_live()) options.record.requested_settings = capture::describe_requested(settings);
  if (!args.quiet) std::cerr << "live: " << source->describe() << "\n";
  const capture::LiveReport report = capture::run_live(*source, options);
  print_summary(report, args, analysis.get());
  if (!report.error.empty()) throw Error("live view stopped: " + report.error);
  if (!report.analysis_error.empty())
    throw Error("the analysis stopped: " + report.analysis_error +
                (report.recorded ? " (the recording in " + args.record + " is complete)" : std::string()));
}

}  // namespace

void add_live_command(CLI::App& app) {
  auto args = std::make_shared<LiveArgs>();
  auto camera = std::make_shared<CameraArgs>();
  CLI::App* sub = app.add_subcommand(
      "live",
      "Show a camera live with the achieved frame rate, lost and incomplete frames and display latency;\n"
      "optionally record at the same time (--record DIR, same folder layout as 'tirstrain record').\n"
      "--no-window runs the same capture and analysis headless and prints a status line per second.\n"
      "With --scene, the stages its compute list asks for (contact, tracking, strain) run on the frames "
      "shown\n"
      "and draw the hull, ellipse, tracks and a strain heat map; the display skips frames when they are "
      "slow,\n"
      "the recording never does.\n"
      "Keys: q or Esc quits. Ctrl-C stops cleanly.");
  sub->add_option("URI", args->uri,
                  "Source: aravis:ID or aravis:IP, v4l2:/dev/videoN, libcamera:ID (tirstrain cameras lists "
                  "them), or a file source")
      ->required();
  sub->add_option(
      "--scene", args->scene,
      "Scene file (YAML): calibration, what to compute, and the camera: section (settings that the "
      "camera flags below override)");
  sub->add_option("--frame-rate-Hz", args->frame_rate_Hz,
                  "Frame rate (Hz) of a recording whose file holds no timestamps and has no frames.csv "
                  "beside it (a multi-page TIFF, a folder of images)")
      ->check(kPositive);
  sub->add_flag("--recorded-rate", args->recorded_rate,
                "Play a recording at the rate its timestamps give, as the camera delivered it (default: as "
                "fast as it is read). Example: tirstrain live REC --scene REC/scene.yaml --recorded-rate");
  sub->add_option("--record", args->record, "Also record losslessly into this folder");
  sub->add_option("--format", args->format, "Recording image format: tiff (default), pgm, png")
      ->check(CLI::IsMember({"png", "tiff", "pgm"}));
  sub->add_flag("--overwrite", args->overwrite, "Replace a recording already in the --record folder");
  sub->add_option("--frames", args->frames, "Stop after N frames")->check(kPositive);
  sub->add_option("--seconds", args->seconds, "Stop after S seconds")->check(kPositive);
  sub->add_flag("--no-window", args->no_window, "No display: print status lines (headless machines)");
  sub->add_flag("--quiet", args->quiet, "No status lines");
  add_camera_options(sub, camera);
  sub->callback([args, camera] { run_live_command(*args, *camera); });
}

}  // namespace tirstrain::cli
