#pragma once
// The report's figures as Vega-Lite specifications, each with the caption that says what it shows and in
// which units. Several results share a figure where their axes agree (time series overlaid, one dash
// pattern per result) and stand side by side where they do not (maps, polar histograms).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report/result_data.hpp"
#include "report/validation_data.hpp"

namespace tirstrain::report {

struct Figure {
  std::string id;                // HTML id of the <figure> (unique in the page)
  std::string title;             // first words of the caption
  std::string caption;           // what it shows and in which units
  nlohmann::json spec;           // Vega-Lite specification; null for a figure that is only `html`
  std::string renderer = "svg";  // "svg" for plots, "canvas" for dense heat maps
  std::string html;              // HTML shown under the plot (a table), already escaped
};

struct FigureOptions {
  double map_percentile = 98.0;  // colour scales of the strain maps span ± this percentile of |value|
  int polar_bins = 18;           // bins over 0–180° for the axial polar histograms (10° each)
  int width_px = 640;            // width of a time-series plot
  bool maps = true;              // the strain maps at the key instants (false: left out, said in the page)
  std::string time_title = "time (s)";  // the time axis (result_figures: the frame number where untimed)
};

// Figures of the process results, in reading order: contact, tracks, forces, strain maps, energy, stick,
// fit, polar histograms. A figure whose data no result has is left out.
std::vector<Figure> result_figures(const std::vector<ResultData>& results, const FigureOptions& options = {});

// The strain maps on the standard ellipse, one figure per result and instant (figure_maps.cpp).
std::vector<Figure> map_figures(const std::vector<ResultData>& results, const FigureOptions& options = {});

// Validation errors against the known truth, one figure per validated result.
std::vector<Figure> validation_figures(const std::vector<ResultData>& results,
                                       const std::vector<ValidationData>& validations);

// Shared by the figure builders: a value rounded to 6 significant digits (the page's size, not its
// precision, is what the digits beyond cost), and text made safe inside HTML.
double rounded(double value);
std::string html_escape(const std::string& text);

}  // namespace tirstrain::report
