// `tirstrain synth`: render a synthetic TIR trial with exact ground truth from a scene file.
#include <cstdint>
#include <iostream>
#include <optional>
#include <string>

#include "samples/synth.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {

void add_synth_command(CLI::App& app) {
  struct Options {
    std::string scene;
    std::string out;
    std::optional<std::uint64_t> seed;
    bool quiet = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("synth",
                                     "Render a synthetic TIR trial with exact ground truth (frames, "
                                     "timestamps, force/accelerometer channels, "
                                     "truth.h5)");
  sub->footer(
      "Writes DIR/frames/NNNNNN.png, DIR/frames.csv (index,t_s), DIR/channels.csv (t_s, normal_N, "
      "tangential_N,\n"
      "plate_x_mm, plate_y_mm, accel_m_s2 at the scene's channel rate), DIR/scene.yaml (for tirstrain "
      "process)\n"
      "and DIR/truth.h5 (per frame: load P, Q, c, delta_x; plate displacement in px; contact mask; "
      "displacement in\n"
      "px, gradient and Green-Lagrange strain on a grid of reference points). Layout: docs/formats.md.\n"
      "Example scenes: samples/scenes/*.yaml. The directory appears only when complete; an earlier trial "
      "in it is\nreplaced, a folder holding anything else is refused.\n"
      "Example: tirstrain synth --scene samples/scenes/default.yaml --out trial   (then: tirstrain process "
      "trial --out result)");
  sub->add_option("--scene", options->scene, "Scene file (YAML) with a synthesis: section")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--out", options->out, "Output trial directory DIR")->required();
  // Up to 2^53, so that the seed reads back exactly from truth.h5 and the written scene.
  sub->add_option("--seed", options->seed, "Random seed (integer 0 to 2^53); overrides synthesis.seed")
      ->check(CLI::Range(std::uint64_t{0}, std::uint64_t{1} << 53));
  sub->add_flag("--quiet,-q", options->quiet, "No progress output");
  sub->callback([options] {
    samples::SynthOptions o;
    o.scene_path = options->scene;
    o.out_dir = options->out;
    o.seed = options->seed;
    o.quiet = options->quiet;
    const samples::SynthSummary summary = samples::synthesize(o);
    if (!options->quiet)
      std::cout << "wrote " << summary.frames << " frames and truth to " << summary.out_dir << " in "
                << summary.render_s << " s\n";
  });
}

}  // namespace tirstrain::cli
