// `tirstrain model cattaneo-mindlin`: the analytic Hertz + Cattaneo–Mindlin surface field on a grid (HDF5 +
// heat maps + summary) or at given points (CSV), for validating measurements against theory.
#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>
#include <map>
#include <numbers>
#include <opencv2/core.hpp>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/heatmap.hpp"
#include "core/version.hpp"
#include "model/cattaneo_mindlin.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/model_verbs.hpp"

namespace tirstrain::cli {
namespace {

struct ModelOptions {
  model::CattaneoMindlinParams params;
  double direction_deg = 0.0;
  int grid = 0;
  double extent_a = 1.5;
  std::string points_csv;
  std::string out;
};

// The model names its parameters by field; the user typed options.
std::string option_of(const std::string& parameter) {
  static const std::map<std::string, std::string> options = {
      {"normal_N", "--normal-N"},          {"tangential_N", "--tangential-N"}, {"radius_m", "--radius-m"},
      {"young_Pa", "--young-Pa"},          {"poisson", "--poisson"},           {"friction", "--friction"},
      {"direction_rad", "--direction-deg"}};
  const auto it = options.find(parameter);
  return it == options.end() ? parameter : it->second;
}

model::CattaneoMindlin build_model(const ModelOptions& options) {
  model::CattaneoMindlinParams params = options.params;
  params.direction_rad = options.direction_deg * std::numbers::pi / 180.0;
  try {
    return model::CattaneoMindlin(params);
  } catch (const model::InvalidParameter& e) {
    throw Error(e.what(), {.key = option_of(e.parameter())});
  }
}

void check_finite(const model::FieldSample& s, double x_m, double y_m) {
  const double values[] = {s.displacement_m.x, s.displacement_m.y,   s.gradient.xx, s.gradient.xy,
                           s.gradient.yx,      s.gradient.yy,        s.strain.xx,   s.strain.yy,
                           s.strain.xy,        s.energy_density_J_m3};
  for (double v : values)
    if (!std::isfinite(v))
      throw Error("model produced a non-finite value at x_m=" + format_double(x_m) +
                  ", y_m=" + format_double(y_m) + " (please report this as a bug)");
}

void run_points(const ModelOptions& options, const model::CattaneoMindlin& cm) {
  if (path_is_within(options.out, options.points_csv))
    throw Error("is the points file being read: write the values to another file",
                {.file = options.out, .key = "--out"});
  const CsvTable table = read_numeric_csv(options.points_csv);
  const auto& xs = table.column("x_m");
  const auto& ys = table.column("y_m");
  CsvWriter out(options.out, {"x_m", "y_m", "ux_m", "uy_m", "Hxx", "Hxy", "Hyx", "Hyy", "Exx", "Eyy", "Exy",
                              "energy_J_m3"});
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const model::FieldSample s = cm.evaluate(xs[i], ys[i]);
    check_finite(s, xs[i], ys[i]);
    out.row({xs[i], ys[i], s.displacement_m.x, s.displacement_m.y, s.gradient.xx, s.gradient.xy,
             s.gradient.yx, s.gradient.yy, s.strain.xx, s.strain.yy, s.strain.xy, s.energy_density_J_m3});
  }
  out.commit();
  std::cout << "wrote " << xs.size() << " points to " << options.out << '\n';
}

// The field sampled on an n × n grid over ±half (m), with its peaks.
struct ModelGrid {
  std::size_t n = 0;
  double half_m = 0.0;
  std::vector<double> axis;  // x and y of the grid's columns and rows, m
  std::vector<double> displacement, gradient, strain, principal, energy;
  cv::Mat exx, eyy, exy, w;  // the pictures' values
  double peak_abs[3] = {0, 0, 0};
  double e1_max = -INFINITY, e2_min = INFINITY, energy_max = 0.0;
};

void store_sample(ModelGrid& g, std::size_t r, std::size_t c, const model::FieldSample& s) {
  const std::size_t k = r * g.n + c;
  g.displacement[2 * k] = s.displacement_m.x, g.displacement[2 * k + 1] = s.displacement_m.y;
  g.gradient[4 * k] = s.gradient.xx, g.gradient[4 * k + 1] = s.gradient.xy;
  g.gradient[4 * k + 2] = s.gradient.yx, g.gradient[4 * k + 3] = s.gradient.yy;
  g.strain[3 * k] = s.strain.xx, g.strain[3 * k + 1] = s.strain.yy, g.strain[3 * k + 2] = s.strain.xy;
  g.principal[3 * k] = s.principal.e1, g.principal[3 * k + 1] = s.principal.e2,
                  g.principal[3 * k + 2] = s.principal.angle_rad;
  g.energy[k] = s.energy_density_J_m3;
  const int ri = static_cast<int>(r), ci = static_cast<int>(c);
  g.exx.at<double>(ri, ci) = s.strain.xx;
  g.eyy.at<double>(ri, ci) = s.strain.yy;
  g.exy.at<double>(ri, ci) = s.strain.xy;
  g.w.at<double>(ri, ci) = s.energy_density_J_m3;
  g.peak_abs[0] = std::max(g.peak_abs[0], std::abs(s.strain.xx));
  g.peak_abs[1] = std::max(g.peak_abs[1], std::abs(s.strain.yy));
  g.peak_abs[2] = std::max(g.peak_abs[2], std::abs(s.strain.xy));
  g.e1_max = std::max(g.e1_max, s.principal.e1);
  g.e2_min = std::min(g.e2_min, s.principal.e2);
  g.energy_max = std::max(g.energy_max, s.energy_density_J_m3);
}

ModelGrid sample_grid(const ModelOptions& options, const model::CattaneoMindlin& cm) {
  ModelGrid g;
  g.n = static_cast<std::size_t>(options.grid);
  const std::size_t n = g.n;
  g.half_m = options.extent_a * cm.hertz().contact_radius_m;
  g.axis.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    g.axis[i] = n == 1 ? 0.0 : -g.half_m + 2.0 * g.half_m * static_cast<double>(i) / (n - 1);
  g.displacement.resize(n * n * 2);
  g.gradient.resize(n * n * 4);
  g.strain.resize(n * n * 3);
  g.principal.resize(n * n * 3);
  g.energy.resize(n * n);
  g.exx = cv::Mat(static_cast<int>(n), static_cast<int>(n), CV_64F);
  g.eyy = g.exx.clone();
  g.exy = g.exx.clone();
  g.w = g.exx.clone();
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c) {
      const double x = g.axis[c], y = g.axis[r];
      const model::FieldSample s = cm.evaluate(x, y);
      check_finite(s, x, y);
      store_sample(g, r, c, s);
    }
  return g;
}

void write_model_h5(const std::string& path, const ModelGrid& g, const model::CattaneoMindlin& cm) {
  const std::size_t n = g.n;
  H5Writer h5(path);
  h5.write("/grid/x_m", std::span<const double>(g.axis), {n});
  h5.write("/grid/y_m", std::span<const double>(g.axis), {n});
  h5.write("/displacement_m", std::span<const double>(g.displacement), {n, n, 2});
  h5.write("/gradient", std::span<const double>(g.gradient), {n, n, 4});
  h5.write("/strain", std::span<const double>(g.strain), {n, n, 3});
  h5.write("/principal", std::span<const double>(g.principal), {n, n, 3});
  h5.write("/energy_density_J_m3", std::span<const double>(g.energy), {n, n});
  const auto& p = cm.params();
  h5.attribute("/", "software", std::string("tirstrain ") + kVersion);
  h5.attribute("/", "model", "Hertz + Cattaneo-Mindlin partial slip, sphere on rigid flat");
  h5.attribute("/", "normal_N", p.normal_N);
  h5.attribute("/", "tangential_N", p.tangential_N);
  h5.attribute("/", "radius_m", p.radius_m);
  h5.attribute("/", "young_Pa", p.young_Pa);
  h5.attribute("/", "poisson", p.poisson);
  h5.attribute("/", "friction", p.friction);
  h5.attribute("/", "direction_rad", p.direction_rad);
  h5.attribute("/", "hertz_radial", p.hertz_radial ? 1.0 : 0.0);
  h5.attribute("/", "contact_radius_m", cm.hertz().contact_radius_m);
  h5.attribute("/", "stick_radius_m", cm.stick_radius_m());
  h5.attribute("/", "rigid_shift_m", cm.rigid_shift_m());
  h5.attribute("/gradient", "components", "Hxx, Hxy, Hyx, Hyy (H_ij = du_i/dx_j)");
  h5.attribute("/strain", "components", "Exx, Eyy, Exy (Green-Lagrange, tensor shear)");
  h5.attribute("/principal", "components", "e1, e2, angle_rad (e1 >= e2, angle of e1 from +x)");
  h5.attribute("/displacement_m", "layout", "[row = y index, column = x index, (ux, uy)]");
  h5.commit();
}

void write_model_pictures(const std::string& dir, const ModelGrid& g, const model::CattaneoMindlin& cm) {
  HeatmapOptions map;
  map.x_min = map.y_min = -g.half_m * 1e3;
  map.x_max = map.y_max = g.half_m * 1e3;
  map.axis_unit = "mm";
  map.circles = {{0.0, 0.0, cm.hertz().contact_radius_m * 1e3, "a"}};
  if (cm.stick_radius_m() > 0) map.circles.push_back({0.0, 0.0, cm.stick_radius_m() * 1e3, "c"});
  const struct {
    const cv::Mat* values;
    const char* file;
    const char* title;
    const char* unit;
    bool diverging;
  } maps[] = {{&g.exx, "strain_Exx.png", "Green-Lagrange E_xx", "strain", true},
              {&g.eyy, "strain_Eyy.png", "Green-Lagrange E_yy", "strain", true},
              {&g.exy, "strain_Exy.png", "Green-Lagrange E_xy", "strain", true},
              {&g.w, "energy_density.png", "Plane-strain energy density", "J/m^3", false}};
  for (const auto& m : maps) {
    map.title = m.title;
    map.unit = m.unit;
    map.diverging = m.diverging;
    write_heatmap_png(dir + "/" + m.file, *m.values, map);
  }
}

void write_model_summary(const std::string& path, const ModelGrid& g, const ModelOptions& options,
                         const model::CattaneoMindlin& cm) {
  const auto& p = cm.params();
  nlohmann::ordered_json summary;
  summary["software"] = std::string("tirstrain ") + kVersion;
  summary["inputs"] = {{"normal_N", p.normal_N},
                       {"tangential_N", p.tangential_N},
                       {"radius_m", p.radius_m},
                       {"young_Pa", p.young_Pa},
                       {"poisson", p.poisson},
                       {"friction", p.friction},
                       {"direction_deg", options.direction_deg},
                       {"hertz_radial", p.hertz_radial}};
  summary["contact_radius_m"] = cm.hertz().contact_radius_m;
  summary["peak_pressure_Pa"] = cm.hertz().peak_pressure_Pa;
  summary["approach_m"] = cm.hertz().approach_m;
  summary["stick_radius_m"] = cm.stick_radius_m();
  summary["rigid_shift_m"] = cm.rigid_shift_m();
  summary["grid"] = {{"points_per_side", g.n}, {"half_extent_m", g.half_m}};
  summary["peak_abs_strain"] = {{"Exx", g.peak_abs[0]}, {"Eyy", g.peak_abs[1]}, {"Exy", g.peak_abs[2]}};
  summary["max_e1"] = g.e1_max;
  summary["min_e2"] = g.e2_min;
  summary["max_energy_density_J_m3"] = g.energy_max;
  write_text_file(path, summary.dump(2) + "\n");
}

void run_grid(const ModelOptions& options, const model::CattaneoMindlin& cm) {
  // Built in "<out>.partial" and swapped in whole: a failed run leaves the earlier output as it was.
  check_replaceable_output(options.out,
                           {"model.h5", "strain_Exx.png", "strain_Eyy.png", "strain_Exy.png",
                            "energy_density.png", "summary.json"},
                           "model");
  StagingDirectory staging(options.out);
  const std::string& dir = staging.path();
  const ModelGrid grid = sample_grid(options, cm);
  write_model_h5(dir + "/model.h5", grid, cm);
  write_model_pictures(dir, grid, cm);
  write_model_summary(dir + "/summary.json", grid, options, cm);
  staging.commit();
  std::cout << "contact radius a = " << cm.hertz().contact_radius_m * 1e3
            << " mm, stick radius c = " << cm.stick_radius_m() * 1e3
            << " mm, rigid shift = " << cm.rigid_shift_m() * 1e6 << " um\n"
            << "wrote model.h5, strain_Exx.png, strain_Eyy.png, strain_Exy.png, energy_density.png and "
            << "summary.json in " << options.out << '\n';
}

}  // namespace

void add_model_command(CLI::App& app) {
  CLI::App* model = app.add_subcommand(
      "model", "Analytic models: Hertz + Cattaneo-Mindlin contact, fingerprint-texture interaction");
  model->require_subcommand(1);
  auto options = std::make_shared<ModelOptions>();
  CLI::App* cm = model->add_subcommand(
      "cattaneo-mindlin",
      "Hertz + Cattaneo-Mindlin partial slip of an elastic sphere on a rigid flat: surface displacement,\n"
      "displacement gradient, Green-Lagrange strain and plane-strain energy density.\n"
      "Either --grid N --out DIR (model.h5, heat maps, summary.json) or --points IN.csv --out OUT.csv.");
  cm->footer(
      "Example:\n"
      "  tirstrain model cattaneo-mindlin --normal-N 2 --tangential-N 1 --radius-m 0.01 --young-Pa 1e6 "
      "--poisson 0.4 --friction 1 --grid 201 --out cm");
  cm->add_option("--normal-N", options->params.normal_N, "Normal load P (N), > 0")->required();
  cm->add_option("--tangential-N", options->params.tangential_N,
                 "Tangential load Q (N), 0 <= Q <= friction*P")
      ->required();
  cm->add_option("--radius-m", options->params.radius_m, "Sphere (fingertip) radius R (m), > 0")->required();
  cm->add_option("--young-Pa", options->params.young_Pa, "Young's modulus E (Pa), > 0")->required();
  cm->add_option("--poisson", options->params.poisson, "Poisson's ratio, -1 < nu < 0.5")->required();
  cm->add_option("--friction", options->params.friction, "Friction coefficient mu, > 0")->required();
  cm->add_option(
        "--direction-deg", options->direction_deg,
        "Direction of the tangential traction on the skin, degrees from +x towards +y (image y down)")
      ->capture_default_str();
  cm->add_flag(
      "--hertz-radial", options->params.hertz_radial,
      "Include the radial displacement from the Hertz pressure (reference image before normal loading)");
  CLI::Option* grid = cm->add_option("--grid", options->grid, "Grid points per side for the maps (>= 2)")
                          ->check(CLI::Range(2, 4001));
  cm->add_option("--extent-a", options->extent_a, "Grid half-width in units of the contact radius a")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 100.0));
  CLI::Option* points = cm->add_option("--points", options->points_csv, "CSV of points with columns x_m,y_m");
  cm->add_option("--out", options->out, "Output directory (with --grid) or CSV file (with --points)")
      ->required();
  grid->excludes(points);
  add_model_texture_interaction_verb(*model);
  cm->callback([options, grid, points] {
    if (!*grid && !*points) throw Error("give either --grid N (maps) or --points IN.csv", {.key = "--grid"});
    const model::CattaneoMindlin field = build_model(*options);
    if (*points)
      run_points(*options, field);
    else
      run_grid(*options, field);
  });
}

}  // namespace tirstrain::cli
