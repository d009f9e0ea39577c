// `tirstrain average RESULT.h5... --out DIR`: strain maps averaged across trials on the standard ellipse, as
// the seed paper averages repetitions and subjects.
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/heatmap.hpp"
#include "strain/normalised_map.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {
namespace {

namespace fs = std::filesystem;

struct Selection {
  std::string how = "max-energy";  // last | max-energy | frame | time
  long frame = -1;
  double time_s = 0.0;
};

// The frame of a result to average.
std::size_t pick_frame(const H5Reader& h5, const Selection& selection) {
  const std::vector<double> t_s = h5.read_doubles("/frames/t_s");
  if (t_s.empty()) throw Error("the result has no frames", {.file = h5.path()});
  if (selection.how == "last") return t_s.size() - 1;
  if (selection.how == "frame") {
    if (selection.frame < 0 || static_cast<std::size_t>(selection.frame) >= t_s.size())
      throw Error("--frame " + std::to_string(selection.frame) + " is outside the result's " +
                      std::to_string(t_s.size()) + " frames",
                  {.file = h5.path()});
    return static_cast<std::size_t>(selection.frame);
  }
  if (selection.how == "time") {
    std::size_t best = 0;
    for (std::size_t i = 1; i < t_s.size(); ++i)
      if (std::abs(t_s[i] - selection.time_s) < std::abs(t_s[best] - selection.time_s)) best = i;
    // Nearest, but within the recording: half a frame interval beyond its ends at most.
    const double half_interval_s =
        t_s.size() > 1 ? 0.5 * (t_s.back() - t_s.front()) / static_cast<double>(t_s.size() - 1) : 0.0;
    if (selection.time_s < t_s.front() - half_interval_s || selection.time_s > t_s.back() + half_interval_s)
      throw Error("--time-s " + format_double(selection.time_s) + " lies outside the result's frames (" +
                      format_double(t_s.front()) + " to " + format_double(t_s.back()) + " s)",
                  {.file = h5.path()});
    return best;
  }
  if (!h5.has("/energy/total_J"))
    throw Error(
        "no /energy/total_J to find the frame of largest strain energy (processed without the strain "
        "stage?)",
        {.file = h5.path()});
  const std::vector<double> energy = h5.read_doubles("/energy/total_J");
  std::size_t best = 0;
  double best_energy = -1.0;
  for (std::size_t i = 0; i < energy.size(); ++i)
    if (std::isfinite(energy[i]) && energy[i] > best_energy) {
      best_energy = energy[i];
      best = i;
    }
  if (best_energy < 0.0) throw Error("the result has no finite strain energy", {.file = h5.path()});
  return best;
}

// One frame's map of `name` ([N, G, G, C]) as C matrices G x G.
std::vector<cv::Mat> frame_maps(const H5Reader& h5, const std::string& name, std::size_t frame,
                                std::size_t* cells) {
  if (!h5.has(name))
    throw Error("no " + name + " (processed without the strain stage?)", {.file = h5.path()});
  H5Shape shape;  // the row's: [G, G, C] or [G, G]
  const std::vector<double> row = h5.read_row_doubles(name, frame, &shape);
  const std::size_t g = shape[0], c = shape.size() > 2 ? shape[2] : 1;
  if (*cells != 0 && g != *cells)
    throw Error("map grid " + std::to_string(g) + " differs from the first result's " +
                    std::to_string(*cells) + " (strain.map_cells must be equal)",
                {.file = h5.path()});
  *cells = g;
  std::vector<cv::Mat> out;
  for (std::size_t k = 0; k < c; ++k) {
    cv::Mat m(static_cast<int>(g), static_cast<int>(g), CV_64F);
    for (std::size_t r = 0; r < g; ++r)
      for (std::size_t col = 0; col < g; ++col)
        m.at<double>(static_cast<int>(r), static_cast<int>(col)) = row[(r * g + col) * c + k];
    out.push_back(m);
  }
  return out;
}

// The maps of every trial at its chosen frame, component by component, and which frame each gave.
struct TrialMaps {
  std::size_t cells = 0;
  std::vector<cv::Mat> exx, eyy, exy, e1, e2, energy;
  std::string used;     // "file@frame;..."
  bool turned = false;  // some trial's map axes are its contact's, not the image's
};

// The result.h5 of each input (a result file or a process output folder), each once.
std::vector<std::string> result_files(const std::vector<std::string>& inputs) {
  std::vector<std::string> files;
  for (const std::string& input : inputs) {
    const std::string file = fs::is_directory(input) ? (fs::path(input) / "result.h5").string() : input;
    if (!fs::exists(file)) throw Error("no such result", {.file = file});
    for (const std::string& earlier : files)
      if (fs::equivalent(earlier, file))
        throw Error("is given twice: each trial counts once in the average", {.file = input});
    files.push_back(file);
  }
  return files;
}

// The output goes beside the results, never into one: `process` replaces its folder as a whole and refuses
// a folder holding files it does not write.
void check_out_beside(const std::string& out, const std::vector<std::string>& result_files) {
  for (const std::string& file : result_files) {
    const fs::path folder = fs::path(file).parent_path().empty() ? "." : fs::path(file).parent_path();
    if (path_is_within(out, folder.string()))
      throw Error("lies inside the result folder " + folder.string() + ": write the average beside it",
                  {.file = out, .key = "--out"});
  }
}

// The map's +x in its trial's image (radians): written by process, else read off the forward similarity.
double map_axes_angle_rad(const H5Reader& h5) {
  if (h5.has_attribute("/maps", "axes_angle_rad")) return h5.attribute_number("/maps", "axes_angle_rad");
  if (!h5.has_attribute("/maps", "to_normalised")) return 0.0;
  double a = 1.0, b = 0.0;
  char comma = 0;
  std::istringstream in(h5.attribute_text("/maps", "to_normalised"));
  return (in >> a >> comma >> b) ? std::atan2(b, a) : 0.0;
}

// Maps average cell by cell in their own axes: trials whose axes lie differently on the finger (a round
// contact keeps the image's, an elongated one takes its major axis) mix directions, which is said.
void warn_if_axes_differ(const std::vector<std::string>& inputs, const std::vector<double>& angles_rad) {
  constexpr double kDegree = std::numbers::pi / 180.0;
  for (std::size_t i = 1; i < angles_rad.size(); ++i) {
    double d = std::fmod(std::abs(angles_rad[i] - angles_rad[0]), std::numbers::pi);
    d = std::min(d, std::numbers::pi - d);
    if (d > 30.0 * kDegree)
      std::cerr << "warning: the maps' axes differ by " << std::lround(d / kDegree) << " degrees between "
                << inputs[0] << " (x at " << std::lround(angles_rad[0] / kDegree)
                << " degrees in its image) and " << inputs[i] << " (" << std::lround(angles_rad[i] / kDegree)
                << " degrees): E_xx, E_yy and E_xy of the two mean different directions on the finger "
                   "(a contact within 5 % of a circle keeps the image's axes)\n";
  }
}

TrialMaps read_trial_maps(const std::vector<std::string>& inputs, const Selection& selection) {
  TrialMaps t;
  std::vector<double> angles_rad;
  for (const std::string& input : inputs) {
    const H5Reader h5(input);
    if (h5.has("/maps") && h5.attribute_number("/maps", "reference_has_ellipse") <= 0.0)
      throw Error("the reference frame had no contact ellipse, so the result has no normalised maps",
                  {.file = input});
    const std::size_t frame = pick_frame(h5, selection);
    const auto strain = frame_maps(h5, "/maps/strain_total", frame, &t.cells);
    const auto principal = frame_maps(h5, "/maps/principal", frame, &t.cells);
    const auto density = frame_maps(h5, "/maps/energy_density_J_m3", frame, &t.cells);
    t.exx.push_back(strain[0]);
    t.eyy.push_back(strain[1]);
    t.exy.push_back(strain[2]);
    t.e1.push_back(principal[0]);
    t.e2.push_back(principal[1]);
    t.energy.push_back(density[0]);
    t.used += (t.used.empty() ? "" : ";") + input + "@" + std::to_string(frame);
    angles_rad.push_back(map_axes_angle_rad(h5));
    t.turned = t.turned || angles_rad.back() != 0.0;
  }
  warn_if_axes_differ(inputs, angles_rad);
  return t;
}

// Cell-by-cell means over the trials that cover each cell.
struct MeanMaps {
  cv::Mat exx, eyy, exy, e1, e2, energy, count;
};

MeanMaps mean_maps(const TrialMaps& t) {
  MeanMaps m;
  m.exx = strain::nan_mean(t.exx, &m.count);
  m.eyy = strain::nan_mean(t.eyy);
  m.exy = strain::nan_mean(t.exy);
  m.e1 = strain::nan_mean(t.e1);
  m.e2 = strain::nan_mean(t.e2);
  m.energy = strain::nan_mean(t.energy);
  return m;
}

void write_average_h5(const fs::path& path, const MeanMaps& m, std::size_t g, const std::string& used,
                      const std::string& selection) {
  std::vector<double> total(g * g * 3), principal(g * g * 2), density(g * g), counts(g * g);
  for (std::size_t r = 0; r < g; ++r)
    for (std::size_t c = 0; c < g; ++c) {
      const int ri = static_cast<int>(r), ci = static_cast<int>(c);
      const std::size_t k = r * g + c;
      total[3 * k] = m.exx.at<double>(ri, ci);
      total[3 * k + 1] = m.eyy.at<double>(ri, ci);
      total[3 * k + 2] = m.exy.at<double>(ri, ci);
      principal[2 * k] = m.e1.at<double>(ri, ci);
      principal[2 * k + 1] = m.e2.at<double>(ri, ci);
      density[k] = m.energy.at<double>(ri, ci);
      counts[k] = m.count.at<double>(ri, ci);
    }
  H5Writer h5(path.string());
  h5.write("/maps/strain_total", std::span<const double>(total), {g, g, 3});
  h5.write("/maps/principal", std::span<const double>(principal), {g, g, 2});
  h5.write("/maps/energy_density_J_m3", std::span<const double>(density), {g, g});
  h5.write("/maps/count", std::span<const double>(counts), {g, g});
  h5.attribute("/maps", "inputs_and_frames", used);
  h5.attribute("/maps", "selection", selection);
  h5.attribute("/maps", "cells", static_cast<double>(g));
  h5.commit();
}

// Strain maps on a scale robust to the few border cells that a single trial covers (98th percentile).
void write_average_pictures(const fs::path& out, const MeanMaps& m, std::size_t trials, bool turned) {
  const auto png = [&](const std::string& name, const cv::Mat& values, const std::string& title,
                       bool diverging) {
    HeatmapOptions o;
    o.title = title;
    o.diverging = diverging;
    o.unit = diverging ? "strain (dimensionless)" : "trials";
    o.range_percentile = diverging ? 98.0 : 100.0;
    o.x_min = o.y_min = -1.0;
    o.x_max = o.y_max = 1.0;
    o.axis_unit = "normalised";
    if (turned) o.axes = "x along each contact's major axis, y 90 deg clockwise";
    write_heatmap_png((out / name).string(), values, o);
  };
  const std::string n = std::to_string(trials);
  png("average_E_xx.png", m.exx, "E_xx, mean of " + n + " trials", true);
  png("average_E_yy.png", m.eyy, "E_yy, mean of " + n + " trials", true);
  png("average_E_xy.png", m.exy, "E_xy, mean of " + n + " trials", true);
  png("average_count.png", m.count, "trials covering each cell", false);
}

}  // namespace

void add_average_command(CLI::App& app) {
  struct Args {
    std::vector<std::string> inputs;
    std::string out, at = "max-energy";
    long frame = -1;
    double time_s = 0.0;
  };
  auto args = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand("average", "Average strain maps across trials on the standard ellipse");
  sub->footer(
      "Each RESULT.h5 (from tirstrain process with the strain stage) contributes one frame's maps on the "
      "standard\n"
      "ellipse of its reference contact (docs/formats.md, /maps): by default the frame of largest total "
      "strain\n"
      "energy; --at last, --frame N or --time-s T instead. Cells are averaged over the trials that cover "
      "them.\n"
      "Writes DIR/average.h5 (/maps/strain_total [G,G,3], /maps/principal [G,G,2], "
      "/maps/energy_density_J_m3\n"
      "[G,G], /maps/count [G,G] trials per cell; attributes: inputs and frames used) and "
      "DIR/average_E_xx.png,\n"
      "average_E_yy.png, average_E_xy.png, average_count.png.\n"
      "Example:\n"
      "  tirstrain average trial1/result.h5 trial2/result.h5 trial3/result.h5 --out avg");
  sub->add_option("RESULT", args->inputs, "result.h5 files (or process output folders)")->required();
  sub->add_option("--out", args->out, "Output folder")->required();
  sub->add_option("--at", args->at, "Which frame of each trial: max-energy (default), last")
      ->check(CLI::IsMember({"max-energy", "last"}));
  sub->add_option("--frame", args->frame, "Use this frame index of every trial");
  sub->add_option("--time-s", args->time_s, "Use the frame nearest this time (s) in every trial");
  sub->callback([args, sub] {
    Selection selection;
    selection.how = args->at;
    if (sub->count("--frame") > 0) {
      selection.how = "frame";
      selection.frame = args->frame;
    }
    if (sub->count("--time-s") > 0) {
      if (selection.how == "frame") throw Error("give --frame or --time-s, not both", {.key = "--time-s"});
      selection.how = "time";
      selection.time_s = args->time_s;
    }
    if (sub->count("--at") > 0 && selection.how != args->at)
      throw Error("give one of --at, --frame and --time-s", {.key = "--at"});
    const std::vector<std::string> files = result_files(args->inputs);
    check_out_beside(args->out, files);
    const TrialMaps trials = read_trial_maps(files, selection);
    // Built in "<out>.partial" and swapped in whole: a failed run leaves the earlier output as it was.
    check_replaceable_output(
        args->out,
        {"average.h5", "average_E_xx.png", "average_E_yy.png", "average_E_xy.png", "average_count.png"},
        "average");
    StagingDirectory staging(args->out);
    const MeanMaps means = mean_maps(trials);
    write_average_h5(fs::path(staging.path()) / "average.h5", means, trials.cells, trials.used,
                     selection.how);
    write_average_pictures(staging.path(), means, args->inputs.size(), trials.turned);
    staging.commit();
    std::cerr << "averaged " << args->inputs.size() << " trials (" << trials.cells << "x" << trials.cells
              << " cells) -> " << (fs::path(args->out) / "average.h5").string() << "\n";
  });
}

}  // namespace tirstrain::cli
