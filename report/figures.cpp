#include "report/figures.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>

namespace tirstrain::report {
namespace {

using nlohmann::json;

bool any_finite(const std::vector<double>& values) {
  for (double v : values)
    if (std::isfinite(v)) return true;
  return false;
}

bool any_result_has(const std::vector<ResultData>& results, std::vector<double> ResultData::*member) {
  for (const ResultData& r : results)
    if (any_finite(r.*member)) return true;
  return false;
}

// Long-format rows {t_s, result, quantity, value}, NaN left out (a gap in the line).
json series_rows(const std::vector<ResultData>& results,
                 const std::vector<std::pair<std::string, std::vector<double> ResultData::*>>& series) {
  json rows = json::array();
  for (const ResultData& r : results)
    for (const auto& [name, member] : series) {
      const std::vector<double>& values = r.*member;
      for (std::size_t i = 0; i < values.size() && i < r.t_s.size(); ++i)
        if (std::isfinite(values[i]))
          rows.push_back({{"t_s", rounded(r.t_s[i])},
                          {"result", r.label},
                          {"quantity", name},
                          {"value", rounded(values[i])}});
    }
  return rows;
}

// A line plot of long-format rows against time: colour tells the quantities apart, the dash pattern the
// results; dragging pans and the wheel zooms; hovering a point shows its values.
json line_panel(json rows, const std::string& y_title, bool several_results, const FigureOptions& options,
                const std::string& zoom_name) {
  json encoding = {
      {"x", {{"field", "t_s"}, {"type", "quantitative"}, {"title", options.time_title}}},
      {"y", {{"field", "value"}, {"type", "quantitative"}, {"title", y_title}, {"scale", {{"zero", false}}}}},
      {"color", {{"field", "quantity"}, {"type", "nominal"}, {"title", nullptr}}},
      {"tooltip", json::array({{{"field", "result"}},
                               {{"field", "quantity"}},
                               {{"field", "t_s"}, {"title", options.time_title}},
                               {{"field", "value"}, {"title", y_title}}})}};
  if (several_results)
    encoding["strokeDash"] = {{"field", "result"}, {"type", "nominal"}, {"title", "result"}};
  return {{"width", options.width_px},
          {"height", 200},
          {"data", {{"values", std::move(rows)}}},
          {"mark", {{"type", "line"}, {"point", {{"size", 14}}}, {"strokeWidth", 1.5}}},
          {"encoding", encoding},
          {"params", json::array({{{"name", zoom_name}, {"select", "interval"}, {"bind", "scales"}}})}};
}

json vertical(std::vector<json> panels) {
  return {{"vconcat", std::move(panels)},
          {"resolve", {{"scale", {{"color", "independent"}, {"strokeDash", "independent"}}}}}};
}

// A figure of time series: panels stacked, each a set of a result's per-frame series in one unit.
using Series = std::vector<double> ResultData::*;
struct Panel {
  std::vector<std::pair<std::string, Series>> series;  // legend name, the series
  std::string y_title;                                 // quantity and unit
};
struct TimeFigure {
  std::string id, title, caption;
  std::vector<Panel> panels;
};

bool panel_has_data(const std::vector<ResultData>& results, const Panel& panel) {
  for (const auto& [name, member] : panel.series)
    if (any_result_has(results, member)) return true;
  return false;
}

// The figure, its panels without data left out; null spec when none has any.
Figure time_figure(const std::vector<ResultData>& results, const TimeFigure& t, const FigureOptions& o) {
  Figure f{t.id, t.title, t.caption, json(), "svg", ""};
  std::vector<json> panels;
  for (const Panel& p : t.panels)
    if (panel_has_data(results, p))
      panels.push_back(line_panel(series_rows(results, p.series), p.y_title, results.size() > 1, o,
                                  "zoom_" + t.id + "_" + std::to_string(panels.size())));
  if (panels.size() == 1) f.spec = std::move(panels.front());
  if (panels.size() > 1) f.spec = vertical(std::move(panels));
  return f;
}

std::string ratio_at_t90_text(const std::vector<ResultData>& results) {
  std::string text;
  for (const ResultData& r : results) {
    if (!std::isfinite(r.energy_ratio_at_t90)) continue;
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.3g", r.energy_ratio_at_t90);
    text += (text.empty() ? "" : "; ") + r.label + ": " + buffer;
  }
  return text.empty() ? "" : " U/U_ext at t90 (/work/energy_ratio): " + text + ".";
}

// Every time-series figure of the report, in reading order.
std::vector<TimeFigure> time_figures(const std::vector<ResultData>& results) {
  using R = ResultData;
  return {
      {"contact",
       "Contact against time",
       "Top: contact area inside the contact's convex hull, mm². Bottom: semi-major and semi-minor axes of "
       "the "
       "ellipse fitted to the hull, mm (no point where no ellipse was fitted).",
       {{{{"area", &R::area_mm2}}, "area (mm²)"},
        {{{"semi-major axis", &R::semi_major_mm}, {"semi-minor axis", &R::semi_minor_mm}},
         "semi-axis (mm)"}}},
      {"tracks",
       "Tracks against time",
       "Top: tracks alive in each frame. Bottom: tracks born (the reference frame's seeding included) and "
       "retired in each frame (counts).",
       {{{{"alive", &R::tracks_alive}}, "tracks alive"},
        {{{"born", &R::tracks_born}, {"retired", &R::tracks_retired}}, "tracks per frame"}}},
      {"forces",
       "Forces and friction against time",
       "Top: normal force W and tangential force along the stroke F_t, N, from the force channels at the "
       "frame times (aligned to the camera clock). Bottom: friction coefficient μ = F_t / W on the tared "
       "channels (dimensionless; no point where W is below the channels' minimum normal force).",
       {{{{"normal W", &R::normal_N}, {"tangential F_t", &R::tangential_N}}, "force (N)"},
        {{{"μ", &R::mu}}, "μ (dimensionless)"}}},
      {"energy",
       "Strain energy against time",
       "Top: strain energy U of the measured strain field (plane-strain St Venant–Kirchhoff, scene's E, ν "
       "and depth), J, over the meshed area only: the mesh stops short of the contact's rim, where "
       "Cattaneo–Mindlin concentrates its energy, so U is a lower bound of the whole contact's. Bottom: U "
       "over the external work U_ext = ∫F_t dx accumulated since the onset "
       "(dimensionless), where U_ext is at least 1 % of its largest value." +
           ratio_at_t90_text(results),
       {{{{"U", &R::energy_J}}, "U (J)"}, {{{"U/U_ext", &R::energy_ratio}}, "U/U_ext (dimensionless)"}}},
      {"stick",
       "Stick ratio against time",
       "Stuck fraction of the meshed area (a triangle is stuck when its centroid moves with the plate within "
       "the stick tolerance) and the stick radius over the contact radius c/a from the Cattaneo–Mindlin slip "
       "profile fitted to the tracks (dimensionless). Where the stuck core moved but no slip showed within "
       "the tracks, c is not measured (the slip annulus lies beyond the outermost tracks or is too thin for "
       "the noise): there the outermost tracks' radius over a is drawn instead.",
       {{{{"stick ratio", &R::stick_ratio},
          {"c/a (stick fit)", &R::stick_radius_ratio},
          {"tracks' reach, c not measured", &R::stick_unmeasured_reach}},
         "fraction (dimensionless)"}}},
      {"fit",
       "Model fit against time",
       "The Hertz + Cattaneo–Mindlin field fitted to the tracked displacements frame by frame (/fit): top, "
       "the fitted stick radius over contact radius c/a (dimensionless); bottom, the tangential load Q it "
       "implies with the scene's tissue, N. The field of each frame is the one chosen by BIC.",
       {{{{"c/a (fit)", &R::fit_c_of_a}}, "c/a (dimensionless)"},
        {{{"Q (fit)", &R::fit_tangential_N}}, "Q (N)"}}},
  };
}

// Axial angles binned over 0–180° and drawn over the full circle (each direction θ also as θ + 180°),
// wedge radius ∝ √fraction so that areas compare; 0° points along +x and angles grow towards +y (down the
// image), as in the image itself. The radius range is explicit: inside a concatenation Vega-Lite cannot
// derive it from the view size and draws every wedge with zero radius.
json polar_panel(const AngleSet& set, const std::string& title, const FigureOptions& o) {
  const int bins = o.polar_bins;
  std::vector<double> weight(static_cast<std::size_t>(bins), 0.0);
  double total = 0.0;
  for (std::size_t i = 0; i < set.angle_rad.size(); ++i) {
    const int b = std::min(bins - 1, static_cast<int>(set.angle_rad[i] / std::numbers::pi * bins));
    weight[static_cast<std::size_t>(std::max(0, b))] += set.weight[i];
    total += set.weight[i];
  }
  json rows = json::array();
  const double width_deg = 180.0 / bins;
  for (int k = 0; k < 2 * bins; ++k) {
    const double fraction = total > 0.0 ? weight[static_cast<std::size_t>(k % bins)] / total : 0.0;
    // Vega's angles run clockwise from 12 o'clock, so the image's 0° (+x, 3 o'clock) sits at π/2.
    const double from_rad = std::numbers::pi / 2.0 + k * width_deg * std::numbers::pi / 180.0;
    rows.push_back({{"from_deg", rounded(k * width_deg)},
                    {"to_deg", rounded((k + 1) * width_deg)},
                    {"fraction", rounded(fraction)},
                    {"theta0", rounded(from_rad)},
                    {"theta1", rounded(from_rad + width_deg * std::numbers::pi / 180.0)}});
  }
  return {{"title", title},
          {"width", 220},
          {"height", 220},
          {"data", {{"values", rows}}},
          {"mark", {{"type", "arc"}, {"stroke", "white"}, {"strokeWidth", 0.5}}},
          {"encoding",
           {{"theta", {{"field", "theta0"}, {"type", "quantitative"}, {"scale", nullptr}}},
            {"theta2", {{"field", "theta1"}}},
            {"radius",
             {{"field", "fraction"},
              {"type", "quantitative"},
              {"scale", {{"type", "sqrt"}, {"zero", true}, {"range", {0, 105}}}},
              {"title", "fraction"}}},
            {"color", {{"value", "#4c78a8"}}},
            {"tooltip", json::array({{{"field", "from_deg"}, {"title", "from (°)"}},
                                     {{"field", "to_deg"}, {"title", "to (°)"}},
                                     {{"field", "fraction"}, {"title", "fraction"}}})}}}};
}

Figure polar_figure(const std::vector<ResultData>& results, AngleSet ResultData::*member,
                    const std::string& id, const std::string& title, const std::string& caption,
                    const FigureOptions& o) {
  std::vector<json> panels;
  for (const ResultData& r : results)
    if (!(r.*member).angle_rad.empty())
      panels.push_back(polar_panel(
          r.*member, r.label + ": " + std::to_string((r.*member).angle_rad.size()) + " samples", o));
  Figure f{id, title, caption, json(), "svg", ""};
  if (panels.empty()) return f;
  f.caption += " Shown: " + (results.front().*member).what +
               (results.size() > 1 ? ", and likewise for each result." : ".");
  f.spec = {{"hconcat", panels}};
  return f;
}

}  // namespace

double rounded(double value) {
  if (!std::isfinite(value) || value == 0.0) return value;
  const double scale = std::pow(10.0, 5 - static_cast<int>(std::floor(std::log10(std::abs(value)))));
  return std::round(value * scale) / scale;
}

std::string html_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// A result whose input had no clock has the frame number as t_s: its axis must not say seconds.
std::string time_axis_title(const std::vector<ResultData>& results) {
  std::string untimed;
  std::size_t count = 0;
  for (const ResultData& r : results)
    if (!r.time_measured) {
      untimed += (untimed.empty() ? "" : ", ") + r.label;
      ++count;
    }
  if (count == 0) return "time (s)";
  if (count == results.size()) return "frame number (the input has no timestamps: not a time)";
  return "time (s); frame number for " + untimed + " (no timestamps)";
}

std::vector<Figure> result_figures(const std::vector<ResultData>& results, const FigureOptions& given) {
  FigureOptions options = given;
  options.time_title = time_axis_title(results);
  std::vector<Figure> figures;
  for (const TimeFigure& t : time_figures(results)) {
    if (t.id == "energy" && options.maps)  // the key instants' maps between the forces and the energy
      for (Figure& f : map_figures(results, options)) figures.push_back(std::move(f));
    Figure f = time_figure(results, t, options);
    if (!f.spec.is_null()) figures.push_back(std::move(f));
  }
  Figure principal = polar_figure(
      results, &ResultData::principal_directions, "principal-directions", "Principal strain directions",
      "Polar histogram of the direction of the larger principal strain e1 over the meshed triangles "
      "(fraction of triangles per 10° bin, each direction drawn at θ and θ + 180°; 0° along +x of the "
      "image, angles growing towards +y, down the image; triangles with e1 − e2 below 1e-3 have no direction "
      "and are left out).",
      options);
  if (!principal.spec.is_null()) figures.push_back(std::move(principal));
  Figure ridges = polar_figure(
      results, &ResultData::ridge_orientation, "ridge-orientation", "Ridge orientation",
      "Polar histogram of the ridge direction per 32 × 32 px block of the contact (fraction of the blocks' "
      "coherence per 10° bin, blocks of coherence below 0.3 left out; angles as in the principal "
      "directions).",
      options);
  if (!ridges.spec.is_null()) figures.push_back(std::move(ridges));
  return figures;
}

}  // namespace tirstrain::report
