// `tirstrain scene init RECORDING --out scene.yaml`: a commented starting scene file from what the images
// show.
#include <iostream>
#include <memory>
#include <string>

#include "pipeline/scene_init.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {

void add_scene_command(CLI::App& app) {
  CLI::App* scene = app.add_subcommand("scene", "Scene files: init writes a starting one from a recording");
  scene->require_subcommand(1);
  auto options = std::make_shared<pipeline::SceneInitOptions>();
  CLI::App* init = scene->add_subcommand(
      "init",
      "Write a commented starting scene file from what a recording's images show: frame size, frame rate\n"
      "(from the timestamps), the glass's printed dot band (along any edge, or none), ridge period and\n"
      "polarity, contact size; calibration and tissue as PLACEHOLDERS holding the defaults.");
  init->footer(
      "Example:\n  tirstrain scene init REC --out REC/scene.yaml    # then edit calibration and tissue");
  init->add_option("RECORDING", options->input,
                   "Frames folder, image pattern or video file (as process takes)")
      ->required();
  init->add_option("--out", options->out_path, "Scene file to write (YAML)")->required();
  init->add_option("--frame-rate-Hz", options->frame_rate_Hz,
                   "Frame rate (Hz) of a recording whose file holds no timestamps and has no frames.csv "
                   "beside it (a multi-page TIFF)")
      ->check(kPositive);
  init->add_flag("--overwrite", options->overwrite, "Replace an existing --out file");
  init->add_option("--frames", options->max_frames, "Frames read at most (default 300)")
      ->check(CLI::Range(1, 1000000));
  init->callback([options] {
    const pipeline::SceneSurvey survey = pipeline::write_initial_scene(*options);
    std::cerr << "scene from " << survey.frames_read << " frames (band: " << survey.band_edge << ", "
              << (survey.first_contact_frame >= 0
                      ? "contact first in frame " + std::to_string(survey.first_contact_frame)
                      : std::string("no contact seen"))
              << ") -> " << options->out_path << "\n";
    if (survey.first_contact_frame < 0)
      std::cerr << "scene init: warning: no frame of " << survey.frames_read
                << " read shows ridge texture in contact: process with this scene tracks nothing (for "
                   "texture without ridges, tirstrain track follows a grid over the whole frame)\n";
  });
}

}  // namespace tirstrain::cli
