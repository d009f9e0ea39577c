// `tirstrain live URI [--scene FILE.yaml] [--record DIR] [--no-window]`: the camera on screen with frame
// rate and losses, optionally recording at the same time without the display slowing the recording.
#include <cstdio>
#include <iostream>
#include <memory>

#include "capture/frame_source.hpp"
#include "capture/live.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "tirstrain/camera_options.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {

void add_live_command(CLI::App& app) {
  struct Args {
    std::string uri, scene, record, format = "tiff";
    std::int64_t frames = -1;
    double seconds = -1;
    bool no_window = false, quiet = false, overwrite = false;
  };
  auto args = std::make_shared<Args>();
  auto camera = std::make_shared<CameraArgs>();
  CLI::App* sub = app.add_subcommand(
      "live",
      "Show a camera live with the achieved frame rate, lost and incomplete frames and display latency;\n"
      "optionally record at the same time (--record DIR, same folder layout as 'tirstrain record').\n"
      "--no-window runs the same capture and analysis headless and prints a status line per second.\n"
      "Analysis overlays (contact, tracks, strain) appear here as those stages become available.\n"
      "Keys: q or Esc quits. Ctrl-C stops cleanly.");
  sub->add_option("URI", args->uri, "Source: aravis:ID, aravis:IP, or a file source")->required();
  sub->add_option("--scene", args->scene, "Scene file (YAML): calibration and what to compute");
  sub->add_option("--record", args->record, "Also record losslessly into this folder");
  sub->add_option("--format", args->format, "Recording image format: tiff (default), pgm, png")
      ->check(CLI::IsMember({"png", "tiff", "pgm"}));
  sub->add_flag("--overwrite", args->overwrite, "Replace a recording already in the --record folder");
  sub->add_option("--frames", args->frames, "Stop after N frames")->check(CLI::PositiveNumber);
  sub->add_option("--seconds", args->seconds, "Stop after S seconds")->check(CLI::PositiveNumber);
  sub->add_flag("--no-window", args->no_window, "No display: print status lines (headless machines)");
  sub->add_flag("--quiet", args->quiet, "No status lines");
  add_camera_options(sub, camera);
  sub->callback([args, camera] {
    // Validated now so a bad scene fails before the camera starts; its stages plug into the overlay hook.
    if (!args->scene.empty()) (void)load_scene(args->scene);
    if (!args->no_window) capture::check_display();  // before the camera starts
    const capture::CameraSettings settings = to_settings(*camera);
    capture::LiveOptions options;
    options.window = !args->no_window;
    options.record_dir = args->record;
    options.record.format = capture::parse_image_format(args->format, "--format");
    options.record.overwrite = args->overwrite;
    options.max_frames = args->frames;
    options.max_seconds = args->seconds;
    install_interrupt_handler();
    options.stop = &interrupt_flag();
    if (!args->quiet)
      options.on_status = [](const capture::LiveStatus& s) {
        std::fprintf(
            stderr,
            "live: %6.1f s  %lld frames  %.1f fps received  %.1f fps shown  lost %lld  incomplete %lld  "
            "latency %.1f ms\n",
            s.elapsed_s, static_cast<long long>(s.frames_received), s.receive_rate_hz, s.show_rate_hz,
            static_cast<long long>(s.frames_lost), static_cast<long long>(s.frames_incomplete), s.latency_ms);
      };
    std::unique_ptr<capture::FrameSource> source = capture::open_source(args->uri, settings);
    if (!args->quiet) std::cerr << "live: " << source->describe() << "\n";
    const capture::LiveReport report = capture::run_live(*source, options);
    const capture::LiveStatus& s = report.status;
    std::cerr << "live: " << s.frames_received << " frames received, " << s.frames_shown << " shown, "
              << s.frames_lost << " lost, " << s.frames_incomplete << " incomplete";
    if (report.recorded)
      std::cerr << "; " << report.record.counts.frames_saved << " saved to " << args->record;
    std::cerr << "\n";
    if (!report.error.empty()) throw Error("live view stopped: " + report.error);
  });
}

}  // namespace tirstrain::cli
