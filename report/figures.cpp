#include "report/figures.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>

namespace tirstrain::report {
namespace {

using nlohmann::json;

// One named series of a result, drawn against the result's frame times.
struct Series {
  std::string name;
  const std::vector<double>* values;
};

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
      {"x", {{"field", "t_s"}, {"type", "quantitative"}, {"title", "time (s)"}}},
      {"y", {{"field", "value"}, {"type", "quantitative"}, {"title", y_title}, {"scale", {{"zero", false}}}}},
      {"color", {{"field", "quantity"}, {"type", "nominal"}, {"title", nullptr}}},
      {"tooltip", json::array({{{"field", "result"}},
                               {{"field", "quantity"}},
                               {{"field", "t_s"}, {"title", "t (s)"}},
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

Figure contact_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"contact", "Contact against time", "", json(), "svg", ""};
  f.caption =
      "Top: contact area inside the contact's convex hull, mm². Bottom: semi-major and semi-minor axes of "
      "the ellipse fitted to the hull, mm (no point where no ellipse was fitted).";
  f.spec = vertical({line_panel(series_rows(results, {{"area", &ResultData::area_mm2}}), "area (mm²)",
                                several, o, "zoom_area"),
                     line_panel(series_rows(results, {{"semi-major axis", &ResultData::semi_major_mm},
                                                      {"semi-minor axis", &ResultData::semi_minor_mm}}),
                                "semi-axis (mm)", several, o, "zoom_axes")});
  return f;
}

Figure tracks_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"tracks", "Tracks against time", "", json(), "svg", ""};
  f.caption =
      "Top: tracks alive in each frame. Bottom: tracks born (the reference frame's seeding included) and "
      "retired in each frame (counts).";
  f.spec = vertical({line_panel(series_rows(results, {{"alive", &ResultData::tracks_alive}}), "tracks alive",
                                several, o, "zoom_alive"),
                     line_panel(series_rows(results, {{"born", &ResultData::tracks_born},
                                                      {"retired", &ResultData::tracks_retired}}),
                                "tracks per frame", several, o, "zoom_born")});
  return f;
}

Figure forces_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"forces", "Forces and friction against time", "", json(), "svg", ""};
  f.caption =
      "Top: normal force W and tangential force along the stroke F_t, N, from the force channels at the "
      "frame times (aligned to the camera clock). Bottom: friction coefficient μ = F_t / W on the tared "
      "channels (dimensionless; no point where W is below the channels' minimum normal force).";
  f.spec = vertical({line_panel(series_rows(results, {{"normal W", &ResultData::normal_N},
                                                      {"tangential F_t", &ResultData::tangential_N}}),
                                "force (N)", several, o, "zoom_force"),
                     line_panel(series_rows(results, {{"μ", &ResultData::mu}}), "μ (dimensionless)", several,
                                o, "zoom_mu")});
  return f;
}

std::string ratio_at_t90_text(const std::vector<ResultData>& results) {
  std::string text;
  for (const ResultData& r : results) {
    if (!std::isfinite(r.energy_ratio_at_t90)) continue;
    char buffer[96];
    std::snprintf(buffer, sizeof buffer, "%s%s: %.3g", text.empty() ? "" : "; ", r.label.c_str(),
                  r.energy_ratio_at_t90);
    text += buffer;
  }
  return text.empty() ? "" : " U/U_ext at t90 (/work/energy_ratio): " + text + ".";
}

Figure energy_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"energy", "Strain energy against time", "", json(), "svg", ""};
  f.caption =
      "Top: strain energy U of the measured strain field (plane-strain St Venant–Kirchhoff, scene's E, ν and "
      "depth), J. Bottom: U over the external work U_ext = ∫F_t dx accumulated since the onset "
      "(dimensionless), where U_ext is at least 1 % of its largest value." +
      ratio_at_t90_text(results);
  std::vector<json> panels{
      line_panel(series_rows(results, {{"U", &ResultData::energy_J}}), "U (J)", several, o, "zoom_u")};
  if (any_result_has(results, &ResultData::energy_ratio))
    panels.push_back(line_panel(series_rows(results, {{"U/U_ext", &ResultData::energy_ratio}}),
                                "U/U_ext (dimensionless)", several, o, "zoom_ratio"));
  f.spec = vertical(std::move(panels));
  return f;
}

Figure stick_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"stick", "Stick ratio against time", "", json(), "svg", ""};
  f.caption =
      "Stuck fraction of the meshed area (a triangle is stuck when its centroid moves with the plate within "
      "the stick tolerance) and the stick radius over the contact radius c/a from the Cattaneo–Mindlin slip "
      "profile fitted to the tracks (dimensionless).";
  f.spec = line_panel(series_rows(results, {{"stick ratio", &ResultData::stick_ratio},
                                            {"c/a (stick fit)", &ResultData::stick_radius_ratio}}),
                      "fraction (dimensionless)", several, o, "zoom_stick");
  return f;
}

Figure fit_figure(const std::vector<ResultData>& results, const FigureOptions& o) {
  const bool several = results.size() > 1;
  Figure f{"fit", "Model fit against time", "", json(), "svg", ""};
  f.caption =
      "The Hertz + Cattaneo–Mindlin field fitted to the tracked displacements frame by frame (/fit): top, "
      "the fitted stick radius over contact radius c/a (dimensionless); bottom, the tangential load Q it "
      "implies with the scene's tissue, N. The field of each frame is the one chosen by BIC.";
  f.spec = vertical({line_panel(series_rows(results, {{"c/a (fit)", &ResultData::fit_c_of_a}}),
                                "c/a (dimensionless)", several, o, "zoom_fit_c"),
                     line_panel(series_rows(results, {{"Q (fit)", &ResultData::fit_tangential_N}}), "Q (N)",
                                several, o, "zoom_fit_q")});
  return f;
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

std::vector<Figure> result_figures(const std::vector<ResultData>& results, const FigureOptions& options) {
  std::vector<Figure> figures;
  if (any_result_has(results, &ResultData::area_mm2)) figures.push_back(contact_figure(results, options));
  if (any_result_has(results, &ResultData::tracks_alive)) figures.push_back(tracks_figure(results, options));
  if (any_result_has(results, &ResultData::normal_N) || any_result_has(results, &ResultData::tangential_N))
    figures.push_back(forces_figure(results, options));
  if (options.maps)
    for (Figure& f : map_figures(results, options)) figures.push_back(std::move(f));
  if (any_result_has(results, &ResultData::energy_J)) figures.push_back(energy_figure(results, options));
  if (any_result_has(results, &ResultData::stick_ratio) ||
      any_result_has(results, &ResultData::stick_radius_ratio))
    figures.push_back(stick_figure(results, options));
  if (any_result_has(results, &ResultData::fit_c_of_a) ||
      any_result_has(results, &ResultData::fit_tangential_N))
    figures.push_back(fit_figure(results, options));
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
