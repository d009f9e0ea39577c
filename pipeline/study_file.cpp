#include "pipeline/study_file.hpp"

#include <glob.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <set>

#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

// study.csv's own columns, which a condition key must not shadow.
const std::set<std::string>& reserved_columns() {
  static const std::set<std::string> names = {"name",        "status",  "frames",  "peak_contact_area_mm2",
                                              "mu_dynamic",  "U_t90_J", "onset_s", "t90_s",
                                              "full_slip_s", "mu_P_N",  "hash",    "error"};
  return names;
}

// Letters, digits and '_', not starting with a digit: a study.csv column name.
bool is_identifier(const std::string& name) {
  const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; };
  return !name.empty() && std::isdigit(static_cast<unsigned char>(name[0])) == 0 &&
         std::all_of(name.begin(), name.end(), word);
}

// Runs fn(); an Error it throws gains the 1-based line of `section` (list entries have no key of their own).
template <typename Fn>
void at_line(const YamlSection& section, Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    if (e.context().row || section.line() == 0) throw;
    ErrorContext context = e.context();
    context.row = section.line();
    throw Error(e.message(), context);
  }
}

std::string absolute_from(const fs::path& base, const std::string& path) {
  const fs::path p(path);
  return (p.is_absolute() ? p : base / p).lexically_normal().string();
}

std::map<std::string, std::string> read_conditions(YamlSection& trial) {
  std::map<std::string, std::string> out;
  const std::string& file = trial.file();
  for (const auto& [name, value] : trial.text_map("conditions")) {
    const std::string where = trial.path_of("conditions") + "." + name;
    if (!is_identifier(name))
      throw Error("a condition name is letters, digits and _ (a study.csv column)",
                  {.file = file, .key = where});
    if (reserved_columns().count(name) > 0)
      throw Error("'" + name + "' is a column study.csv has already", {.file = file, .key = where});
    out[name] = value;
  }
  return out;
}

void check_trial_name(const std::string& name, const std::string& file, const std::string& key) {
  const auto allowed = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' || c == '_' || c == '-';
  };
  if (name.empty() || std::isalnum(static_cast<unsigned char>(name[0])) == 0 ||
      !std::all_of(name.begin(), name.end(), allowed))
    throw Error(
        "a trial name is letters, digits, '.', '_' and '-', starting with a letter or digit "
        "(it names the folder trials/NAME)",
        {.file = file, .key = key});
}

StudyTrial read_trial(YamlSection& s, const fs::path& base, const std::string& default_scene) {
  const std::string& file = s.file();
  StudyTrial trial;
  at_line(s, [&] {
    trial.name = s.required_text("name");
    check_trial_name(trial.name, file, s.path_of("name"));
    trial.input = absolute_from(base, s.required_text("input"));
    const std::string scene = s.text("scene", "");
    trial.scene = scene.empty() ? default_scene : absolute_from(base, scene);
    trial.conditions = read_conditions(s);
    s.finish();
  });
  return trial;
}

std::vector<StudyTrial> glob_trials(const std::string& pattern, const std::string& file, const fs::path& base,
                                    const std::string& scene) {
  const std::string full = absolute_from(base, pattern);
  glob_t found{};
  const int rc = ::glob(full.c_str(), 0, nullptr, &found);
  std::vector<std::string> paths(found.gl_pathv, found.gl_pathv + (rc == 0 ? found.gl_pathc : 0));
  ::globfree(&found);
  if (paths.empty()) throw Error("the pattern matches nothing: " + full, {.file = file, .key = "inputs"});
  std::sort(paths.begin(), paths.end());
  std::vector<StudyTrial> trials;
  for (std::string p : paths) {
    while (p.size() > 1 && p.back() == '/') p.pop_back();
    StudyTrial t{fs::path(p).filename().string(), p, scene, {}};
    check_trial_name(t.name, file, "inputs (" + p + ")");
    trials.push_back(t);
  }
  return trials;
}

StudyAggregate read_aggregate(YamlSection s) {
  StudyAggregate a;
  for (YamlSection& law : s.sections("power_laws")) {
    at_line(law, [&] {
      StudyPowerLaw p;
      p.name = law.required_text("name");
      check_trial_name(p.name, s.file(), law.path_of("name"));
      p.normal = law.text("normal", p.normal);
      p.mu = law.text("mu", p.mu);
      law.finish();
      a.power_laws.push_back(p);
    });
  }
  YamlSection maps = s.section("maps");
  a.maps_by = maps.texts("by", {}, "names");
  maps.finish();
  YamlSection table = s.section("table");
  a.table_by = table.texts("by", {}, "names");
  table.finish();
  s.finish();
  return a;
}

StudySlurm read_slurm(YamlSection s) {
  StudySlurm r;
  r.partition = s.text("partition", "");
  r.cpus_per_task = s.integer("cpus_per_task", 1, 1, 1024);
  r.mem_MB = s.integer("mem_MB", 0, 0, 1L << 30);
  r.time_min = s.integer("time_min", 0, 0, 1L << 20);
  s.finish();
  return r;
}

// Every grouping key names a condition some trial has; trial names are unique.
void check_consistency(const StudySpec& spec) {
  std::set<std::string> names, keys;
  for (const StudyTrial& t : spec.trials) {
    if (!names.insert(t.name).second)
      throw Error("two trials are named '" + t.name + "' (" + t.input + " and another input of that name)",
                  {.file = spec.file, .key = "inputs"});
    for (const auto& [k, v] : t.conditions) keys.insert(k);
  }
  const auto check = [&](const std::vector<std::string>& by, const std::string& key) {
    for (const std::string& k : by)
      if (keys.count(k) == 0)
        throw Error("'" + k + "' is not a condition of any trial", {.file = spec.file, .key = key});
  };
  static const std::set<std::string> results = {
      "peak_contact_area_mm2", "mu_dynamic", "U_t90_J", "onset_s", "t90_s", "full_slip_s", "mu_P_N"};
  for (std::size_t i = 0; i < spec.aggregate.power_laws.size(); ++i) {
    const StudyPowerLaw& p = spec.aggregate.power_laws[i];
    for (const std::string& column : {p.normal, p.mu})
      if (keys.count(column) == 0 && results.count(column) == 0)
        throw Error("'" + column + "' is neither a condition nor a key result column of study.csv",
                    {.file = spec.file, .key = "aggregate.power_laws[" + std::to_string(i) + "]"});
  }
  check(spec.aggregate.maps_by, "aggregate.maps.by");
  check(spec.aggregate.table_by, "aggregate.table.by");
}

}  // namespace

StudySpec load_study_file(const std::string& path) {
  StudySpec spec;
  spec.file = fs::absolute(path).lexically_normal().string();
  const fs::path base = fs::path(spec.file).parent_path();
  YamlSection top(SceneSection::load(path), spec.file);
  const std::string scene = top.text("scene", "");
  const std::string default_scene = scene.empty() ? "" : absolute_from(base, scene);
  const bool listed = top.has("trials");
  const std::string pattern = top.text("inputs", "");
  if (listed == !pattern.empty())
    throw Error("give either trials: (a list) or inputs: (a glob pattern), not both or neither",
                {.file = spec.file, .key = "trials"});
  if (listed) {
    std::vector<YamlSection> trials = top.sections("trials");
    if (trials.empty())
      throw Error("expected a non-empty list of {name, input, scene, conditions}",
                  {.file = spec.file, .key = "trials"});
    std::set<std::string> names;
    for (YamlSection& trial : trials) {
      spec.trials.push_back(read_trial(trial, base, default_scene));
      // Said here, where the second entry's line is known; check_consistency catches a glob's twins.
      at_line(trial, [&] {
        if (!names.insert(spec.trials.back().name).second)
          throw Error("two trials are named '" + spec.trials.back().name + "'",
                      {.file = spec.file, .key = trial.path_of("name")});
      });
    }
  } else {
    spec.trials = glob_trials(pattern, spec.file, base, default_scene);
  }
  spec.compute = top.texts("compute", {}, "names");
  spec.aggregate = read_aggregate(top.section("aggregate"));
  spec.slurm = read_slurm(top.section("slurm"));
  top.finish();
  check_consistency(spec);
  return spec;
}

}  // namespace tirstrain::pipeline
