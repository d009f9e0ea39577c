// DIR/aggregate/ of a study: what is computed across its trials (docs/formats.md, "Study folder").
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "pipeline/study.hpp"
#include "pipeline/study_executor.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

struct Row {
  const StudyTrial* trial;
  TrialStatus status;
  std::map<std::string, double> numbers;  // study.csv's numeric result columns (finite only)
};

const std::vector<std::string>& metric_names() {
  static const std::vector<std::string> names = {
      "peak_contact_area_mm2", "mu_dynamic", "U_t90_J", "onset_s", "t90_s", "full_slip_s", "mu_P_N"};
  return names;
}

std::vector<Row> done_rows(const std::string& dir, const StudySpec& spec) {
  std::vector<Row> rows;
  for (const StudyTrial& t : spec.trials) {
    Row r{&t, observed_status(dir, t.name), {}};
    if (r.status.status != "done") continue;
    const TrialResults& v = r.status.results;
    const double values[] = {v.peak_contact_area_mm2, v.mu_dynamic, v.U_t90_J, v.onset_s, v.t90_s,
                             v.full_slip_s,           v.mu_P_N};
    for (std::size_t k = 0; k < metric_names().size(); ++k)
      if (std::isfinite(values[k])) r.numbers[metric_names()[k]] = values[k];
    rows.push_back(r);
  }
  return rows;
}

// A column of study.csv for one trial, as a number: a result column or a numeric condition.
std::optional<double> column_value(const Row& r, const std::string& column) {
  if (const auto it = r.numbers.find(column); it != r.numbers.end()) return it->second;
  const auto c = r.trial->conditions.find(column);
  if (c == r.trial->conditions.end()) return std::nullopt;
  try {
    std::size_t used = 0;
    const double v = std::stod(c->second, &used);
    if (used == c->second.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

// "key=value,key=value" of the grouping keys (a folder name: characters other than letters, digits and
// ".-_=," become '_').
std::string group_name(const StudyTrial& t, const std::vector<std::string>& by) {
  std::string name;
  for (const std::string& k : by) {
    name += (name.empty() ? "" : ",") + k + "=" + (t.conditions.count(k) ? t.conditions.at(k) : "");
  }
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && std::string(".-_=,").find(c) == std::string::npos)
      c = '_';
  return name.empty() ? "all" : name;
}

std::vector<std::string> condition_keys(const StudySpec& spec) {
  std::set<std::string> keys;
  for (const StudyTrial& t : spec.trials)
    for (const auto& [k, v] : t.conditions) keys.insert(k);
  return {keys.begin(), keys.end()};
}

// conditions.csv: per group, the trials and the mean and sample SD of each key result over its done trials.
void write_condition_table(const fs::path& out, const StudySpec& spec, const std::vector<Row>& rows) {
  const std::vector<std::string> by =
      spec.aggregate.table_by.empty() ? condition_keys(spec) : spec.aggregate.table_by;
  std::map<std::string, std::vector<const Row*>> groups;
  std::map<std::string, const StudyTrial*> first;
  for (const StudyTrial& t : spec.trials) first.emplace(group_name(t, by), &t);
  for (const Row& r : rows) groups[group_name(*r.trial, by)].push_back(&r);
  std::ostringstream csv;
  for (const std::string& k : by) csv << k << ',';
  csv << "trials,trials_done";
  for (const std::string& m : metric_names()) csv << ',' << m << "_mean," << m << "_sd," << m << "_n";
  csv << '\n';
  for (const auto& [name, trial] : first) {
    const std::vector<const Row*>& g = groups[name];
    for (const std::string& k : by) csv << (trial->conditions.count(k) ? trial->conditions.at(k) : "") << ',';
    std::size_t total = 0;
    for (const StudyTrial& t : spec.trials) total += group_name(t, by) == name;
    csv << total << ',' << g.size();
    for (const std::string& m : metric_names()) {
      double sum = 0.0, sum2 = 0.0;
      std::size_t n = 0;
      for (const Row* r : g)
        if (const auto it = r->numbers.find(m); it != r->numbers.end()) {
          sum += it->second;
          sum2 += it->second * it->second;
          ++n;
        }
      const double mean = n > 0 ? sum / static_cast<double>(n) : std::nan("");
      const double sd = n > 1 ? std::sqrt(std::max(0.0, (sum2 - static_cast<double>(n) * mean * mean) /
                                                            static_cast<double>(n - 1)))
                              : std::nan("");
      csv << ',' << (std::isfinite(mean) ? format_double(mean) : "") << ','
          << (std::isfinite(sd) ? format_double(sd) : "") << ',' << n;
    }
    csv << '\n';
  }
  write_text_file((out / "conditions.csv").string(), csv.str());
}

void power_law(const fs::path& out, const StudyPowerLaw& law, const std::vector<Row>& rows,
               const std::string& cli, const std::string& log, std::vector<std::string>* problems) {
  std::ostringstream csv;
  csv << "normal_N,mu\n";  // numbers only: signals power-law reads every column as one
  std::size_t n = 0;
  for (const Row& r : rows) {
    const auto w = column_value(r, law.normal), mu = column_value(r, law.mu);
    if (!w || !mu) continue;
    csv << format_double(*w) << ',' << format_double(*mu) << '\n';
    ++n;
  }
  const std::string stem = "power_law_" + law.name;
  write_text_file((out / (stem + ".csv")).string(), csv.str());
  if (n < 3) {
    problems->push_back(stem + ": " + std::to_string(n) + " trials have both " + law.normal + " and " +
                        law.mu + " (3 or more needed)");
    return;
  }
  const int code = run_child({cli, "signals", "power-law", (out / (stem + ".csv")).string(), "--normal",
                              "normal_N", "--mu", "mu", "--out", (out / (stem + ".json")).string()},
                             log);
  if (code != 0)
    problems->push_back(stem + ": tirstrain signals power-law failed (exit " + std::to_string(code) +
                        ", see logs/aggregate.log)");
}

void averaged_maps(const fs::path& out, const std::string& dir, const StudySpec& spec,
                   const std::vector<Row>& rows, const std::string& cli, const std::string& log,
                   std::vector<std::string>* problems) {
  if (spec.aggregate.maps_by.empty()) return;
  std::map<std::string, std::vector<std::string>> groups;
  for (const Row& r : rows)
    groups[group_name(*r.trial, spec.aggregate.maps_by)].push_back(
        (fs::path(dir) / "trials" / r.trial->name / "result.h5").string());
  fs::create_directories(out / "maps");
  for (const auto& [name, results] : groups) {
    std::vector<std::string> argv = {cli, "average"};
    argv.insert(argv.end(), results.begin(), results.end());
    argv.insert(argv.end(), {"--out", (out / "maps" / name).string()});
    const int code = run_child(argv, log);
    if (code != 0)
      problems->push_back("maps/" + name + ": tirstrain average failed (exit " + std::to_string(code) +
                          ", see logs/aggregate.log)");
  }
}

// The study report: every done trial's result on one page (`tirstrain report`), time series overlaid. Beyond
// kReportMapTrials trials the per-trial strain maps are left out (the page would grow by about 1 MB a trial);
// the maps averaged per condition are in aggregate/maps/.
constexpr std::size_t kReportMapTrials = 8;

std::string study_report(const fs::path& out, const std::string& dir, const std::vector<Row>& rows,
                         const std::string& cli, const std::string& log, std::vector<std::string>* problems) {
  if (rows.empty()) return "not written: no trial is done";
  std::vector<std::string> argv = {cli, "report"};
  for (const Row& r : rows) argv.push_back((fs::path(dir) / "trials" / r.trial->name).string());
  argv.insert(argv.end(), {"--out", (out / "report.html").string(), "--title",
                           "tirstrain study: " + fs::path(dir).filename().string(), "--quiet"});
  const bool maps = rows.size() <= kReportMapTrials;
  if (!maps) argv.push_back("--no-maps");
  const int code = run_child(argv, log);
  if (code != 0) {
    problems->push_back("report.html: tirstrain report failed (exit " + std::to_string(code) +
                        ", see logs/aggregate.log)");
    return "not written: tirstrain report failed";
  }
  return maps ? "report.html"
              : "report.html (without per-trial strain maps: more than " + std::to_string(kReportMapTrials) +
                    " trials)";
}

// The problems recorded by an aggregate/ built from the same plan and outcomes, if there is one.
std::optional<std::vector<std::string>> up_to_date(const std::string& dir, const std::string& fingerprint) {
  std::ifstream in(fs::path(dir) / "aggregate" / "aggregate.json");
  if (!in) return std::nullopt;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.value("fingerprint", "") != fingerprint) return std::nullopt;
    return j.at("problems").get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::vector<std::string> aggregate_study(const std::string& dir, const StudySpec& spec,
                                         const std::string& cli) {
  const std::string fingerprint = study_fingerprint(dir);
  if (const auto problems = up_to_date(dir, fingerprint)) return *problems;
  const std::vector<Row> rows = done_rows(dir, spec);
  const std::string log = (fs::path(dir) / "logs" / "aggregate.log").string();
  fs::create_directories(fs::path(dir) / "logs");
  std::remove(log.c_str());
  std::vector<std::string> problems;
  StagingDirectory staging((fs::path(dir) / "aggregate").string());
  const fs::path out(staging.path());
  write_condition_table(out, spec, rows);
  for (const StudyPowerLaw& law : spec.aggregate.power_laws) power_law(out, law, rows, cli, log, &problems);
  averaged_maps(out, dir, spec, rows, cli, log, &problems);
  const std::string report = study_report(out, dir, rows, cli, log, &problems);
  const nlohmann::json summary = {{"trials", spec.trials.size()},
                                  {"trials_done", rows.size()},
                                  {"problems", problems},
                                  {"report", report},
                                  {"fingerprint", fingerprint}};
  write_text_file((out / "aggregate.json").string(), summary.dump(2) + "\n");
  staging.commit();
  return problems;
}

}  // namespace tirstrain::pipeline
