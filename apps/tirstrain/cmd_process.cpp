// `tirstrain process INPUT --out DIR`: run the analysis stages over a recording and write the results.
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/process.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

struct ProcessArgs {
  std::string input, scene, out, overlay = "mp4", preset, segmentation, strain_mode;
  std::optional<double> frame_rate_Hz;
  std::vector<std::string> compute;
  std::int64_t flush_every_frames = 64;
  double checkpoint_every_s = 30.0;
  bool quiet = false, strict = false, no_scene = false, resume = false;
};

const char* const kProcessHelp =
    "Measure contact, tracks, strain and channels from a recording: the stages the scene's compute list\n"
    "asks for, or without one every stage whose inputs exist (channels: a channels: section, or\n"
    "channels.csv beside the frames with tirstrain synth's column names). The model fit (fit) runs only\n"
    "when the scene or --compute asks for it.\n"
    "INPUT: a folder of frames (DIR/frames/*.png + DIR/frames.csv, or images directly in DIR), a printf "
    "or\n"
    "glob pattern ('run/img_%05d.tif', 'run/*.png'), or a video file. Time comes from frames.csv "
    "(index,t_s)\n"
    "or the video's timestamps. Without --scene: INPUT/scene.yaml if INPUT is a folder holding one (as\n"
    "tirstrain synth writes), else 52 px/mm, E = 1 MPa, nu = 0.4, depth 2 mm (each default is said on\n"
    "the console and in summary.json), and ridge period, polarity, contact and the glass's printed\n"
    "pattern band (along any image edge, or none) found from the images.\n"
    "Writes DIR/result.h5, DIR/frames.csv, DIR/summary.json and DIR/overlay.mp4 (see docs/formats.md),\n"
    "built in DIR.partial and swapped in for DIR only when complete: an earlier result stays whole until\n"
    "then. DIR must not be, or hold, INPUT or the scene, nor hold files process does not write.\n"
    "A run that is interrupted (killed, power lost) leaves DIR.partial with the frames before its last\n"
    "flush and a checkpoint; --resume continues from there with the same input, scene and options and\n"
    "gives the result an uninterrupted run gives.\n"
    "Example: tirstrain process recording/ --out result/   (then, if it was killed: add --resume)";

pipeline::ProcessOptions process_options(const ProcessArgs& args) {
  pipeline::ProcessOptions options;
  options.input = args.input;
  options.frame_rate_Hz = args.frame_rate_Hz;
  if (!args.scene.empty()) options.scene_path = args.scene;
  options.folder_scene = !args.no_scene;
  options.out_dir = args.out;
  options.quiet = args.quiet;
  options.strict = args.strict;
  static const std::map<std::string, pipeline::OverlayMode> modes = {{"mp4", pipeline::OverlayMode::kMp4},
                                                                     {"png", pipeline::OverlayMode::kPng},
                                                                     {"none", pipeline::OverlayMode::kNone}};
  options.overlay = modes.at(args.overlay);
  options.compute = args.compute;
  options.tracking_preset = args.preset;
  options.segmentation_preset = args.segmentation;
  options.strain_mode = args.strain_mode;
  options.flush_every_frames = args.flush_every_frames;
  options.resume = args.resume;
  options.checkpoint_every_s = args.checkpoint_every_s;
  return options;
}

void run_process_command(const ProcessArgs& args) {
  const pipeline::ProcessReport report = pipeline::run_process(process_options(args));
  if (args.quiet) return;
  std::cerr << "processed " << report.frames << " frames (" << report.frames_with_contact << " with contact";
  if (report.frames_skipped > 0) std::cerr << ", " << report.frames_skipped << " skipped";
  std::cerr << ") -> " << args.out << "\n";
}

}  // namespace

void add_process_command(CLI::App& app) {
  auto args = std::make_shared<ProcessArgs>();
  CLI::App* sub = app.add_subcommand("process", kProcessHelp);
  sub->add_option("INPUT", args->input,
                  "Frames folder, image pattern, multi-page TIFF, .cine, .mraw/.cih or video file "
                  "(docs/formats.md)")
      ->required();
  sub->add_option("--frame-rate-Hz", args->frame_rate_Hz,
                  "Frame rate (Hz) of a recording whose file holds no timestamps and has no frames.csv "
                  "beside it (a multi-page TIFF, a folder of images)")
      ->check(kPositive);
  sub->add_option("--scene", args->scene, "Scene file (YAML) for calibration and what to compute");
  sub->add_flag(
      "--no-scene", args->no_scene,
      "Use the defaults even when INPUT holds a scene.yaml (what a recording without a scene gets)");
  sub->add_option("--out", args->out, "Output folder (created if needed; replaced as a whole when complete)")
      ->required();
  sub->add_option(
         "--compute", args->compute,
         "Stages to run in addition to the scene's compute list (or the default one): contact, tracking, "
         "strain, channels, fit (the Cattaneo-Mindlin fit of tirstrain fit, per frame; never run unless "
         "asked)")
      ->delimiter(',');
  sub->add_option("--preset", args->preset, "Tracking preset, replacing the scene's: auto or delhaye2016")
      ->check(CLI::IsMember({"auto", "delhaye2016"}));
  sub->add_option(
         "--segmentation", args->segmentation,
         "Contact segmentation preset, replacing the scene's segmentation.preset: accurate (default; "
         "~4 ms per 1280x1024 frame), balanced (~2 ms), fast (~1 ms, centre to ~2.5 px)")
      ->check(CLI::IsMember({"accurate", "balanced", "fast"}));
  sub->add_option("--strain-mode", args->strain_mode,
                  "exact (Green-Lagrange from F against the reference; default) or incremental (the paper's "
                  "running sum of per-frame increments)")
      ->check(CLI::IsMember({"exact", "incremental"}));
  sub->add_flag("--quiet", args->quiet, "No progress or warnings on stderr");
  sub->add_flag(
      "--strict", args->strict,
      "Stop at a corrupt frame, a missing stage or missing timestamps instead of skipping/assuming");
  sub->add_option("--flush-every-frames", args->flush_every_frames,
                  "Frames between flushes of the partial result (default 64): a run killed later leaves the "
                  "frames before the last flush readable in DIR.partial, marked incomplete")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40));
  sub->add_flag("--resume", args->resume,
                "Continue the run interrupted in DIR.partial from its last checkpoint (same input, scene and "
                "options); without one, start from the first frame");
  sub->add_option("--checkpoint-every-s", args->checkpoint_every_s,
                  "Least seconds of wall time between checkpoints for --resume, written with a flush "
                  "(default 30; the first flush always writes one; they are also spaced by 50 times the "
                  "last one's writing time, so that they take at most 2 % of the run)")
      ->check(CLI::Range(0.0, 1e9));
  sub->add_option("--overlay", args->overlay, "Overlay for viewing: mp4 (default), png (DIR/overlay/), none")
      ->check(CLI::IsMember({"mp4", "png", "none"}));
  sub->callback([args] { run_process_command(*args); });
}

}  // namespace tirstrain::cli
