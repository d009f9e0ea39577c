// `tirstrain validate`: synthesise (or take) a trial, process it, and compare with its exact truth.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>

#include "pipeline/validate.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

void print_table(const pipeline::ValidationReport& report) {
  // Text columns as wide as their longest entry.
  int q_width = 8, r_width = 9, m_width = 4;
  for (const auto& s : report.rows) {
    q_width = std::max(q_width, static_cast<int>(s.quantity.size()));
    r_width = std::max(r_width, static_cast<int>(s.reference.size()));
    m_width = std::max(m_width, static_cast<int>(s.mode.size()));
  }
  std::printf("%-*s %-*s %-*s %12s %12s %12s %9s\n", q_width, "quantity", r_width, "reference", m_width,
              "mode", "rms", "max |err|", "mean err", "samples");
  for (const auto& s : report.rows) {
    const std::string unit = s.unit.empty() ? "" : " " + s.unit;
    std::printf("%-*s %-*s %-*s %12.4g %12.4g %12.4g %9ld%s\n", q_width, s.quantity.c_str(), r_width,
                s.reference.c_str(), m_width, s.mode.c_str(), s.rms, s.max_abs, s.mean, s.samples,
                unit.c_str());
  }
}

struct ValidateArgs {
  std::string scene, trial, result, out, preset, segmentation, strain_mode, process_scene, staged_in;
  double border_mm = 0.3;
  int map_frame = -1;
  bool quiet = false, no_maps = false, process_defaults = false;
};

const char* const kValidateFooter =
    "With --scene the trial is synthesised into OUT/trial; with --trial an existing `tirstrain synth` "
    "folder\n"
    "is used; its scene.yaml must still be the one it was synthesised with (checked against truth.h5; pass\n"
    "other processing settings with --process-scene). The trial is processed (contact, tracking, strain) "
    "into\n"
    "OUT/result unless --result names an existing result of it. Errors are measured in the contact "
    "interior:\n"
    "triangles whose reference and true current centroids lie more than --border-mm inside the contact\n"
    "border. Strain references: 'point' is the exact Green-Lagrange strain at the triangle's reference\n"
    "centroid; 'triangle' the strain of the triangle with its vertices moved by the exact field (tracking\n"
    "error only). Both strain modes (exact and incremental) are reported. U: % error of the total strain\n"
    "energy against the truth on the same triangles, over frames with >= 10 % of the largest energy (none "
    "if\n"
    "that is below a uniform 1e-4 strain's, as in a rigid motion). c: stick radius from the stuck "
    "triangles'\n"
    "area against the Cattaneo-Mindlin model's, in partial slip. Contact, every frame: 1 - IoU of the hull\n"
    "against the truth mask, and the ellipse's centre (px) and semi-axes (%) against the same direct fit of\n"
    "the truth mask's outline.\n"
    "Writes OUT/validation.csv (one row per quantity), OUT/validation_frames.csv (per frame) and\n"
    "OUT/maps_E_xx.png, maps_E_yy.png, maps_E_xy.png (measured | truth | difference on the standard "
    "ellipse).\n"
    "Examples:\n"
    "  tirstrain validate --scene samples/scenes/default.yaml --out val\n"
    "  tirstrain validate --trial TRIAL --out val    # a trial made earlier by tirstrain synth";

pipeline::ValidateOptions validate_options(const ValidateArgs& args) {
  pipeline::ValidateOptions o;
  if (!args.scene.empty()) o.scene_path = args.scene;
  if (!args.trial.empty()) o.trial_dir = args.trial;
  if (!args.result.empty()) o.result_dir = args.result;
  o.out_dir = args.out;
  if (const std::size_t eq = args.staged_in.find('='); eq != std::string::npos)
    o.staged_folders.push_back({args.staged_in.substr(0, eq), args.staged_in.substr(eq + 1)});
  if (!args.process_scene.empty()) o.process_scene_path = args.process_scene;
  o.process_defaults = args.process_defaults;
  o.tracking_preset = args.preset;
  o.segmentation_preset = args.segmentation;
  o.strain_mode = args.strain_mode;
  o.border_exclusion_mm = args.border_mm;
  o.map_frame = args.map_frame;
  o.write_maps = !args.no_maps;
  o.quiet = args.quiet;
  return o;
}

void run_validate_command(const ValidateArgs& args) {
  const pipeline::ValidationReport report = pipeline::run_validate(validate_options(args));
  print_table(report);
  for (const std::string& w : report.warnings) std::cerr << "validate: warning: " << w << "\n";
  // A result with nothing to compare (no contact, no tracks, no strain in any frame) validates nothing: a
  // table of empty rows must not pass for a validation.
  // (The coverage deficit measures what is missing, so it has samples whatever was measured.)
  const bool nothing =
      std::all_of(report.rows.begin(), report.rows.end(), [](const pipeline::ErrorStats& row) {
        return row.samples == 0 || row.quantity.starts_with("coverage_deficit");
      });
  if (nothing)
    throw Error(
        "nothing could be validated: no row of the comparison has a sample (no contact, tracks or "
        "strain was measured in any frame; the result's summary.json says why)",
        {.file = report.result_dir});
  if (args.quiet) return;
  std::cerr << "validated " << report.frames << " frames";
  if (report.process_wall_s > 0.0) std::cerr << " (processing took " << report.process_wall_s << " s)";
  std::cerr << "\n";
  for (const auto& path : report.outputs) std::cerr << "  " << path << "\n";
}

}  // namespace

void add_validate_command(CLI::App& app) {
  auto args = std::make_shared<ValidateArgs>();
  CLI::App* sub = app.add_subcommand("validate",
                                     "Compare a processed synthetic trial with its exact truth (contact, "
                                     "tracks, strain, energy, stick zone)");
  sub->footer(kValidateFooter);
  sub->add_option("--scene", args->scene, "Scene file with a synthesis: section (synthesised first)")
      ->check(CLI::ExistingFile);
  sub->add_option("--trial", args->trial, "An existing synthesised trial folder")
      ->check(CLI::ExistingDirectory);
  sub->add_option("--result", args->result,
                  "An existing process output folder for that trial (skip processing)")
      ->check(CLI::ExistingDirectory);
  sub->add_option("--out", args->out, "Output folder (replaced as a whole when the run completes)")
      ->required();
  sub->add_option("--process-scene", args->process_scene,
                  "Process with this scene (e.g. other tracking settings) instead of the trial's own")
      ->check(CLI::ExistingFile);
  sub->add_flag("--process-defaults", args->process_defaults,
                "Process with no scene (defaults; stages and pattern band found from the images), as a "
                "recording without a scene file is; the truth still comes from the trial's scene");
  sub->add_option("--preset", args->preset, "Tracking preset: auto or delhaye2016")
      ->check(CLI::IsMember({"auto", "delhaye2016"}));
  sub->add_option(
         "--segmentation", args->segmentation,
         "Contact segmentation preset, replacing the scene's segmentation.preset: accurate (default; "
         "~4 ms per 1280x1024 frame), balanced (~2 ms), fast (~1 ms, centre to ~2.5 px)")
      ->check(CLI::IsMember({"accurate", "balanced", "fast"}));
  sub->add_option("--strain-mode", args->strain_mode, "exact or incremental")
      ->check(CLI::IsMember({"exact", "incremental"}));
  sub->add_option("--border-mm", args->border_mm,
                  "Distance from the contact border excluded (mm, default 0.3)")
      ->check(CLI::Range(0.0, 100.0));
  sub->add_option("--map-frame", args->map_frame, "Frame of the map images (default: largest true energy)")
      ->check(kAtLeastZero);
  sub->add_flag("--no-maps", args->no_maps, "Do not write the map images");
  sub->add_flag("--quiet", args->quiet, "No progress on stderr");
  // For `bench`, which runs validate inside its own staging folder: STAGING=FINAL.
  sub->add_option("--staged-in", args->staged_in)->group("");
  sub->callback([args] { run_validate_command(*args); });
}

}  // namespace tirstrain::cli
