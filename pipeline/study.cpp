#include "pipeline/study.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/version.hpp"
#include "pipeline/output_folder.hpp"
#include "pipeline/process.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// FNV-1a, 64 bit: change detection, not security.
struct Fnv64 {
  std::uint64_t h = 1469598103934665603ULL;
  void add(const char* data, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(data[i])) * 1099511628211ULL;
  }
  void add(const std::string& s) {
    add(s.data(), s.size());
    add("\0", 1);  // separates fields, so "ab"+"c" differs from "a"+"bc"
  }
};

void hash_file(Fnv64& h, const fs::path& file, const fs::path& shown) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error("cannot read the trial's input file", {.file = file.string()});
  h.add(shown.string());
  std::vector<char> buffer(1 << 16);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    h.add(buffer.data(), static_cast<std::size_t>(in.gcount()));
  }
}

void hash_location(Fnv64& h, const fs::path& location) {
  if (!fs::is_directory(location)) return hash_file(h, location, location.filename());
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(location))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) hash_file(h, f, f.lexically_relative(location));
}

std::string status_path(const std::string& dir, const std::string& name) {
  return (fs::path(dir) / "status" / (name + ".json")).string();
}

double number_or_nan(const json& j, const std::string& a, const std::string& b = "") {
  if (!j.contains(a)) return std::nan("");
  const json& v = b.empty() ? j.at(a) : (j.at(a).contains(b) ? j.at(a).at(b) : json());
  return v.is_number() ? v.get<double>() : std::nan("");
}

json results_json(const TrialResults& r) {
  const auto n = [](double v) { return std::isfinite(v) ? json(v) : json(); };
  return {{"frames", r.frames},
          {"peak_contact_area_mm2", n(r.peak_contact_area_mm2)},
          {"mu_dynamic", n(r.mu_dynamic)},
          {"U_t90_J", n(r.U_t90_J)},
          {"onset_s", n(r.onset_s)},
          {"t90_s", n(r.t90_s)},
          {"full_slip_s", n(r.full_slip_s)},
          {"mu_P_N", n(r.mu_P_N)}};
}

TrialResults results_from_json(const json& j) {
  TrialResults r;
  r.frames = j.value("frames", std::int64_t{0});
  r.peak_contact_area_mm2 = number_or_nan(j, "peak_contact_area_mm2");
  r.mu_dynamic = number_or_nan(j, "mu_dynamic");
  r.U_t90_J = number_or_nan(j, "U_t90_J");
  r.onset_s = number_or_nan(j, "onset_s");
  r.t90_s = number_or_nan(j, "t90_s");
  r.full_slip_s = number_or_nan(j, "full_slip_s");
  r.mu_P_N = number_or_nan(j, "mu_P_N");
  return r;
}

void write_status(const std::string& dir, const TrialStatus& s) {
  const json j = {{"name", s.name},
                  {"status", s.status},
                  {"hash", s.hash},
                  {"version", s.version},
                  {"error", s.error},
                  {"wall_s", s.wall_s},
                  {"results", results_json(s.results)},
                  {"pid", s.pid},
                  {"host", s.host}};
  fs::create_directories(fs::path(dir) / "status");
  write_text_file(status_path(dir, s.name), j.dump(2) + "\n");
}

// The fitted μP of the frame with the largest fitted Q among those with a μP estimate: μP is best determined
// where Q/μP is largest (the slip annulus that carries it is widest), and frames just past the onset give
// degenerate estimates near 0. NaN when no frame has one.
double limit_at_largest_load(const std::vector<double>& limit_N, const std::vector<double>& tangential_N) {
  double best_Q = -1.0, limit = std::nan("");
  for (std::size_t i = 0; i < std::min(limit_N.size(), tangential_N.size()); ++i)
    if (std::isfinite(limit_N[i]) && std::isfinite(tangential_N[i]) && tangential_N[i] > best_Q) {
      best_Q = tangential_N[i];
      limit = limit_N[i];
    }
  return limit;
}

TrialResults read_key_results(const fs::path& out) {
  std::ifstream in(out / "summary.json");
  const json summary = json::parse(in);
  TrialResults r;
  if (summary.contains("frames") && summary["frames"].contains("total"))
    r.frames = summary["frames"]["total"].get<std::int64_t>();
  r.peak_contact_area_mm2 = number_or_nan(summary, "contact", "area_mm2_max");
  r.mu_dynamic = number_or_nan(summary, "channels", "mu_dynamic");
  r.U_t90_J = number_or_nan(summary, "channels", "strain_energy_at_t90_J");
  if (summary.contains("channels") && summary["channels"].contains("events")) {
    const json& e = summary["channels"]["events"];
    r.onset_s = number_or_nan(e, "onset_s");
    r.t90_s = number_or_nan(e, "t90_s");
    r.full_slip_s = number_or_nan(e, "full_slip_s");
  }
  const H5Reader h5((out / "result.h5").string());
  if (r.frames == 0) r.frames = static_cast<std::int64_t>(h5.shape("/frames/t_s")[0]);
  if (h5.has("/fit/limit_N"))
    r.mu_P_N = limit_at_largest_load(h5.read_doubles("/fit/limit_N"), h5.read_doubles("/fit/tangential_N"));
  return r;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string csv_number(double v) {
  return std::isfinite(v) ? format_double(v) : "";
}

}  // namespace

std::string trial_hash(const StudyTrial& trial) {
  Fnv64 h;
  h.add(std::string("tirstrain ") + kVersion);
  const std::vector<std::string> locations = input_locations(trial.input);
  if (locations.empty()) throw Error("a study trial's input must be files on disk", {.file = trial.input});
  for (const std::string& l : locations) {
    if (!fs::exists(l)) throw Error("no such input", {.file = l});
    hash_location(h, l);
  }
  h.add(trial.scene);
  if (!trial.scene.empty()) hash_file(h, trial.scene, "scene");
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h.h));
  return hex;
}

std::string study_fingerprint(const std::string& dir) {
  Fnv64 h;
  hash_file(h, fs::path(dir) / "plan.json", "plan");
  hash_file(h, fs::path(dir) / "study.csv", "study.csv");
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h.h));
  return hex;
}

void check_study_folder(const std::string& dir) {
  static const std::vector<std::string> kStudyNames = {"plan.json", "study.csv", "status",   "trials",
                                                       "logs",      "slurm",     "aggregate"};
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("is a file, not a folder", {.file = dir, .key = "--out"});
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    const bool leftover = name.size() > 8 && name.compare(name.size() - 8, 8, ".partial") == 0;
    if (std::find(kStudyNames.begin(), kStudyNames.end(), name) == kStudyNames.end() && !leftover)
      throw Error("holds '" + name +
                      "', which a study does not write: give a new or empty folder, or an earlier study's",
                  {.file = dir, .key = "--out"});
  }
}

void write_plan(const std::string& dir, const StudySpec& spec) {
  json trials = json::array();
  for (const StudyTrial& t : spec.trials)
    trials.push_back(
        {{"name", t.name}, {"input", t.input}, {"scene", t.scene}, {"conditions", t.conditions}});
  json laws = json::array();
  for (const StudyPowerLaw& p : spec.aggregate.power_laws)
    laws.push_back({{"name", p.name}, {"normal", p.normal}, {"mu", p.mu}});
  const json plan = {
      {"study_file", spec.file},
      {"version", kVersion},
      {"trials", trials},
      {"compute", spec.compute},
      {"aggregate",
       {{"power_laws", laws}, {"maps_by", spec.aggregate.maps_by}, {"table_by", spec.aggregate.table_by}}}};
  write_text_file((fs::path(dir) / "plan.json").string(), plan.dump(2) + "\n");
}

StudySpec read_plan(const std::string& dir) {
  const std::string path = (fs::path(dir) / "plan.json").string();
  std::ifstream in(path);
  if (!in) throw Error("not a study folder (no plan.json; run tirstrain study run first)", {.file = path});
  try {
    const json plan = json::parse(in);
    StudySpec spec;
    spec.file = plan.at("study_file").get<std::string>();
    for (const json& t : plan.at("trials"))
      spec.trials.push_back({t.at("name"), t.at("input"), t.at("scene"), t.at("conditions")});
    spec.compute = plan.at("compute").get<std::vector<std::string>>();
    for (const json& p : plan.at("aggregate").at("power_laws"))
      spec.aggregate.power_laws.push_back({p.at("name"), p.at("normal"), p.at("mu")});
    spec.aggregate.maps_by = plan.at("aggregate").at("maps_by").get<std::vector<std::string>>();
    spec.aggregate.table_by = plan.at("aggregate").at("table_by").get<std::vector<std::string>>();
    return spec;
  } catch (const json::exception& e) {
    throw Error(std::string("corrupt plan: ") + e.what(), {.file = path});
  }
}

namespace {

std::string this_host() {
  char name[256] = {};
  return ::gethostname(name, sizeof name - 1) == 0 ? std::string(name) : std::string();
}

// A trial left "running" by a process that was killed: known only on the machine it ran on.
bool process_is_gone(long pid, const std::string& host) {
  if (pid <= 0 || host.empty() || host != this_host()) return false;
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

}  // namespace

TrialStatus read_status(const std::string& dir, const std::string& name) {
  TrialStatus s;
  s.name = name;
  std::ifstream in(status_path(dir, name));
  if (!in) return s;
  try {
    const json j = json::parse(in);
    s.status = j.at("status");
    s.hash = j.at("hash");
    s.version = j.at("version");
    s.error = j.at("error");
    s.wall_s = j.at("wall_s");
    s.results = results_from_json(j.at("results"));
    s.pid = j.value("pid", 0L);
    s.host = j.value("host", std::string());
  } catch (const json::exception& e) {
    s.status = "failed";
    s.error = std::string("unreadable status file: ") + e.what();
  }
  return s;
}

TrialStatus observed_status(const std::string& dir, const std::string& name) {
  TrialStatus s = read_status(dir, name);
  if (s.status == "running" && process_is_gone(s.pid, s.host)) {
    s.status = "failed";
    s.error = "interrupted: the process that ran it (" + std::to_string(s.pid) + " on " + s.host +
              ") is gone; run the study again";
  }
  return s;
}

std::vector<std::size_t> trials_needing_work(const std::string& dir, const StudySpec& spec) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < spec.trials.size(); ++i) {
    const StudyTrial& t = spec.trials[i];
    const TrialStatus s = read_status(dir, t.name);
    const bool complete = fs::exists(fs::path(dir) / "trials" / t.name / "result.h5");
    std::string hash;
    try {
      hash = trial_hash(t);
    } catch (const Error&) {
      hash = "unreadable";  // the task records why
    }
    if (s.status != "done" || !complete || s.hash != hash) out.push_back(i);
  }
  return out;
}

void record_failure(const std::string& dir, const StudyTrial& trial, const std::string& error) {
  TrialStatus s;
  s.name = trial.name;
  s.status = "failed";
  s.version = kVersion;
  s.error = error;
  write_status(dir, s);
}

void mark_queued(const std::string& dir, const StudyTrial& trial) {
  TrialStatus s;
  s.name = trial.name;
  s.status = "queued";
  s.version = kVersion;
  write_status(dir, s);
}

bool run_study_trial(const std::string& dir, std::size_t index) {
  const StudySpec spec = read_plan(dir);
  if (index >= spec.trials.size())
    throw Error("trial index " + std::to_string(index) + " is outside the plan's " +
                    std::to_string(spec.trials.size()) + " trials",
                {.file = dir});
  const StudyTrial& trial = spec.trials[index];
  TrialStatus s;
  s.name = trial.name;
  s.version = kVersion;
  const auto start = std::chrono::steady_clock::now();
  try {
    s.hash = trial_hash(trial);
    s.status = "running";
    s.pid = static_cast<long>(::getpid());
    s.host = this_host();
    write_status(dir, s);
    s.pid = 0;  // the outcome written below is no process's state
    s.host.clear();
    ProcessOptions o;
    o.input = trial.input;
    if (!trial.scene.empty()) o.scene_path = trial.scene;
    o.out_dir = (fs::path(dir) / "trials" / trial.name).string();
    o.overlay = OverlayMode::kNone;
    o.quiet = true;
    o.compute = spec.compute;
    fs::create_directories(fs::path(dir) / "trials");
    run_process(o);
    s.results = read_key_results(o.out_dir);
    s.status = "done";
  } catch (const std::exception& e) {
    s.status = "failed";
    s.error = e.what();
  }
  s.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_status(dir, s);
  return s.status == "done";
}

void write_study_csv(const std::string& dir, const StudySpec& spec) {
  std::set<std::string> keys;
  for (const StudyTrial& t : spec.trials)
    for (const auto& [k, v] : t.conditions) keys.insert(k);
  std::ostringstream csv;
  csv << "name";
  for (const std::string& k : keys) csv << ',' << k;
  csv << ",status,frames,peak_contact_area_mm2,mu_dynamic,U_t90_J,onset_s,t90_s,full_slip_s,mu_P_N,hash,"
         "error\n";
  for (const StudyTrial& t : spec.trials) {
    const TrialStatus s = observed_status(dir, t.name);
    csv << csv_field(t.name);
    for (const std::string& k : keys)
      csv << ',' << csv_field(t.conditions.count(k) ? t.conditions.at(k) : "");
    const TrialResults& r = s.results;
    const bool done = s.status == "done";
    csv << ',' << s.status << ',' << (done ? std::to_string(r.frames) : "") << ','
        << csv_number(r.peak_contact_area_mm2) << ',' << csv_number(r.mu_dynamic) << ','
        << csv_number(r.U_t90_J) << ',' << csv_number(r.onset_s) << ',' << csv_number(r.t90_s) << ','
        << csv_number(r.full_slip_s) << ',' << csv_number(r.mu_P_N) << ',' << s.hash << ','
        << csv_field(s.error) << '\n';
  }
  write_text_file((fs::path(dir) / "study.csv").string(), csv.str());
}

std::string study_status_text(const std::string& dir, const StudySpec& spec) {
  std::map<std::string, int> counts;
  std::string failures;
  double wall_s = 0.0;
  for (const StudyTrial& t : spec.trials) {
    const TrialStatus s = observed_status(dir, t.name);
    ++counts[s.status];
    wall_s += s.wall_s;
    if (s.status == "failed") failures += "  " + t.name + ": " + s.error + "\n";
  }
  std::ostringstream out;
  out << spec.trials.size() << " trials (" << spec.file << "):";
  for (const char* k : {"done", "failed", "running", "queued", "pending"})
    out << ' ' << counts[k] << ' ' << k;
  out << "; processing time " << format_double(std::round(wall_s * 10.0) / 10.0) << " s\n";
  if (!failures.empty()) out << "failed:\n" << failures;
  return out.str();
}

}  // namespace tirstrain::pipeline
