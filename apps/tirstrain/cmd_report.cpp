// `tirstrain report RESULT_DIR... --out report.html`: one self-contained HTML page with the figures of one or
// several process results (report/report.hpp). Only flags are parsed here.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "report/report.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {

void add_report_command(CLI::App& app) {
  struct Options {
    report::ReportOptions report;
    bool quiet = false;
    bool no_maps = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand(
      "report", "Write one self-contained HTML page with the figures of one or several process results");
  sub->footer(
      "Figures (each with a caption naming what it shows and its units; those without data are left out):\n"
      "contact area and ellipse axes, tracks alive/born/retired, forces and mu (channels), strain maps\n"
      "E_xx E_yy E_xy e1 e2 on the standard ellipse at onset, t90 and full slip (robust colour scales),\n"
      "strain energy U and U/U_ext, stick ratio and c/a, the model fit's c/a and Q (/fit), polar histograms\n"
      "of principal strain directions and ridge orientation, validation errors (--validation), and the\n"
      "settings and software versions of each run. Several results: time series overlaid, maps and polar\n"
      "histograms side by side. The plotting scripts (Vega-Lite) are inlined: the page opens offline.\n"
      "The file appears only when complete; an earlier report of that name is replaced.\n"
      "Example:\n"
      "  tirstrain synth --scene samples/scenes/default.yaml --out trial\n"
      "  tirstrain process trial --out result\n"
      "  tirstrain validate --trial trial --result result --out validation\n"
      "  tirstrain report result --validation validation --out report.html");
  sub->add_option("RESULT_DIR", options->report.results,
                  "tirstrain process output folders (or their result.h5 files)")
      ->required();
  sub->add_option("--out,-o", options->report.out_path, "HTML file to write")->required();
  sub->add_option("--validation", options->report.validations,
                  "tirstrain validate output folders, one per RESULT_DIR in order (optional)");
  sub->add_option("--title", options->report.title, "Page heading (default: the results' folder names)");
  sub->add_option("--map-percentile", options->report.figures.map_percentile,
                  "Strain maps' colour scales span +- this percentile of |value| (default 98)")
      ->check(CLI::Range(50.0, 100.0));
  sub->add_flag("--no-maps", options->no_maps, "Leave the strain maps out (a smaller page for many results)");
  sub->add_flag("--quiet,-q", options->quiet, "No summary output");
  sub->callback([options] {
    options->report.figures.maps = !options->no_maps;
    const report::ReportSummary summary = report::write_report(options->report);
    if (options->quiet) return;
    std::cout << "wrote " << options->report.out_path << ": " << summary.figure_ids.size() << " figures, "
              << (summary.bytes + 512) / 1024 << " KiB\n";
  });
}

}  // namespace tirstrain::cli
