// The strain maps on the standard ellipse: one figure per result and instant, the five components side by
// side, each colour scale symmetric about zero and spanning a percentile of |value| over every map of that
// component in the report, so that a few extreme border cells do not wash out the interior and maps of the
// same component compare across instants and results.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "report/figures.hpp"

namespace tirstrain::report {
namespace {

using nlohmann::json;

double percentile_of_magnitude(std::vector<double> magnitudes, double percentile) {
  if (magnitudes.empty()) return 0.0;
  const auto k =
      static_cast<std::size_t>(std::round(percentile / 100.0 * static_cast<double>(magnitudes.size() - 1)));
  std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<long>(k), magnitudes.end());
  return magnitudes[k];
}

// Per component, the colour scale's half-range over every result's maps.
std::vector<double> colour_ranges(const std::vector<ResultData>& results, double percentile) {
  std::vector<double> ranges;
  for (std::size_t c = 0; c < std::size(kMapComponents); ++c) {
    std::vector<double> magnitudes;
    for (const ResultData& r : results)
      for (const StrainMaps& m : r.maps)
        for (double v : m.component[c])
          if (std::isfinite(v)) magnitudes.push_back(std::abs(v));
    const double range = percentile_of_magnitude(std::move(magnitudes), percentile);
    ranges.push_back(range > 0.0 ? rounded(range) : 1e-6);
  }
  return ranges;
}

// One row per cell with any finite value: its square in normalised coordinates and the five components.
json cell_rows(const StrainMaps& m) {
  json rows = json::array();
  const double half = 1.0 / (m.cells - 1);
  for (int j = 0; j < m.cells; ++j)
    for (int i = 0; i < m.cells; ++i) {
      const auto c = static_cast<std::size_t>(j * m.cells + i);
      if (!std::isfinite(m.component[0][c])) continue;
      const double x = -1.0 + 2.0 * i / (m.cells - 1), y = -1.0 + 2.0 * j / (m.cells - 1);
      json row = {{"x", rounded(x)},         {"y", rounded(y)},         {"x0", rounded(x - half)},
                  {"x1", rounded(x + half)}, {"y0", rounded(y - half)}, {"y1", rounded(y + half)}};
      for (std::size_t k = 0; k < std::size(kMapComponents); ++k)
        row[kMapComponents[k]] = rounded(m.component[k][c]);
      rows.push_back(std::move(row));
    }
  return rows;
}

json ellipse_outline(double aspect) {
  json rows = json::array();
  for (int k = 0; k <= 72; ++k) {
    const double t = 2.0 * std::numbers::pi * k / 72.0;
    rows.push_back({{"k", k}, {"x", rounded(std::cos(t))}, {"y", rounded(aspect * std::sin(t))}});
  }
  return rows;
}

json map_panel(const std::string& component, double range, double aspect) {
  const json x_scale = {{"domain", {-1.05, 1.05}}, {"nice", false}};
  const json y_scale = {{"domain", {-1.05, 1.05}}, {"nice", false}, {"reverse", true}};
  json heat = {
      {"transform", json::array({{{"filter", "isValid(datum['" + component + "'])"}}})},
      {"mark", {{"type", "rect"}}},
      {"encoding",
       {{"x",
         {{"field", "x0"}, {"type", "quantitative"}, {"scale", x_scale}, {"title", "x / semi-major axis"}}},
        {"x2", {{"field", "x1"}}},
        {"y",
         {{"field", "y0"}, {"type", "quantitative"}, {"scale", y_scale}, {"title", "y / semi-major axis"}}},
        {"y2", {{"field", "y1"}}},
        {"color",
         {{"field", component},
          {"type", "quantitative"},
          {"scale", {{"scheme", "redblue"}, {"reverse", true}, {"domain", {-range, range}}, {"clamp", true}}},
          {"title", component + " (dimensionless)"},
          {"legend", {{"orient", "bottom"}, {"gradientLength", 150}}}}},
        {"tooltip", json::array({{{"field", "x"}, {"title", "x"}},
                                 {{"field", "y"}, {"title", "y"}},
                                 {{"field", component}, {"title", component}}})}}}};
  json outline = {{"data", {{"values", ellipse_outline(aspect)}}},
                  {"mark", {{"type", "line"}, {"color", "black"}, {"strokeWidth", 1}}},
                  {"encoding",
                   {{"x", {{"field", "x"}, {"type", "quantitative"}, {"scale", x_scale}}},
                    {"y", {{"field", "y"}, {"type", "quantitative"}, {"scale", y_scale}}},
                    {"order", {{"field", "k"}}}}}};
  return {{"title", component},
          {"width", 170},
          {"height", 170},
          {"layer", json::array({heat, outline})},
          {"resolve", {{"scale", {{"color", "independent"}}}}}};
}

std::string number(const char* format, double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, format, value);
  return buffer;
}

// Which way the map's axes lie in the image.
std::string map_axes(const StrainMaps& m) {
  if (m.axes_angle_rad == 0.0) return "x right and y down, as in the image (a contact this round keeps them)";
  return "x along the reference contact's major axis towards the image's bottom, at " +
         number("%.0f", m.axes_angle_rad * 180.0 / std::numbers::pi) +
         "° from the image's x, y 90° clockwise from it on screen";
}

std::string map_caption(const ResultData& r, const StrainMaps& m, const std::vector<double>& ranges,
                        double percentile) {
  std::string caption =
      "Green–Lagrange strain of " + r.label + " at " + m.instant.name + " (frame " +
      std::to_string(m.instant.frame) + ", t = " + number("%.4g", m.instant.t_s) + " s; instant from " +
      m.instant.source + ") on the standard ellipse, lengths in units of its semi-major axis; " +
      map_axes(m) +
      "; the black line is the contact ellipse. "
      "Components E_xx, E_yy, E_xy (tensor shear, in the map's axes) and the principal strains e1 ≥ e2, all "
      "dimensionless; each cell holds the constant strain of the mesh triangle over it (no "
      "smoothing), blank outside the mesh: " +
      number("%.0f", 100.0 * m.covered_fraction) + " % of the ellipse is covered. Colour scales span ± the " +
      number("%.0f", percentile) + "th percentile of |value| over every map of the report (";
  for (std::size_t k = 0; k < ranges.size(); ++k)
    caption += (k ? ", " : "") + std::string(kMapComponents[k]) + " ±" + number("%.3g", ranges[k]);
  return caption + "); values beyond take the end colour.";
}

}  // namespace

std::vector<Figure> map_figures(const std::vector<ResultData>& results, const FigureOptions& options) {
  const std::vector<double> ranges = colour_ranges(results, options.map_percentile);
  std::vector<Figure> figures;
  for (std::size_t ri = 0; ri < results.size(); ++ri)
    for (const StrainMaps& m : results[ri].maps) {
      json panels = json::array();
      for (std::size_t k = 0; k < std::size(kMapComponents); ++k)
        panels.push_back(map_panel(kMapComponents[k], ranges[k], m.aspect));
      Figure f;
      f.id = "maps-" + std::to_string(ri) + "-" + m.instant.name;
      std::replace(f.id.begin(), f.id.end(), ' ', '-');
      f.title =
          "Strain maps at " + m.instant.name + (results.size() > 1 ? " (" + results[ri].label + ")" : "");
      f.caption = map_caption(results[ri], m, ranges, options.map_percentile);
      f.renderer = "canvas";
      f.spec = {{"data", {{"values", cell_rows(m)}}},
                {"hconcat", panels},
                {"resolve", {{"scale", {{"color", "independent"}}}}}};
      figures.push_back(std::move(f));
    }
  return figures;
}

}  // namespace tirstrain::report
