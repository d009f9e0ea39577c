// Validation errors against the truth of a synthetic trial: the per-frame errors as plots and every row of
// validation.csv as a table.
#include <cmath>

#include "report/figures.hpp"

namespace tirstrain::report {
namespace {

using nlohmann::json;

json rows_of(const std::vector<double>& t_s,
             const std::vector<std::pair<std::string, const std::vector<double>*>>& series) {
  json rows = json::array();
  for (const auto& [name, values] : series)
    for (std::size_t i = 0; i < values->size() && i < t_s.size(); ++i)
      if (std::isfinite((*values)[i]) && std::isfinite(t_s[i]))
        rows.push_back({{"t_s", rounded(t_s[i])}, {"quantity", name}, {"value", rounded((*values)[i])}});
  return rows;
}

json panel(json rows, const std::string& y_title, const std::string& zoom) {
  return {{"width", 640},
          {"height", 180},
          {"data", {{"values", std::move(rows)}}},
          {"mark", {{"type", "line"}, {"point", {{"size", 14}}}}},
          {"encoding",
           {{"x", {{"field", "t_s"}, {"type", "quantitative"}, {"title", "time (s)"}}},
            {"y", {{"field", "value"}, {"type", "quantitative"}, {"title", y_title}}},
            {"color", {{"field", "quantity"}, {"type", "nominal"}, {"title", nullptr}}},
            {"tooltip", json::array({{{"field", "quantity"}},
                                     {{"field", "t_s"}, {"title", "t (s)"}},
                                     {{"field", "value"}, {"title", y_title}}})}}},
          {"params", json::array({{{"name", zoom}, {"select", "interval"}, {"bind", "scales"}}})}};
}

std::string summary_table(const TextTable& t) {
  std::string html = "<details><summary>Every row of validation.csv (" + std::to_string(t.rows.size()) +
                     " rows)</summary><div class=\"table\"><table><thead><tr>";
  for (const std::string& name : t.names) html += "<th>" + html_escape(name) + "</th>";
  html += "</tr></thead><tbody>";
  for (const auto& row : t.rows) {
    html += "<tr>";
    for (const std::string& cell : row) html += "<td>" + html_escape(cell) + "</td>";
    html += "</tr>";
  }
  return html + "</tbody></table></div></details>";
}

Figure validation_figure(const std::string& label, const ValidationData& v, std::size_t index) {
  Figure f;
  f.id = "validation-" + std::to_string(index);
  f.title = "Errors against the known truth" + (label.empty() ? "" : " (" + label + ")");
  f.caption =
      "From `tirstrain validate` (" + v.dir +
      "). First the RMS displacement error of the live tracks, px; then the RMS error of E_xx over the "
      "interior triangles (dimensionless); last the strain energy U measured and true on the same "
      "triangles, J (no point where a frame has no value). The "
      "table lists every error row (units in its unit column).";
  std::vector<json> panels;
  if (!v.t_s.empty()) {
    panels.push_back(panel(rows_of(v.t_s, {{"displacement RMS (px)", &v.displacement_rms_px}}),
                           "displacement error (px)", "zoom_vd_" + std::to_string(index)));
    panels.push_back(panel(rows_of(v.t_s, {{"E_xx RMS", &v.E_xx_rms}}), "E_xx error (dimensionless)",
                           "zoom_ve_" + std::to_string(index)));
    panels.push_back(panel(rows_of(v.t_s, {{"U measured", &v.U_J}, {"U true", &v.U_truth_J}}), "U (J)",
                           "zoom_vu_" + std::to_string(index)));
    f.spec = {{"vconcat", panels}, {"resolve", {{"scale", {{"color", "independent"}}}}}};
  }
  f.html = summary_table(v.summary);
  return f;
}

}  // namespace

std::vector<Figure> validation_figures(const std::vector<ResultData>& results,
                                       const std::vector<ValidationData>& validations) {
  std::vector<Figure> figures;
  for (std::size_t i = 0; i < validations.size(); ++i)
    figures.push_back(validation_figure(i < results.size() && results.size() > 1 ? results[i].label : "",
                                        validations[i], i));
  return figures;
}

}  // namespace tirstrain::report
