#include "pipeline/validate.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <numbers>
#include <span>
#include <sstream>

#include "contact/ellipse.hpp"
#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/heatmap.hpp"
#include "core/tensor2.hpp"
#include "pipeline/contact_observability.hpp"
#include "pipeline/error_accumulator.hpp"
#include "pipeline/process.hpp"
#include "pipeline/validate_rings.hpp"
#include "samples/synth.hpp"
#include "samples/trial.hpp"
#include "strain/deformation.hpp"
#include "strain/stick_zone.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using Accumulator = ErrorAccumulator;

// The six strain quantities compared per triangle.
constexpr const char* kComponents[] = {"E_xx", "E_yy", "E_xy", "e1", "e2", "energy_density"};
constexpr int kComponentCount = 6;

std::array<double, kComponentCount> components(const Strain2& e, double young_Pa, double poisson) {
  const Principal2 p = principal_strains(e);
  return {e.xx, e.yy, e.xy, p.e1, p.e2, plane_strain_energy_density_J_m3(e, young_Pa, poisson)};
}

// Reads a dataset and checks its leading dimensions.
std::vector<double> read(const H5Reader& h5, const std::string& name, H5Shape* shape) {
  if (!h5.has(name))
    throw Error("the result has no " + name + " (was it processed with tracking and strain?)",
                {.file = h5.path()});
  return h5.read_doubles(name, shape);
}

cv::Matx23d parse_matrix(const std::string& text, const std::string& file) {
  cv::Matx23d m;
  std::istringstream in(text);
  char separator = 0;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      if (!(in >> m(r, c))) throw Error("malformed /maps to_normalised attribute", {.file = file});
      if (r * 3 + c < 5) in >> separator;
    }
  return m;
}

cv::Matx23d invert_similarity(const cv::Matx23d& m) {
  const cv::Matx22d a(m(0, 0), m(0, 1), m(1, 0), m(1, 1));
  const cv::Matx22d inv = a.inv();
  const cv::Vec2d t = -(inv * cv::Vec2d(m(0, 2), m(1, 2)));
  return {inv(0, 0), inv(0, 1), t[0], inv(1, 0), inv(1, 1), t[1]};
}

// The truth's contact: the generator's mask (the same in every frame: its contact does not move in the
// image) and the same direct ellipse fit the segmenter reports, applied to the mask's outline. Outline
// pixels' centres lie half a pixel inside the mask's edge, so the semi-axes get that half pixel back.
struct ContactTruth {
  cv::Mat mask;  // CV_8UC1, 255 inside
  std::optional<contact::Ellipse> ellipse;
  double area_px = 0.0;
};

ContactTruth contact_truth(const samples::Trial& trial) {
  ContactTruth truth;
  truth.mask = trial.contact_mask() * 255;
  truth.area_px = cv::countNonZero(truth.mask);
  truth.ellipse = truth_contact_ellipse(truth.mask);
  return truth;
}

struct ContactErrors {
  double iou = kNaN;             // hull polygon filled against the truth mask
  double centre_px = kNaN;       // ellipse centre distance
  double semi_major_pct = kNaN;  // signed, measured − truth
  double semi_minor_pct = kNaN;
  double area_pct = kNaN;
};

// One frame's contact against the truth; NaN for what the frame does not have (no contact, no ellipse).
ContactErrors contact_errors(const ContactTruth& truth, std::int64_t status, std::span<const double> hull_px,
                             std::span<const double> ellipse, double area_mm2, double px_per_mm) {
  ContactErrors e;
  if ((status & (contact::kNoContact | contact::kFrameSkipped)) != 0 || hull_px.empty()) return e;
  std::vector<cv::Point2d> hull;
  for (std::size_t p = 0; p + 1 < hull_px.size(); p += 2) hull.emplace_back(hull_px[p], hull_px[p + 1]);
  e.iou = contact::mask_iou(contact::rasterize_polygon(hull, truth.mask.size()), truth.mask);
  if (truth.area_px > 0.0) e.area_pct = 100.0 * (area_mm2 * px_per_mm * px_per_mm / truth.area_px - 1.0);
  if ((status & contact::kNoEllipse) == 0 && truth.ellipse && ellipse.size() == 5 && ellipse[2] > 0.0) {
    e.centre_px = std::hypot(ellipse[0] - truth.ellipse->cx_px, ellipse[1] - truth.ellipse->cy_px);
    e.semi_major_pct = 100.0 * (ellipse[2] / truth.ellipse->semi_major_px - 1.0);
    e.semi_minor_pct = 100.0 * (ellipse[3] / truth.ellipse->semi_minor_px - 1.0);
  }
  return e;
}

// Per live track at one frame: where the displacement errors are (for finding a tracking bias).
void write_tracks_csv(const fs::path& path, const samples::Trial& trial, std::size_t frame,
                      const std::vector<double>& reference, const std::vector<double>& position) {
  const samples::FrameField field = trial.field(static_cast<int>(frame));
  const std::size_t k = reference.size() / 2;
  CsvWriter csv(path.string(), {"frame", "track", "X_px", "Y_px", "border_distance_px", "u_px", "v_px",
                                "u_truth_px", "v_truth_px"});
  for (std::size_t j = 0; j < k; ++j) {
    const Vec2 x{position[2 * (frame * k + j)], position[2 * (frame * k + j) + 1]};
    if (!std::isfinite(x.x)) continue;
    const Vec2 X{reference[2 * j], reference[2 * j + 1]};
    const Vec2 u = field.displacement_px(X);
    csv.row_text({std::to_string(frame), std::to_string(j), format_double(X.x), format_double(X.y),
                  format_double(-trial.contact_signed_distance_px(X)), format_double(x.x - X.x),
                  format_double(x.y - X.y), format_double(u.x), format_double(u.y)});
  }
  csv.commit();
}

void write_rows_csv(const fs::path& path, const std::vector<ErrorStats>& rows) {
  CsvWriter csv(path.string(),
                {"quantity", "reference", "mode", "unit", "rms", "max_abs", "mean", "samples"});
  for (const ErrorStats& s : rows)
    csv.row_text({s.quantity, s.reference, s.mode, s.unit, format_double(s.rms), format_double(s.max_abs),
                  format_double(s.mean), std::to_string(s.samples)});
  csv.commit();
}

// The side-by-side maps (measured | truth | measured − truth) on the normalised grid at the map frame
// (default: the frame of largest true energy); returns the files written.
std::vector<std::string> write_side_by_side_maps(const ValidateOptions& options, const H5Reader& h5,
                                                 const std::string& result_path, const samples::Trial& trial,
                                                 const std::string& mode, const fs::path& out, std::size_t n,
                                                 std::size_t u_argmax) {
  std::vector<std::string> outputs;
  if (!(options.write_maps && h5.has("/maps/strain_total") &&
        h5.attribute_number("/maps", "reference_has_ellipse") > 0))
    return outputs;
  H5Shape shape;
  const std::size_t frame =
      options.map_frame >= 0 ? std::min(static_cast<std::size_t>(options.map_frame), n - 1) : u_argmax;
  const std::vector<double> maps = h5.read_doubles("/maps/strain_total", &shape);
  const std::size_t g = shape[1];
  const cv::Matx23d to_reference =
      invert_similarity(parse_matrix(h5.attribute_text("/maps", "to_normalised"), result_path));
  const samples::FrameField field = trial.field(static_cast<int>(frame));
  cv::Mat measured[3], truth[3];
  for (int c = 0; c < 3; ++c) {
    measured[c] = cv::Mat(static_cast<int>(g), static_cast<int>(g), CV_64F, cv::Scalar(kNaN));
    truth[c] = measured[c].clone();
  }
  for (std::size_t r = 0; r < g; ++r)
    for (std::size_t col = 0; col < g; ++col) {
      const double qx = -1.0 + 2.0 * static_cast<double>(col) / static_cast<double>(g - 1);
      const double qy = -1.0 + 2.0 * static_cast<double>(r) / static_cast<double>(g - 1);
      const Vec2 X{to_reference(0, 0) * qx + to_reference(0, 1) * qy + to_reference(0, 2),
                   to_reference(1, 0) * qx + to_reference(1, 1) * qy + to_reference(1, 2)};
      const std::size_t base = ((frame * g + r) * g + col) * 3;
      const bool inside = trial.contact_signed_distance_px(X) < 0.0;
      const Strain2 e = inside ? green_lagrange(field.evaluate(X).gradient) : Strain2{kNaN, kNaN, kNaN};
      const double truth_values[3] = {e.xx, e.yy, e.xy};
      for (int c = 0; c < 3; ++c) {
        measured[c].at<double>(static_cast<int>(r), static_cast<int>(col)) =
            maps[base + static_cast<std::size_t>(c)];
        truth[c].at<double>(static_cast<int>(r), static_cast<int>(col)) = truth_values[c];
      }
    }
  const char* names[3] = {"E_xx", "E_yy", "E_xy"};
  for (int c = 0; c < 3; ++c) {
    double range = 0.0;
    for (auto it = truth[c].begin<double>(); it != truth[c].end<double>(); ++it)
      if (std::isfinite(*it)) range = std::max(range, std::abs(*it));
    range = std::max(range, 1e-6);
    cv::Mat difference = measured[c] - truth[c];  // NaN where either is NaN
    HeatmapOptions o;
    o.x_min = o.y_min = -1.0;
    o.x_max = o.y_max = 1.0;
    o.axis_unit = "normalised";
    o.min = -range;
    o.max = range;
    char title[128];
    std::snprintf(title, sizeof title, "%s measured (%s), frame %zu", names[c], mode.c_str(), frame);
    o.title = title;
    const cv::Mat left = render_heatmap(measured[c], o);
    std::snprintf(title, sizeof title, "%s truth (exact field)", names[c]);
    o.title = title;
    const cv::Mat middle = render_heatmap(truth[c], o);
    o.title = "measured - truth";
    o.min = -0.25 * range;
    o.max = 0.25 * range;
    const cv::Mat right = render_heatmap(difference, o);
    cv::Mat row;
    cv::hconcat(std::vector<cv::Mat>{left, middle, right}, row);
    const std::string path = (out / (std::string("maps_") + names[c] + ".png")).string();
    const std::string partial = path + ".partial.png";
    if (!cv::imwrite(partial, row)) throw Error("cannot write map image", {.file = path});
    fs::rename(partial, path);
    outputs.push_back(path);
  }
  return outputs;
}

// The files and folders a validate run writes into its output folder.
const std::vector<std::string>& validate_output_names() {
  static const std::vector<std::string> names = {"trial",
                                                 "result",
                                                 "validation.csv",
                                                 "validation_rings.csv",
                                                 "validation_frames.csv",
                                                 "validation_tracks.csv",
                                                 "maps_E_xx.png",
                                                 "maps_E_yy.png",
                                                 "maps_E_xy.png"};
  return names;
}

// The output folder is replaced as a whole when the run completes: it must hold nothing but an earlier
// validate run's files, and none of this run's inputs (the swap would delete them).
void check_validate_output(const ValidateOptions& options) {
  const std::pair<const std::optional<std::string>*, const char*> inputs[] = {
      {&options.scene_path, "--scene"},
      {&options.trial_dir, "--trial"},
      {&options.result_dir, "--result"},
      {&options.process_scene_path, "--process-scene"}};
  for (const auto& [path, option] : inputs)
    if (*path && path_is_within(**path, options.out_dir))
      throw Error(std::string("the output folder ") +
                      (path_is_within(options.out_dir, **path) ? "is" : "contains") + " the " + option +
                      " input " + **path +
                      "; it is replaced as a whole when the run completes, so give a folder of its own",
                  {.file = options.out_dir, .key = "--out"});
  check_replaceable_output(options.out_dir, validate_output_names(), "validate");
}

// The report's paths inside the staging folder, renamed to where they are after the swap.
ValidationReport with_final_paths(ValidationReport report, const StagingDirectory& staging) {
  const auto rebase = [&](std::string& path) {
    if (path.rfind(staging.path(), 0) == 0) path = staging.final_path() + path.substr(staging.path().size());
  };
  rebase(report.result_dir);
  for (std::string& path : report.outputs) rebase(path);
  return report;
}

}  // namespace

const ErrorStats* ValidationReport::find(const std::string& quantity, const std::string& reference,
                                         const std::string& mode) const {
  for (const ErrorStats& s : rows)
    if (s.quantity == quantity && s.reference == reference && s.mode == mode) return &s;
  return nullptr;
}

ValidationReport run_validate(const ValidateOptions& options) {
  if (options.scene_path.has_value() == options.trial_dir.has_value())
    throw Error("validate needs exactly one of --scene (synthesise) and --trial (an existing trial folder)");
  check_validate_output(options);
  // Built in "<out>.partial" and swapped in whole: a failed or killed run leaves the earlier output as it
  // was.
  StagingDirectory staging(options.out_dir);
  const fs::path out(staging.path());
  ValidationReport report;

  std::string trial_dir;
  if (options.scene_path) {
    trial_dir = (out / "trial").string();
    samples::SynthOptions synth;
    synth.scene_path = *options.scene_path;
    synth.out_dir = trial_dir;
    synth.quiet = options.quiet;
    samples::synthesize(synth);
  } else {
    trial_dir = *options.trial_dir;
  }
  const std::string scene_path = (fs::path(trial_dir) / "scene.yaml").string();
  if (!fs::exists(scene_path))
    throw Error("not a synthesised trial folder (no scene.yaml with a synthesis section)",
                {.file = trial_dir});
  const samples::Trial trial(samples::load_synth_config(scene_path));
  const Scene& scene = trial.config().scene;

  if (options.result_dir) {
    report.result_dir = *options.result_dir;
  } else {
    report.result_dir = (out / "result").string();
    ProcessOptions process;
    process.input = trial_dir;
    if (options.process_defaults) {
      if (options.process_scene_path)
        throw Error("validate takes --process-scene or --process-defaults, not both");
      process.folder_scene = false;
    } else {
      process.scene_path = options.process_scene_path.value_or(scene_path);
    }
    process.out_dir = report.result_dir;
    process.staged_folders = {staging.folder()};
    process.staged_folders.insert(process.staged_folders.end(), options.staged_folders.begin(),
                                  options.staged_folders.end());
    process.quiet = options.quiet;
    process.overlay = OverlayMode::kNone;
    process.compute = {"contact", "tracking", "strain"};
    process.tracking_preset = options.tracking_preset;
    process.segmentation_preset = options.segmentation_preset;
    process.strain_mode = options.strain_mode;
    process.log = options.log;
    const auto t0 = std::chrono::steady_clock::now();
    run_process(process);
    report.process_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  const std::string result_path = (fs::path(report.result_dir) / "result.h5").string();
  if (!fs::exists(result_path))
    throw Error("no result.h5 (incomplete or missing run)", {.file = report.result_dir});
  const H5Reader h5(result_path);
  H5Shape shape;
  const std::vector<double> t_s = read(h5, "/frames/t_s", &shape);
  const std::size_t n = shape[0];
  if (static_cast<int>(n) != trial.frames())
    throw Error(
        "the result has " + std::to_string(n) + " frames but the trial " + std::to_string(trial.frames()),
        {.file = result_path});
  for (std::size_t i = 0; i < n; ++i)
    if (std::abs(t_s[i] - trial.frame_times_s()[i]) > 1e-6)
      throw Error("frame times differ from the trial's (a different trial or seed?)",
                  {.file = result_path, .frame = static_cast<std::int64_t>(i)});
  report.frames = static_cast<int>(n);

  const std::vector<double> reference = read(h5, "/tracks/reference_px", &shape);
  const std::size_t k = shape[0];
  const std::vector<double> position = read(h5, "/tracks/position_px", &shape);
  const std::vector<double> covariance = h5.has("/tracks/covariance_px2")
                                             ? h5.read_doubles("/tracks/covariance_px2", &shape)
                                             : std::vector<double>(position.size() / 2 * 3, kNaN);
  const std::vector<double> plate = read(h5, "/plate/displacement_px", &shape);
  const std::vector<double> triangles = read(h5, "/mesh/triangles", &shape);
  const std::size_t t_count = shape[0];
  const std::string mode = h5.attribute_text("/strain", "mode");
  const std::string other_mode = mode == "exact" ? "incremental" : "exact";
  const std::vector<double> total = read(h5, "/strain/total", &shape);
  const std::vector<double> other = read(h5, "/strain/total_" + other_mode, &shape);
  const std::vector<double> energy = read(h5, "/energy/total_J", &shape);
  const std::vector<double> total_sd = h5.has("/strain/total_sd")
                                           ? h5.read_doubles("/strain/total_sd", &shape)
                                           : std::vector<double>(total.size(), kNaN);
  const std::vector<double> stick_ratio = read(h5, "/stick/ratio", &shape);
  const std::vector<std::int64_t> stuck = h5.read_integers("/stick/stuck");
  const double tolerance_px = h5.attribute_number("/stick", "tolerance_px");
  // c from the strain stage's slip-profile fit (older results have only the stuck labels).
  const std::vector<double> c_fit =
      h5.has("/stick/radius_mm") ? h5.read_doubles("/stick/radius_mm", &shape) : std::vector<double>(n, kNaN);

  // Contact, per frame: the measured hull and ellipse against the truth's.
  const ContactTruth true_contact = contact_truth(trial);
  const std::vector<std::int64_t> contact_status = h5.read_integers("/contact/status");
  const std::vector<double> hull = read(h5, "/contact/hull_px", &shape);
  const std::size_t hull_values = shape.size() == 3 ? shape[1] * shape[2] : 0;
  const std::vector<double> ellipses = read(h5, "/contact/ellipse", &shape);
  const std::vector<double> contact_area = read(h5, "/contact/area_mm2", &shape);
  if (contact_status.size() != n || hull.size() != n * hull_values || hull_values % 2 != 0 ||
      ellipses.size() != n * 5 || contact_area.size() != n)
    throw Error("the /contact datasets do not have one row per frame", {.file = result_path});
  std::vector<ContactErrors> contact_frames(n);
  Accumulator contact_iou_deficit, contact_centre, contact_major, contact_minor, contact_area_error;
  for (std::size_t i = 0; i < n; ++i) {
    const ContactErrors e = contact_errors(
        true_contact, contact_status[i], std::span<const double>(hull).subspan(i * hull_values, hull_values),
        std::span<const double>(ellipses).subspan(i * 5, 5), contact_area[i], scene.px_per_mm);
    contact_frames[i] = e;
    contact_iou_deficit.add(1.0 - e.iou);
    contact_centre.add(e.centre_px);
    contact_major.add(e.semi_major_pct);
    contact_minor.add(e.semi_minor_pct);
    contact_area_error.add(e.area_pct);
  }

  if (!true_contact.ellipse)
    throw Error("the trial's contact mask does not fit an ellipse", {.file = trial_dir});
  RingValidation rings(true_contact.mask, *true_contact.ellipse);

  const double young = scene.tissue.young_Pa, nu = scene.tissue.poisson, depth = scene.tissue.depth_m;
  const double px_per_mm = scene.px_per_mm;
  const double m_per_px = 1e-3 / px_per_mm;
  const double border_px = options.border_exclusion_mm * px_per_mm;
  const auto vec = [](const std::vector<double>& v, std::size_t i) { return Vec2{v[2 * i], v[2 * i + 1]}; };

  std::map<std::string, Accumulator> acc;  // key: quantity|reference|mode
  const auto key = [](const std::string& q, const std::string& r, const std::string& m) {
    return q + "|" + r + "|" + m;
  };
  double gain_mt = 0.0, gain_tt = 0.0;
  Accumulator c_exact_error, c_true_contact_error;
  Accumulator energy_triangle_error, energy_interior_error, energy_contact_error;
  std::array<Accumulator, 3> displacement_by_depth;  // tracks < 0.5, 0.5-1, > 1 mm inside the border
  Accumulator displacement, displacement_interior, plate_error, energy_error, stick_error, c_error,
      c_label_error, c_all_error;
  std::vector<double> c_exact_tracks(n, kNaN), c_true_contact(n, kNaN);
  std::vector<double> u_truth_triangle(n, kNaN), u_interior(n, kNaN), u_truth_interior(n, kNaN);
  std::vector<double> u_truth(n, kNaN), u_truth_contact(n, kNaN), ratio_truth(n, kNaN), c_labels(n, kNaN),
      c_model(n, kNaN), disp_rms(n, kNaN), exx_rms(n, kNaN);
  // The paper's running sum of increments applied to the exact vertex positions, triangle by triangle and
  // over the same frames as the measured sum (it starts at 0 on the reference frame, or at the exact total
  // when the triangle joins later, and adds no increment for a frame in which the triangle is not valid or
  // a vertex was not tracked in the frame before). Against it, the incremental mode's measurement error;
  // against the point truth, how far the paper's definition itself lies from the exact Green–Lagrange strain.
  const auto reference_row = static_cast<std::size_t>(h5.attribute_number("/tracks", "reference_frame_row"));
  std::vector<Strain2> increments_truth(t_count, Strain2{kNaN, kNaN, kNaN});
  std::vector<Vec2> true_now(k), true_before(k);
  std::vector<double> u_other(n, kNaN), u_truth_increments(n, kNaN);
  Accumulator energy_other_error, energy_increments_error;
  const std::vector<double>& incremental_total = mode == "incremental" ? total : other;

  for (std::size_t i = 0; i < n; ++i) {
    const samples::FrameField field = trial.field(static_cast<int>(i));
    const samples::LoadState load = trial.load(static_cast<int>(i));
    // Tracks.
    Accumulator frame_disp;
    for (std::size_t j = 0; j < k; ++j) {
      const Vec2 x = vec(position, i * k + j);
      if (!std::isfinite(x.x)) continue;
      const Vec2 X = vec(reference, j);
      const Vec2 u = field.displacement_px(X);
      const double error = std::hypot(x.x - X.x - u.x, x.y - X.y - u.y);
      displacement.add(error);
      frame_disp.add(error);
      const std::size_t c = 3 * (i * k + j);
      rings.add_track({X.x + u.x, X.y + u.y}, {x.x - X.x - u.x, x.y - X.y - u.y},
                      {covariance[c], covariance[c + 1], covariance[c + 2]});
      const double inside_px = -std::max(trial.contact_signed_distance_px(X),
                                         trial.contact_signed_distance_px({X.x + u.x, X.y + u.y}));
      if (inside_px > border_px) displacement_interior.add(error);
      const double inside_mm = inside_px / px_per_mm;
      displacement_by_depth[inside_mm < 0.5 ? 0 : inside_mm < 1.0 ? 1 : 2].add(error);
    }
    disp_rms[i] = frame_disp.stats("", "", "", "").rms;
    if (std::isfinite(plate[2 * i]))
      plate_error.add(std::hypot(plate[2 * i] - load.plate_px.x, plate[2 * i + 1] - load.plate_px.y));

    // Triangles. Their vertices' true positions, once per track.
    for (std::size_t j = 0; j < k; ++j) {
      const Vec2 X = vec(reference, j);
      const Vec2 u = field.displacement_px(X);
      true_now[j] = {X.x + u.x, X.y + u.y};
    }
    double other_energy = 0.0;             // U of the other strain mode, same triangles
    double truth_increments_energy = 0.0;  // U of the running sum of increments of the exact positions
    double truth_energy = 0.0, stuck_area_mm2 = 0.0, stuck_truth_area = 0.0, valid_area = 0.0;
    double interior_energy = 0.0, interior_truth_energy = 0.0, truth_triangle_energy = 0.0;
    Accumulator frame_exx;
    std::vector<std::array<Vec2, 3>> measured_triangles;
    for (std::size_t t = 0; t < t_count; ++t) {
      const std::size_t cell = i * t_count + t;
      if (!std::isfinite(total[cell * 3])) continue;
      std::array<Vec2, 3> X, x_true;
      for (std::size_t v = 0; v < 3; ++v) {
        const auto id = static_cast<std::size_t>(triangles[t * 3 + v]);
        X[v] = vec(reference, id);
        x_true[v] = true_now[id];
      }
      const Vec2 centroid{(X[0].x + X[1].x + X[2].x) / 3.0, (X[0].y + X[1].y + X[2].y) / 3.0};
      const samples::FieldValue at = field.evaluate(centroid);
      const Strain2 e_point = green_lagrange(at.gradient);
      const double area_m2 = std::abs(strain::signed_area(X[0], X[1], X[2])) * m_per_px * m_per_px;
      truth_energy += plane_strain_energy_density_J_m3(e_point, young, nu) * area_m2;
      const Strain2 other_value = {other[cell * 3], other[cell * 3 + 1], other[cell * 3 + 2]};
      if (std::isfinite(other_value.xx))
        other_energy += plane_strain_energy_density_J_m3(other_value, young, nu) * area_m2;
      valid_area += area_m2;
      const bool truth_stuck = std::hypot(at.displacement_px.x - load.plate_px.x,
                                          at.displacement_px.y - load.plate_px.y) <= tolerance_px;
      if (truth_stuck) stuck_truth_area += area_m2;
      if (stuck[cell] == 1) stuck_area_mm2 += area_m2 * 1e6;

      const Gradient2 h_true = strain::displacement_gradient(X, x_true);
      const Strain2 e_triangle = green_lagrange(h_true);
      Strain2& sum_truth = increments_truth[t];
      if (std::isfinite(incremental_total[cell * 3])) {
        if (!std::isfinite(sum_truth.xx)) {
          sum_truth = i == reference_row ? Strain2{0.0, 0.0, 0.0} : e_triangle;
        } else {
          // The strain stage adds an increment when all three vertices were tracked in the frame before.
          std::array<Vec2, 3> x_before;
          bool tracked_before = i > 0;
          for (std::size_t v = 0; v < 3 && tracked_before; ++v) {
            const auto id = static_cast<std::size_t>(triangles[t * 3 + v]);
            tracked_before = std::isfinite(position[2 * ((i - 1) * k + id)]);
            x_before[v] = true_before[id];
          }
          if (tracked_before) {
            const Gradient2 h_before = strain::displacement_gradient(X, x_before);
            const Strain2 inc = green_lagrange(strain::incremental_gradient(h_true, h_before));
            sum_truth = {sum_truth.xx + inc.xx, sum_truth.yy + inc.yy, sum_truth.xy + inc.xy};
          }
        }
        truth_increments_energy += plane_strain_energy_density_J_m3(sum_truth, young, nu) * area_m2;
      }
      truth_triangle_energy += plane_strain_energy_density_J_m3(e_triangle, young, nu) * area_m2;
      const Strain2 measured = {total[cell * 3], total[cell * 3 + 1], total[cell * 3 + 2]};
      const Vec2 current{centroid.x + at.displacement_px.x, centroid.y + at.displacement_px.y};
      rings.add_triangle(current,
                         {measured.xx - e_point.xx, measured.yy - e_point.yy, measured.xy - e_point.xy},
                         {total_sd[cell * 3], total_sd[cell * 3 + 1], total_sd[cell * 3 + 2]});
      {
        std::array<Vec2, 3> x_measured;
        for (std::size_t v = 0; v < 3; ++v)
          x_measured[v] = vec(position, i * k + static_cast<std::size_t>(triangles[t * 3 + v]));
        measured_triangles.push_back(x_measured);
      }
      if (trial.contact_signed_distance_px(centroid) >= -border_px ||
          trial.contact_signed_distance_px(current) >= -border_px)
        continue;
      interior_energy += plane_strain_energy_density_J_m3(measured, young, nu) * area_m2;
      interior_truth_energy += plane_strain_energy_density_J_m3(e_point, young, nu) * area_m2;
      const Strain2 measured_other = {other[cell * 3], other[cell * 3 + 1], other[cell * 3 + 2]};
      const auto truth_point = components(e_point, young, nu);
      const auto truth_triangle = components(e_triangle, young, nu);
      if (std::isfinite(sum_truth.xx)) {
        const Strain2 measured_incremental = {incremental_total[cell * 3], incremental_total[cell * 3 + 1],
                                              incremental_total[cell * 3 + 2]};
        const auto c = components(measured_incremental, young, nu);
        const auto truth_increments = components(sum_truth, young, nu);
        for (int q = 0; q < kComponentCount; ++q) {
          const auto qi = static_cast<std::size_t>(q);
          acc[key(kComponents[q], "truth increments", "incremental")].add(c[qi] - truth_increments[qi]);
          acc[key(kComponents[q], "point", "incremental of truth")].add(truth_increments[qi] -
                                                                        truth_point[qi]);
        }
      }
      for (const auto& [m, value] : {std::pair{mode, measured}, std::pair{other_mode, measured_other}}) {
        const auto c = components(value, young, nu);
        for (int q = 0; q < kComponentCount; ++q) {
          acc[key(kComponents[q], "point", m)].add(c[static_cast<std::size_t>(q)] -
                                                   truth_point[static_cast<std::size_t>(q)]);
          acc[key(kComponents[q], "triangle", m)].add(c[static_cast<std::size_t>(q)] -
                                                      truth_triangle[static_cast<std::size_t>(q)]);
        }
      }
      frame_exx.add(measured.xx - e_point.xx);
      // Least-squares gain of the measured strain on the truth (pooled components): 1 when the errors are
      // unbiased noise; a scale error shows here and in U as 2 × (gain − 1).
      for (const auto& [m_value, t_value] :
           {std::pair{measured.xx, e_point.xx}, std::pair{measured.yy, e_point.yy},
            std::pair{measured.xy, e_point.xy}}) {
        gain_mt += m_value * t_value;
        gain_tt += t_value * t_value;
      }
    }
    exx_rms[i] = frame_exx.stats("", "", "", "").rms;
    rings.add_frame_coverage(measured_triangles);
    std::swap(true_now, true_before);
    if (valid_area > 0.0) {
      u_truth[i] = depth * truth_energy;
      u_other[i] = depth * other_energy;
      u_truth_increments[i] = depth * truth_increments_energy;
      u_truth_triangle[i] = depth * truth_triangle_energy;
      u_interior[i] = depth * interior_energy;
      u_truth_interior[i] = depth * interior_truth_energy;
      ratio_truth[i] = stuck_truth_area / valid_area;
    }
    const samples::GridTruth grid = trial.grid_truth(static_cast<int>(i));
    const double cell_m2 =
        trial.config().truth.grid_step_px * trial.config().truth.grid_step_px * m_per_px * m_per_px;
    double contact_energy = 0.0;
    for (std::size_t g = 0; g < grid.in_contact.size(); ++g)
      if (grid.in_contact[g]) contact_energy += grid.energy_J_m3[g] * cell_m2;
    u_truth_contact[i] = depth * contact_energy;
    c_labels[i] = std::sqrt(stuck_area_mm2 / std::numbers::pi);
    // The same slip-profile fit on the exact displacements of the live tracks, with the true contact: what
    // the estimator gives without tracking error (separates its bias from the tracks').
    if (field.model()) {
      std::vector<Vec2> ref_px, exact_px, tracked_px;
      for (std::size_t j = 0; j < k; ++j) {
        if (!std::isfinite(position[2 * (i * k + j)])) continue;
        const Vec2 X = vec(reference, j);
        const Vec2 u = field.displacement_px(X);
        ref_px.push_back(X);
        exact_px.push_back({X.x + u.x, X.y + u.y});
        tracked_px.push_back(vec(position, i * k + j));
      }
      const samples::LoadHistory& history = trial.history();
      const strain::ContactDisk disk =
          strain::contact_disk(history.contact_centre_px(), history.contact_semi_axes_px().x,
                               history.contact_semi_axes_px().y, history.contact_angle_rad());
      c_exact_tracks[i] = strain::fit_stick_zone(ref_px, exact_px, disk, nu).radius_px / px_per_mm;
      // ... and on the tracked displacements with the true contact (separates the measured ellipse's share).
      c_true_contact[i] = strain::fit_stick_zone(ref_px, tracked_px, disk, nu).radius_px / px_per_mm;
    }
    c_model[i] = load.stick_radius_m * 1e3;
    if (std::isfinite(stick_ratio[i]) && std::isfinite(ratio_truth[i]))
      stick_error.add(stick_ratio[i] - ratio_truth[i]);
  }

  // Energy: relative error on the frames carrying at least 10 % of the largest true energy, if that is at
  // least the energy of a uniform strain of 1e-4 over the contact to the tissue depth. A rigid motion's
  // true energy is rounding (1e-30 J), and relative to it every error read 1e28 %.
  const Vec2 semi_axes_px = trial.history().contact_semi_axes_px();
  const double contact_m2 = std::numbers::pi * semi_axes_px.x * semi_axes_px.y * m_per_px * m_per_px;
  const double u_floor = 0.5 * young * 1e-8 * contact_m2 * depth;
  double u_max = 0.0;
  std::size_t u_argmax = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (std::isfinite(u_truth[i]) && u_truth[i] > u_max) {
      u_max = u_truth[i];
      u_argmax = i;
    }
  for (std::size_t i = 0; i < n && u_max >= u_floor; ++i)
    if (std::isfinite(u_truth[i]) && u_truth[i] >= 0.1 * u_max && std::isfinite(energy[i])) {
      energy_error.add(100.0 * (energy[i] - u_truth[i]) / u_truth[i]);
      if (std::isfinite(u_other[i])) energy_other_error.add(100.0 * (u_other[i] - u_truth[i]) / u_truth[i]);
      const double u_incremental = mode == "incremental" ? energy[i] : u_other[i];
      if (std::isfinite(u_incremental) && u_truth_increments[i] > 0.0)
        energy_increments_error.add(100.0 * (u_incremental - u_truth_increments[i]) / u_truth_increments[i]);
      energy_triangle_error.add(100.0 * (energy[i] - u_truth_triangle[i]) / u_truth_triangle[i]);
      if (u_truth_interior[i] > 0.0)
        energy_interior_error.add(100.0 * (u_interior[i] - u_truth_interior[i]) / u_truth_interior[i]);
      if (u_truth_contact[i] > 0.0)
        energy_contact_error.add(100.0 * (energy[i] - u_truth_contact[i]) / u_truth_contact[i]);
    }
  // Stick radius: frames in partial slip whose stick zone lies well inside the meshed interior and is not
  // tiny (the tracks resolve neither a stick zone near the border nor one a few track spacings wide). The
  // fitted c (/stick/radius_mm) is the reference row; the radius of the stuck labels' area is reported next
  // to it; every frame once the plate moves (full slip c = 0 and c near a included) as an absolute error.
  const double a_mm = trial.history().contact_radius_m() * 1e3;
  Accumulator c_of_a_error;  // every frame in partial slip, in % of the contact radius
  for (std::size_t i = 0; i < n; ++i) {
    const double c = c_model[i];
    if (c > 0.2 * a_mm && c < a_mm - 2.0 * options.border_exclusion_mm) {
      if (std::isfinite(c_fit[i])) c_error.add(100.0 * (c_fit[i] - c) / c);
      if (std::isfinite(c_labels[i])) c_label_error.add(100.0 * (c_labels[i] - c) / c);
      if (std::isfinite(c_exact_tracks[i])) c_exact_error.add(100.0 * (c_exact_tracks[i] - c) / c);
      if (std::isfinite(c_true_contact[i])) c_true_contact_error.add(100.0 * (c_true_contact[i] - c) / c);
    }
    if (trial.load(static_cast<int>(i)).tangential_N > 0.0 && std::isfinite(c_fit[i]))
      c_all_error.add(c_fit[i] - c);
    if (c > 0.0 && c < a_mm && std::isfinite(c_fit[i])) c_of_a_error.add(100.0 * (c_fit[i] - c) / a_mm);
  }

  {
    const std::size_t frame =
        options.map_frame >= 0 ? std::min(static_cast<std::size_t>(options.map_frame), n - 1) : u_argmax;
    write_tracks_csv(out / "validation_tracks.csv", trial, frame, reference, position);
    report.outputs.push_back((out / "validation_tracks.csv").string());
  }

  for (const std::string& m : {mode, other_mode})
    for (const char* reference_name : {"point", "triangle"})
      for (int q = 0; q < kComponentCount; ++q)
        report.rows.push_back(acc[key(kComponents[q], reference_name, m)].stats(
            kComponents[q], reference_name, m, q == 5 ? "J/m3" : ""));
  for (const auto& [reference_name, m] :
       {std::pair{"truth increments", "incremental"}, std::pair{"point", "incremental of truth"}})
    for (int q = 0; q < kComponentCount; ++q)
      report.rows.push_back(acc[key(kComponents[q], reference_name, m)].stats(kComponents[q], reference_name,
                                                                              m, q == 5 ? "J/m3" : ""));
  report.rows.push_back(displacement.stats("displacement", "tracks", "", "px"));
  report.rows.push_back(displacement_interior.stats("displacement_interior", "tracks", "", "px"));
  // Where the error lives: the ridge contrast fades near the border, and there the ridges often run along it.
  report.rows.push_back(displacement_by_depth[0].stats("displacement_border_0-0.5mm", "tracks", "", "px"));
  report.rows.push_back(displacement_by_depth[1].stats("displacement_border_0.5-1mm", "tracks", "", "px"));
  report.rows.push_back(displacement_by_depth[2].stats("displacement_beyond_1mm", "tracks", "", "px"));
  report.rows.push_back(plate_error.stats("plate_displacement", "truth", "", "px"));
  report.rows.push_back(energy_error.stats("U", "same triangles", mode, "%"));
  report.rows.push_back(energy_other_error.stats("U", "same triangles", other_mode, "%"));
  report.rows.push_back(energy_increments_error.stats("U", "truth increments", "incremental", "%"));
  {
    ErrorStats gain{"strain_gain", "point", mode, "", kNaN, kNaN, kNaN, 0};
    if (gain_tt > 0.0) gain.rms = gain.mean = gain_mt / gain_tt;
    gain.samples = acc[key("E_xx", "point", mode)].n;
    report.rows.push_back(gain);
  }
  report.rows.push_back(energy_triangle_error.stats("U_triangle_truth", "same triangles", mode, "%"));
  report.rows.push_back(energy_interior_error.stats("U_interior", "interior triangles", mode, "%"));
  report.rows.push_back(energy_contact_error.stats("U_whole_contact", "truth grid", mode, "%"));
  report.rows.push_back(stick_error.stats("stick_ratio", "same triangles", "", ""));
  report.rows.push_back(c_error.stats("stick_radius_c", "model", "", "%"));
  report.rows.push_back(c_label_error.stats("stick_radius_c_labels", "model", "", "%"));
  report.rows.push_back(c_exact_error.stats("stick_radius_c_exact_tracks", "model", "", "%"));
  report.rows.push_back(c_true_contact_error.stats("stick_radius_c_true_contact", "model", "", "%"));
  report.rows.push_back(c_all_error.stats("stick_radius_c_all_frames", "model", "", "mm"));
  report.rows.push_back(c_of_a_error.stats("stick_radius_c_of_a", "model", "", "%"));
  report.rows.push_back(contact_iou_deficit.stats("contact_1-IoU", "truth mask", "", ""));
  report.rows.push_back(contact_centre.stats("contact_centre", "truth ellipse", "", "px"));
  report.rows.push_back(contact_major.stats("contact_semi_major", "truth ellipse", "", "%"));
  report.rows.push_back(contact_minor.stats("contact_semi_minor", "truth ellipse", "", "%"));
  report.rows.push_back(contact_area_error.stats("contact_area", "truth mask", "", "%"));
  for (ErrorStats& row : rings.rows()) report.rows.push_back(std::move(row));
  rings.write_csv((out / "validation_rings.csv").string());
  report.outputs.push_back((out / "validation_rings.csv").string());

  write_rows_csv(out / "validation.csv", report.rows);
  report.outputs.push_back((out / "validation.csv").string());
  {
    CsvWriter csv(
        (out / "validation_frames.csv").string(),
        {"index", "t_s", "U_J", "U_truth_J", "U_truth_contact_J", "U_truth_triangle_J", "U_interior_J",
         "U_truth_interior_J", "stick_ratio", "stick_ratio_truth", "c_mm", "c_labels_mm", "c_model_mm",
         "displacement_rms_px", "E_xx_rms", "contact_iou", "contact_centre_error_px",
         "contact_semi_major_error_pct", "contact_semi_minor_error_pct"});
    for (std::size_t i = 0; i < n; ++i)
      csv.row_text(
          {std::to_string(i), format_double(t_s[i]), format_double(energy[i]), format_double(u_truth[i]),
           format_double(u_truth_contact[i]), format_double(u_truth_triangle[i]),
           format_double(u_interior[i]), format_double(u_truth_interior[i]), format_double(stick_ratio[i]),
           format_double(ratio_truth[i]), format_double(c_fit[i]), format_double(c_labels[i]),
           format_double(c_model[i]), format_double(disp_rms[i]), format_double(exx_rms[i]),
           format_double(contact_frames[i].iou), format_double(contact_frames[i].centre_px),
           format_double(contact_frames[i].semi_major_pct), format_double(contact_frames[i].semi_minor_pct)});
    csv.commit();
    report.outputs.push_back((out / "validation_frames.csv").string());
  }

  for (std::string& path : write_side_by_side_maps(options, h5, result_path, trial, mode, out, n, u_argmax))
    report.outputs.push_back(std::move(path));
  staging.commit();
  return with_final_paths(std::move(report), staging);
}

}  // namespace tirstrain::pipeline
