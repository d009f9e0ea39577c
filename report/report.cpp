#include "report/report.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "core/version.hpp"
#include "report/html_page.hpp"
#include "report/validation_data.hpp"
#include "report/vendored_scripts.hpp"

namespace tirstrain::report {
namespace {

namespace fs = std::filesystem;

// An existing file at --out is replaced only when it is an earlier page (every page carries its figures'
// specifications in one script element): anything else may be a user's.
void check_replaceable_page(const fs::path& out, const std::string& out_arg) {
  if (!fs::exists(out)) return;
  std::ifstream in(out, std::ios::binary);
  const std::string page((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (page.find(kGeneratorMeta) == std::string::npos && page.find(kSpecsScriptId) == std::string::npos)
    throw Error(
        "exists and is not a page tirstrain report wrote: it is not replaced; remove it or choose "
        "another file",
        {.file = out_arg, .key = "--out"});
}

// The inputs first, so that a missing one is named as such; then the page goes beside them, never into
// one: `process` replaces its folder as a whole and refuses a folder holding files it does not write, so a
// report inside would block the next run there, and it must never replace an input.
void check_output(const ReportOptions& o) {
  if (o.out_path.empty()) throw Error("an output file is required", {.key = "--out"});
  if (!o.validations.empty() && o.validations.size() != o.results.size())
    throw Error("give one --validation folder per result, in the results' order (" +
                    std::to_string(o.results.size()) + " results, " + std::to_string(o.validations.size()) +
                    " validation folders)",
                {.key = "--validation"});
  std::vector<std::string> input_folders;
  for (const std::string& input : o.results) {
    const fs::path file(result_file_of(input));
    input_folders.push_back(file.parent_path().empty() ? "." : file.parent_path().string());
  }
  for (const std::string& dir : o.validations) {
    if (!fs::is_directory(dir))
      throw Error("no such folder: give a folder written by `tirstrain validate`",
                  {.file = dir, .key = "--validation"});
    input_folders.push_back(dir);
  }
  if (fs::is_directory(o.out_path))
    throw Error("is a folder: give the HTML file to write", {.file = o.out_path, .key = "--out"});
  for (const std::string& folder : input_folders)
    if (path_is_within(o.out_path, folder))
      throw Error("is inside the input folder " + folder + ": write the report beside it",
                  {.file = o.out_path, .key = "--out"});
  const fs::path out = fs::absolute(o.out_path).lexically_normal();
  check_replaceable_page(out, o.out_path);
  ensure_output_dir(out.parent_path().string(), "--out");
}

// Distinct labels: results from folders of the same name get their position appended.
void make_labels_distinct(std::vector<ResultData>& results) {
  for (std::size_t i = 0; i < results.size(); ++i)
    for (std::size_t j = i + 1; j < results.size(); ++j)
      if (results[j].label == results[i].label) results[j].label += " (" + std::to_string(j + 1) + ")";
}

std::string row(const std::string& name, const std::string& value) {
  return "<tr><th>" + html_escape(name) + "</th><td>" + html_escape(value) + "</td></tr>";
}

std::string json_text(const nlohmann::json& j, const char* key) {
  if (!j.contains(key)) return "";
  return j[key].is_string() ? j[key].get<std::string>() : j[key].dump();
}

std::string result_settings(const ResultData& r) {
  std::string html = "<h3>" + html_escape(r.label) + "</h3><table>";
  html += row("folder", r.dir) + row("software", r.software_version) + row("input", r.input) +
          row("stages", r.stages);
  html += row("scene", json_text(r.summary, "scene")) + row("px per mm", json_text(r.summary, "px_per_mm"));
  html += row("tissue", json_text(r.summary, "tissue")) +
          row("defaults used", json_text(r.summary, "defaults_used"));
  html += row("warnings", json_text(r.summary, "warnings")) + "</table>";
  if (r.summary.contains("tracking") && r.summary["tracking"].contains("settings"))
    html += "<details><summary>Tracking settings in effect</summary><pre>" +
            html_escape(r.summary["tracking"]["settings"].dump(2)) + "</pre></details>";
  html += "<details><summary>Scene in effect (YAML)</summary><pre>" + html_escape(r.scene_yaml) +
          "</pre></details>";
  html +=
      "<details><summary>summary.json</summary><pre>" + html_escape(r.summary.dump(2)) + "</pre></details>";
  return html;
}

std::string software_versions() {
  std::string html = "<p>Written by tirstrain " + std::string(kVersion) + ". Plots drawn with";
  for (const VendoredScript& s : vendored_scripts())
    html += " " + std::string(s.name) + " " + s.version + ",";
  html.back() = '.';
  html += " (inlined; their licences follow).</p>";
  for (const VendoredScript& s : vendored_scripts())
    html += "<details><summary>Licence of " + std::string(s.name) + "</summary><pre>" +
            html_escape(std::string(s.licence)) + "</pre></details>";
  return html;
}

std::string intro(const std::vector<ResultData>& results) {
  std::string html = "<p>Results: ";
  for (std::size_t i = 0; i < results.size(); ++i)
    html += (i ? ", " : "") + std::string("<b>") + html_escape(results[i].label) + "</b> (" +
            html_escape(results[i].dir) + ")";
  return html +
         ". Drag a plot to pan, use the wheel to zoom, hover a point for its values; the ⋯ menu of "
         "each plot saves it as SVG or PNG.</p>\n";
}

Page build_page(const ReportOptions& o, const std::vector<ResultData>& results,
                const std::vector<ValidationData>& validations) {
  Page page;
  page.title = o.title;
  if (page.title.empty()) {
    page.title = "tirstrain report:";
    for (const ResultData& r : results) page.title += " " + r.label;
  }
  page.intro_html = intro(results);
  if (!o.figures.maps) page.intro_html += "<p>The strain maps are left out of this page (--no-maps).</p>\n";
  page.figures = result_figures(results, o.figures);
  for (Figure& f : validation_figures(results, validations)) page.figures.push_back(std::move(f));
  std::string settings;
  for (const ResultData& r : results) settings += result_settings(r);
  page.sections.push_back({"settings", "Settings and software of the runs", settings});
  page.sections.push_back({"software", "This page", software_versions()});
  return page;
}

}  // namespace

ReportSummary write_report(const ReportOptions& o) {
  if (o.results.empty()) throw Error("give at least one result folder written by `tirstrain process`");
  check_output(o);
  std::vector<ResultData> results;
  for (const std::string& path : o.results) results.push_back(read_result(path, o.read));
  make_labels_distinct(results);
  std::vector<ValidationData> validations;
  for (const std::string& dir : o.validations) validations.push_back(read_validation(dir));
  for (std::size_t i = 0; i < validations.size(); ++i)
    check_validation_of(validations[i], results[i].summary, results[i].dir);
  const Page page = build_page(o, results, validations);
  const std::string html = render_page(page);
  AtomicFile out(o.out_path);
  out.append(html);
  out.commit();
  ReportSummary summary;
  for (const Figure& f : page.figures) summary.figure_ids.push_back(f.id);
  summary.bytes = html.size();
  return summary;
}

}  // namespace tirstrain::report
