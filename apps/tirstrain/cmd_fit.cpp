// `tirstrain fit RESULT_DIR --out DIR`: the Hertz + Cattaneo–Mindlin field fitted to a result's tracks, frame
// by frame, with model selection and uncertainties (fit/fit_result.hpp). Only flags are parsed here.
#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "fit/fit_result.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

namespace fs = std::filesystem;

// The loads come out in the calibration and tissue the result was processed with: where those were
// process's defaults (no scene), the fitted forces are only as right as they are, and the run says so.
void warn_if_default_calibration(const std::string& result) {
  const fs::path folder = fs::is_directory(result) ? fs::path(result) : fs::path(result).parent_path();
  std::ifstream in(folder / "summary.json");
  if (!in) return;
  const nlohmann::json s = nlohmann::json::parse(in, nullptr, false);
  if (!s.is_object()) return;
  std::string defaults;
  if (s.value("px_per_mm_source", std::string()) == "default") defaults = "px_per_mm";
  if (s.contains("tissue") && s["tissue"].is_object() &&
      s["tissue"].value("source", std::string()) == "default")
    defaults += std::string(defaults.empty() ? "" : ", ") + "E and nu";
  if (!defaults.empty())
    std::cerr << "fit: warning: the result was processed without a scene: its " << defaults
              << " are process's defaults, and the fitted loads (N) and radii (mm) scale with them\n";
}

}  // namespace

void add_fit_command(CLI::App& app) {
  struct Options {
    std::string result;
    std::string out;
    fit::RunOptions run;
    bool frame_limit = false;
    bool quiet = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand(
      "fit",
      "Fit the Hertz + Cattaneo-Mindlin field to a result's tracks, frame by frame (c, Q, direction, SDs)");
  sub->footer(
      "Each frame's tracked displacements inside the contact are fitted (Ceres, Huber loss) with four "
      "fields:\n"
      "rest (no tangential load), full stick, partial slip and full slip (c = 0); the lowest BIC is chosen.\n"
      "Then the trial's muP, measured on the frames whose slip annulus the tracks resolve, is held in the\n"
      "frames in stick or partial slip: their c follows from the stick zone's shift where the annulus lies\n"
      "beyond the tracks (fit.csv limit_from_trial; --frame-limit fits muP on each frame instead).\n"
      "Reports the contact centre, load direction, a, c, Q = tangential_N and mu*P = limit_N (from the\n"
      "scene's tissue E, nu) with SDs, AIC/BIC of every field and the residuals per track. Needs a result\n"
      "processed with the tracking stage. Writes DIR/fit.csv and DIR/fit.h5 (docs/formats.md, \"Model "
      "fit\");\n"
      "DIR appears only when complete and an earlier fit there is replaced.\n"
      "Example:\n"
      "  tirstrain synth --scene samples/scenes/default.yaml --out trial\n"
      "  tirstrain process trial --out trial_result --compute tracking\n"
      "  tirstrain fit trial_result --out trial_fit");
  sub->add_option("RESULT_DIR", options->result, "A tirstrain process output folder (or its result.h5)")
      ->required();
  sub->add_option("--out", options->out, "Output folder DIR")->required();
  sub->add_option("--loss-scale-px", options->run.fit.loss_scale_px,
                  "Huber loss scale, px: residuals beyond it count linearly (default 0.3)")
      ->check(kPositive);
  sub->add_option("--min-tracks", options->run.fit.min_tracks,
                  "Frames with fewer usable tracks are not fitted (status too_few_tracks; default 20)")
      ->check(CLI::Range(7, 1000000));
  sub->add_option("--threads", options->run.frame_threads, "Frames fitted in parallel (default 2)")
      ->check(CLI::Range(1, 256));
  sub->add_flag(
      "--frame-limit", options->frame_limit,
      "Fit muP on every frame on its own rather than hold the trial's in its stick and partial-slip "
      "frames");
  sub->add_flag("--quiet,-q", options->quiet, "No summary output");
  sub->callback([options] {
    const auto start = std::chrono::steady_clock::now();
    options->run.trial_limit = !options->frame_limit;
    const fit::ResultForFit result = fit::read_result_for_fit(options->result);
    const fit::FitRun run = fit::fit_result(result, options->run);
    const std::vector<fit::FrameFit>& fits = run.frames;
    const double fit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::array<int, fit::kFieldModels> by_model{};
    int unfitted = 0, from_trial = 0, no_contact = 0;
    for (const fit::FrameFit& f : fits) {
      from_trial += f.limit_from_trial ? 1 : 0;
      no_contact += f.status == fit::FitStatus::no_contact ? 1 : 0;
      if (f.status == fit::FitStatus::no_contact || f.status == fit::FitStatus::too_few_tracks)
        ++unfitted;
      else
        ++by_model[static_cast<int>(f.model)];
    }
    // A fit folder without a single fit would look like a result; say why instead.
    if (unfitted == static_cast<int>(fits.size()))
      throw Error("no frame could be fitted: " + std::to_string(fits.size()) + " frames, " +
                      std::to_string(no_contact) + " with no contact, " +
                      std::to_string(unfitted - no_contact) + " with fewer than " +
                      std::to_string(options->run.fit.min_tracks) +
                      " usable tracks (--min-tracks); nothing written",
                  {.file = options->result});
    fit::write_fit_outputs(options->out, result, run, options->run.fit);
    warn_if_default_calibration(options->result);
    if (options->quiet) return;
    std::cout << "fitted " << fits.size() - unfitted << " of " << fits.size() << " frames in " << fit_s
              << " s: rest " << by_model[0] << ", full stick " << by_model[1] << ", partial slip "
              << by_model[2] << ", full slip " << by_model[3] << "; not fitted " << unfitted << "\n";
    if (run.trial_limit)
      std::cout << "the trial's μP " << run.trial_limit->limit_N << " ± " << run.trial_limit->sd_N
                << " N (measured on " << run.trial_limit->frames << " frames) held in " << from_trial
                << " frames in stick or partial slip: their c follows from the stick zone's shift\n";
    else if (options->run.trial_limit)
      std::cout
          << "the trial's μP not measured (no frame resolves its slip annulus and stick zone): μP fitted per "
             "frame\n";
    std::cout << "wrote " << options->out << "/fit.csv and fit.h5\n";
  });
}

}  // namespace tirstrain::cli
