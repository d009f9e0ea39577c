// `tirstrain record URI --out DIR [--frames N | --seconds S]`: lossless recording from a camera (or any
// source) into a folder that `tirstrain process` reads directly.
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "capture/frame_source.hpp"
#include "capture/recorder.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "pipeline/output_folder.hpp"
#include "tirstrain/camera_options.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

void print_progress(const capture::RecordProgress& p) {
  std::fprintf(
      stderr,
      "record: %6.1f s  %lld received (%.1f fps)  %lld saved  queue %lld  incomplete %lld  lost %lld%s\n",
      p.elapsed_s, static_cast<long long>(p.frames_received), p.receive_rate_hz,
      static_cast<long long>(p.frames_saved), static_cast<long long>(p.queue_frames),
      static_cast<long long>(p.frames_incomplete),
      static_cast<long long>(p.frames_lost_device + p.frames_dropped_host),
      p.frames_dropped_host > 0 ? "  WARNING: the disk cannot keep up, frames are being dropped" : "");
}

struct RecordArgs {
  std::string uri, out, scene, format = "tiff";
  std::int64_t frames = -1;
  double seconds = -1;
  int png_level = 1, writers = 2;
  std::size_t queue_MiB = 512;
  bool overwrite = false, quiet = false;
};

capture::RecordOptions record_options(const RecordArgs& args) {
  capture::RecordOptions options;
  options.out_dir = args.out;
  options.max_frames = args.frames;
  options.max_seconds = args.seconds;
  options.format = capture::parse_image_format(args.format, "--format");
  options.png_level = args.png_level;
  options.writer_threads = args.writers;
  options.queue_bytes = args.queue_MiB * 1024u * 1024u;
  options.overwrite = args.overwrite;
  options.input_paths = pipeline::input_locations(args.uri);
  install_interrupt_handler();
  options.stop = &interrupt_flag();
  if (!args.quiet) options.on_progress = print_progress;
  return options;
}

// What was saved, received and lost, a warning per kind of loss, and an error when the recording stopped
// early (what was saved before it stays).
void report_recording(const capture::RecordReport& report, const std::string& out,
                      std::int64_t frames_asked) {
  const capture::RecordProgress& c = report.counts;
  const std::string& saved_in = report.folder.empty() ? out : report.folder;
  std::cerr << "record: " << c.frames_saved << " frames saved to " << saved_in << " in " << report.elapsed_s
            << " s (" << c.frames_received << " received, " << c.frames_incomplete << " incomplete, "
            << c.frames_lost_device << " lost by the camera/network, " << c.frames_dropped_host
            << " dropped because the disk could not keep up); stopped: " << report.stop_reason << "\n";
  if (report.stop_reason == "end of stream" && frames_asked > 0 && c.frames_received < frames_asked)
    std::cerr << "record: the source ended after " << c.frames_received << " frames, before the "
              << frames_asked << " --frames asked for: the recording holds all the source had\n";
  if (c.frames_dropped_host > 0)
    std::cerr
        << "record: WARNING: " << c.frames_dropped_host
        << " frames were dropped because writing could not keep up; try --format pgm, more --writers or "
           "a faster disk\n";
  if (c.frames_incomplete > 0 || c.frames_lost_device > 0)
    std::cerr << "record: WARNING: " << c.frames_incomplete
              << " incomplete frames (listed in frames.csv with "
              << "status 1, no image) and " << c.frames_lost_device << " frames never received\n";
  if (!report.ok())
    throw Error("recording stopped early: " + report.error + " -- the " + std::to_string(c.frames_saved) +
                " frames before it are saved in " + saved_in);
}

void run_record_command(const RecordArgs& args, const CameraArgs& camera) {
  std::optional<Scene> scene;
  if (!args.scene.empty()) scene = load_scene(args.scene);
  const capture::CameraSettings settings = camera_settings(camera, scene ? &*scene : nullptr);
  capture::RecordOptions options = record_options(args);
  std::unique_ptr<capture::FrameSource> source = capture::open_source(args.uri, settings);
  // File sources ignore a scene's camera: section (it describes the camera that made them).
  if (source->is_live()) options.requested_settings = capture::describe_requested(settings);
  if (!args.quiet) std::cerr << "record: " << source->describe() << "\n";
  report_recording(capture::record(*source, options), args.out, args.frames);
}

}  // namespace

void add_record_command(CLI::App& app) {
  auto args = std::make_shared<RecordArgs>();
  auto camera = std::make_shared<CameraArgs>();
  CLI::App* sub = app.add_subcommand(
      "record",
      "Record frames losslessly from a camera (aravis:<device id or IP>) or any other source.\n"
      "Writes DIR/frames/NNNNNN.tif (numbered by the camera's frame counter, so lost frames are missing\n"
      "numbers), DIR/frames.csv (index,t_s,device_frame_id,device_time_s,host_time_s,status,...) and\n"
      "DIR/recording.json (settings read back from the device, what was asked, counts, why it stopped).\n"
      "Camera settings come from the scene's camera: section (--scene) and the flags below, which override\n"
      "it. DIR is a valid input for 'tirstrain process'. Ctrl-C stops cleanly. See docs/capture.md.");
  sub->footer(
      "Examples:\n"
      "  tirstrain record aravis:192.168.1.20 --out REC --seconds 10\n"
      "  tirstrain record v4l2:/dev/video0 --out REC --frames 500");
  sub->add_option("URI", args->uri,
                  "Source: aravis:ID or aravis:IP, v4l2:/dev/videoN, libcamera:ID (tirstrain cameras lists "
                  "them), or a file source")
      ->required();
  sub->add_option("--out", args->out, "Output folder")->required();
  sub->add_option(
      "--scene", args->scene,
      "Scene file (YAML) whose camera: section sets pixel format, ROI, exposure, gain, frame rate, "
      "trigger, packet size and buffers");
  auto* frames = sub->add_option("--frames", args->frames, "Stop after N frames received")->check(kPositive);
  auto* seconds = sub->add_option("--seconds", args->seconds, "Stop after S seconds")->check(kPositive);
  frames->excludes(seconds);
  sub->add_option(
         "--format", args->format,
         "Image format: tiff (default, uncompressed), pgm (raw), png (smaller, ~10x slower to write)")
      ->check(CLI::IsMember({"png", "tiff", "pgm"}));
  sub->add_option("--png-level", args->png_level, "PNG zlib level 0..9 (default 1: fast, lossless)")
      ->check(CLI::Range(0, 9));
  sub->add_option("--writers", args->writers, "Writer threads, 1..64 (default 2)")->check(CLI::Range(1, 64));
  sub->add_option("--queue-MiB", args->queue_MiB,
                  "Frames held for the writers before dropping, 16..1048576 MiB (default 512)")
      ->check(CLI::Range(std::size_t{16}, std::size_t{1} << 20));
  sub->add_flag("--overwrite", args->overwrite, "Replace a recording already in DIR");
  sub->add_flag("--quiet", args->quiet, "Only errors and the final summary");
  add_camera_options(sub, camera);
  sub->callback([args, camera] { run_record_command(*args, *camera); });
}

}  // namespace tirstrain::cli
