// `tirstrain orientation-stats RESULT... --at INSTANT... --out DIR`: circular statistics of the ridge
// orientation and of the principal strain directions at chosen instants of processed trials, Kuiper's
// test between every two groups (a group is one trial at one instant), and their rose diagrams.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/atomic_output.hpp"
#include "core/circular_statistics.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/rose_plot.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct OrientationOptions {
  std::vector<std::string> inputs;          // result.h5 files or process output folders
  std::vector<std::string> instants;        // onset, t90, full_slip or a frame number
  std::string out;                          // output folder
  std::size_t bins = 18;                    // sectors of [0, π) in the rose diagrams
  double min_coherence = 0.3;               // ridge blocks below are not used
  double min_principal_difference = 0.005;  // triangles with e1 − e2 below are not used (no defined axis)
};

// One trial at one instant: its directions of both kinds.
struct Group {
  std::string label;
  std::size_t frame = 0;
  std::vector<double> ridge_rad, principal_rad;
  std::size_t ridge_excluded = 0, principal_excluded = 0;
};

std::string result_file(const std::string& input) {
  const std::string path = fs::is_directory(input) ? (fs::path(input) / "result.h5").string() : input;
  if (!fs::exists(path)) throw Error("no such result", {.file = path});
  return path;
}

std::string trial_label(const std::string& input) {
  fs::path p(input);
  if (p.filename() == "result.h5" || p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

std::size_t instant_frame(const H5Reader& h5, const std::string& instant, std::size_t frames) {
  long frame = -1;
  if (instant == "last") {
    frame = static_cast<long>(frames) - 1;
  } else if (instant == "onset" || instant == "t90" || instant == "full_slip") {
    const std::string name = "/events/" + instant + "_frame";
    if (!h5.has(name))
      throw Error("no " + name +
                      ": the trial was processed without force channels, or the event was not "
                      "found; give a frame number instead",
                  {.file = h5.path(), .key = "--at"});
    frame = static_cast<long>(h5.read_integers(name).at(0));
  } else {
    try {
      std::size_t used = 0;
      frame = std::stol(instant, &used);
      if (used != instant.size()) frame = -2;
    } catch (const std::exception&) {
      frame = -2;
    }
    if (frame == -2)
      throw Error("'" + instant + "' is neither onset, t90, full_slip, last nor a frame number",
                  {.key = "--at"});
  }
  if (frame < 0 || static_cast<std::size_t>(frame) >= frames)
    throw Error("frame " + std::to_string(frame) + " of '" + instant + "' is outside the result's " +
                    std::to_string(frames) + " frames",
                {.file = h5.path(), .key = "--at"});
  return static_cast<std::size_t>(frame);
}

void read_ridges(const H5Reader& h5, Group& g, double min_coherence) {
  if (!h5.has("/contact/orientation_rad")) return;
  H5Shape shape;
  const auto angle = h5.read_doubles("/contact/orientation_rad", &shape);
  const auto coherence = h5.read_doubles("/contact/coherence");
  const std::size_t per_frame = shape.at(1) * shape.at(2);
  for (std::size_t k = g.frame * per_frame; k < (g.frame + 1) * per_frame; ++k) {
    if (!(coherence[k] > 0.0)) continue;  // outside the contact
    if (coherence[k] >= min_coherence && std::isfinite(angle[k]))
      g.ridge_rad.push_back(angle[k]);
    else
      ++g.ridge_excluded;
  }
}

void read_principal(const H5Reader& h5, Group& g, double min_difference) {
  if (!h5.has("/strain/principal") || !h5.has("/mesh/status")) return;
  H5Shape shape;
  const auto principal = h5.read_doubles("/strain/principal", &shape);
  const auto status = h5.read_integers("/mesh/status");
  const std::size_t triangles = shape.at(1);
  for (std::size_t t = 0; t < triangles; ++t) {
    const std::size_t k = g.frame * triangles + t;
    if (status[k] != 0) continue;
    const double e1 = principal[3 * k], e2 = principal[3 * k + 1], angle = principal[3 * k + 2];
    if (std::isfinite(angle) && e1 - e2 >= min_difference)
      g.principal_rad.push_back(angle);
    else
      ++g.principal_excluded;
  }
}

std::vector<Group> read_groups(const OrientationOptions& o) {
  std::vector<Group> groups;
  for (const std::string& input : o.inputs) {
    const H5Reader h5(result_file(input));
    const std::size_t frames = h5.read_doubles("/frames/t_s").size();
    for (const std::string& instant : o.instants) {
      Group g;
      g.frame = instant_frame(h5, instant, frames);
      g.label = trial_label(input) + "@" + instant +
                (instant == std::to_string(g.frame) ? "" : " (frame " + std::to_string(g.frame) + ")");
      read_ridges(h5, g, o.min_coherence);
      read_principal(h5, g, o.min_principal_difference);
      groups.push_back(std::move(g));
    }
  }
  return groups;
}

json summary_json(const std::vector<double>& angles, std::size_t excluded) {
  json j = {{"count", angles.size()}, {"excluded", excluded}};
  if (angles.empty()) return j;
  const AxialSummary s = axial_summary(angles);
  j["mean_direction_deg"] = s.mean_direction_rad * 180.0 / std::numbers::pi;
  j["resultant_length"] = s.resultant_length;
  j["circular_variance"] = s.circular_variance;
  j["kurtosis"] = s.kurtosis;
  return j;
}

// Kuiper's test between every two groups that have directions of this kind.
json kuiper_json(const std::vector<Group>& groups, std::vector<double> Group::*angles) {
  json tests = json::array();
  for (std::size_t a = 0; a < groups.size(); ++a)
    for (std::size_t b = a + 1; b < groups.size(); ++b) {
      if ((groups[a].*angles).empty() || (groups[b].*angles).empty()) continue;
      const auto k = kuiper_two_sample_axial(groups[a].*angles, groups[b].*angles);
      tests.push_back({{"a", groups[a].label},
                       {"b", groups[b].label},
                       {"kuiper_V", k.statistic},
                       {"p_value", k.p_value},
                       {"count_a", k.count_a},
                       {"count_b", k.count_b}});
    }
  return tests;
}

void write_rose(const std::string& path, const std::vector<Group>& groups, std::vector<double> Group::*angles,
                std::size_t bins, const std::string& title) {
  std::vector<RoseGroup> roses;
  for (const auto& g : groups) {
    if ((g.*angles).empty()) continue;
    roses.push_back({g.label + " (n = " + std::to_string((g.*angles).size()) + ")",
                     axial_histogram(g.*angles, bins), axial_summary(g.*angles).mean_direction_rad});
  }
  if (!roses.empty()) write_rose_png(path, roses, {.title = title});
}

void run(const OrientationOptions& o) {
  if (o.bins < 2 || o.bins > 180) throw Error("must lie between 2 and 180", {.key = "--bins"});
  const auto groups = read_groups(o);
  json out = {{"conventions",
               {{"angles", "axial, degrees from +x towards +y in the image, in [0, 180)"},
                {"statistics",
                 "of the doubled angles (Fisher 1993); Kuiper's two-sample test with Stephens' "
                 "asymptotic p-value"},
                {"min_coherence", o.min_coherence},
                {"min_principal_difference", o.min_principal_difference}}},
              {"groups", json::array()}};
  for (const auto& g : groups)
    out["groups"].push_back({{"label", g.label},
                             {"frame", g.frame},
                             {"ridge", summary_json(g.ridge_rad, g.ridge_excluded)},
                             {"principal", summary_json(g.principal_rad, g.principal_excluded)}});
  out["kuiper"] = {{"ridge", kuiper_json(groups, &Group::ridge_rad)},
                   {"principal", kuiper_json(groups, &Group::principal_rad)}};
  check_replaceable_output(o.out, {"orientation_stats.json", "rose_ridge.png", "rose_principal.png"},
                           "orientation-stats");
  StagingDirectory staging(o.out);
  const fs::path dir(staging.path());
  write_text_file((dir / "orientation_stats.json").string(), out.dump(2) + "\n");
  write_rose((dir / "rose_ridge.png").string(), groups, &Group::ridge_rad, o.bins, "ridge orientation");
  write_rose((dir / "rose_principal.png").string(), groups, &Group::principal_rad, o.bins,
             "principal strain direction (e1)");
  staging.commit();
  std::cerr << "orientation statistics of " << groups.size() << " groups -> " << o.out << "\n";
}

}  // namespace

void add_orientation_command(CLI::App& app) {
  auto o = std::make_shared<OrientationOptions>();
  CLI::App* sub = app.add_subcommand(
      "orientation-stats", "Circular statistics of ridge and principal strain directions; Kuiper tests");
  sub->footer(
      "A group is one trial at one instant (--at onset, t90, full_slip, last or a frame number; the events "
      "need "
      "force channels). Per group and per kind of direction: count, mean direction, resultant length, "
      "circular variance and Fisher's circular kurtosis of the doubled (axial) angles; Kuiper's two-sample "
      "test between every two groups. Ridge directions: the contact stage's blocks inside the contact with "
      "coherence >= --min-coherence; principal directions: the used triangles' e1 axes where e1 - e2 >= "
      "--min-principal-difference (a nearly isotropic strain has no axis). Writes "
      "DIR/orientation_stats.json, "
      "DIR/rose_ridge.png and DIR/rose_principal.png (rose diagrams, groups overlaid).\n"
      "Example: tirstrain orientation-stats trialA trialB --at onset t90 --out orient");
  sub->add_option("RESULT", o->inputs, "result.h5 files or process output folders")->required();
  sub->add_option("--at", o->instants, "instants: onset, t90, full_slip, last or frame numbers")->required();
  sub->add_option("--out", o->out, "output folder")->required();
  sub->add_option("--bins", o->bins, "sectors of [0, 180) deg in the rose diagrams")->capture_default_str();
  sub->add_option("--min-coherence", o->min_coherence, "ridge blocks below this coherence are left out")
      ->capture_default_str();
  sub->add_option("--min-principal-difference", o->min_principal_difference,
                  "triangles with e1 - e2 below this are left out")
      ->capture_default_str();
  sub->callback([o] { run(*o); });
}

}  // namespace tirstrain::cli
