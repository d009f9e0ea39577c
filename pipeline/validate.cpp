#include "pipeline/validate.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <span>
#include <sstream>
#include <utility>

#include "contact/ellipse.hpp"
#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/heatmap.hpp"
#include "core/png_file.hpp"
#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "pipeline/contact_observability.hpp"
#include "pipeline/error_accumulator.hpp"
#include "pipeline/process.hpp"
#include "pipeline/validate_field.hpp"
#include "pipeline/validate_rings.hpp"
#include "samples/synth.hpp"
#include "samples/trial.hpp"
#include "strain/deformation.hpp"
#include "strain/stick_zone.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

// Per live track at one frame: where the displacement errors are (for finding a tracking bias). `position`:
// that frame's /tracks/position_px row.
void write_tracks_csv(const fs::path& path, const samples::Trial& trial, std::size_t frame,
                      const std::vector<double>& reference, const std::vector<double>& position) {
  const samples::FrameField field = trial.field(static_cast<int>(frame));
  const std::size_t k = reference.size() / 2;
  CsvWriter csv(path.string(), {"frame", "track", "X_px", "Y_px", "border_distance_px", "u_px", "v_px",
                                "u_truth_px", "v_truth_px"});
  for (std::size_t j = 0; j < k; ++j) {
    const Vec2 x{position[2 * j], position[2 * j + 1]};
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
  // Only the pictured frame's map is read: the maps of a long trial do not fit in memory.
  const std::vector<double> maps = h5.read_row_doubles("/maps/strain_total", frame, &shape);
  const std::size_t g = shape[0];
  const cv::Matx23d to_normalised = parse_matrix(h5.attribute_text("/maps", "to_normalised"), result_path);
  const cv::Matx23d to_reference = invert_similarity(to_normalised);
  // The map's components are in its own axes (the forward similarity's rotation).
  const double axes_angle_rad = std::atan2(to_normalised(0, 1), to_normalised(0, 0));
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
      const std::size_t base = (r * g + col) * 3;
      const bool inside = trial.contact_signed_distance_px(X) < 0.0;
      const Strain2 e = inside ? in_axes(green_lagrange(field.evaluate(X).gradient), axes_angle_rad)
                               : Strain2{kNaN, kNaN, kNaN};
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
    if (axes_angle_rad != 0.0)
      o.axes = "x along the major axis (" +
               std::to_string(std::lround(axes_angle_rad * 180.0 / std::numbers::pi)) +
               " deg in the image), y 90 deg clockwise";
    o.unit = "strain (dimensionless)";
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
    write_png_file(path, row);
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
                                                 "validation.json",
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

// What a result's summary.json says about the run that made it: its input and wall time (together they
// tell one run from another, wherever its folder is now); empty without a summary.
nlohmann::json result_identity(const std::string& result_dir) {
  const fs::path summary = fs::path(result_dir) / "summary.json";
  if (!fs::exists(summary)) return {};
  std::ifstream in(summary);
  const nlohmann::json s = nlohmann::json::parse(in, nullptr, false);
  if (s.is_discarded() || !s.is_object()) return {};
  return {{"input", s.value("input", "")}, {"wall_time_s", s.value("wall_time_s", 0.0)}};
}

// A --result processed from another trial folder that still exists would be compared with this trial's
// truth: refused, naming both. (A result whose input folder is gone or is no trial cannot be told apart.)
void check_result_of_trial(const ValidateOptions& options, const std::string& trial_dir) {
  if (!options.result_dir) return;
  const nlohmann::json identity = result_identity(*options.result_dir);
  const std::string input = identity.is_object() ? identity.value("input", "") : "";
  if (input.empty() || !fs::exists(fs::path(input) / "truth.h5")) return;
  std::error_code failed;
  if (fs::equivalent(input, trial_dir, failed) || failed) return;
  throw Error("is a result of the trial " + input + ", not of " + trial_dir +
                  ": its errors would be taken against another trial's truth",
              {.file = *options.result_dir, .key = "--result"});
}

// OUT/validation.json: which trial and which result run the tables describe, so that `tirstrain report`
// can refuse a validation given beside another result.
void write_provenance(const fs::path& out, const std::string& trial_dir, const std::string& result_dir,
                      const std::string& final_result_dir, std::size_t frames) {
  const nlohmann::json j = {{"format", "tirstrain validation"},
                            {"trial", fs::absolute(trial_dir).lexically_normal().string()},
                            {"result", fs::absolute(final_result_dir).lexically_normal().string()},
                            {"result_run", result_identity(result_dir)},
                            {"frames", frames}};
  write_text_file((out / "validation.json").string(), j.dump(2) + "\n");
}

// The trial folder: synthesised into OUT/trial from --scene, or the --trial given.
std::string prepare_trial(const ValidateOptions& options, const fs::path& out) {
  if (!options.scene_path) return *options.trial_dir;
  const std::string trial_dir = (out / "trial").string();
  samples::SynthOptions synth;
  synth.scene_path = *options.scene_path;
  synth.out_dir = trial_dir;
  synth.quiet = options.quiet;
  samples::synthesize(synth);
  return trial_dir;
}

samples::SynthConfig load_trial_config(const std::string& trial_dir) {
  const std::string scene_path = (fs::path(trial_dir) / "scene.yaml").string();
  if (!fs::exists(scene_path))
    throw Error("not a synthesised trial folder (no scene.yaml with a synthesis section)",
                {.file = trial_dir});
  return samples::load_synth_config(scene_path);
}

// truth.h5 keeps the scene the frames were made with (trials synthesised before it did are checked by the
// quantities below alone): any edit to scene.yaml since is refused, whatever it changes.
void check_scene_text_matches(const H5Reader& truth, const std::string& trial_dir) {
  if (!truth.has_attribute("/", "scene_yaml")) return;
  const fs::path scene_path = fs::path(trial_dir) / "scene.yaml";
  // Compared as scenes, written out the same way: comments and layout are not edits.
  if (scene_to_yaml(load_scene(scene_path.string())) == truth.attribute_text("/", "scene_yaml")) return;
  throw Error(
      "the trial's scene.yaml differs from the scene its frames were made with (kept in truth.h5): "
      "edited since `tirstrain synth`? To process the trial with other settings, leave its scene as "
      "it is and pass them with --process-scene",
      {.file = scene_path.string()});
}

// The truth is recomputed from the trial's scene.yaml, and truth.h5 records what the frames were made with.
// A scene edited since `tirstrain synth` (the pattern band moved, the calibration changed) would be
// validated against a truth the frames do not show, so every quantity the truth depends on must match.
void check_scene_matches_truth(const samples::Trial& trial, const std::string& trial_dir) {
  const fs::path truth_path = fs::path(trial_dir) / "truth.h5";
  if (!fs::exists(truth_path))
    throw Error(
        "no truth.h5: nothing tells that scene.yaml still describes the frames (`tirstrain synth` "
        "writes both)",
        {.file = trial_dir});
  const H5Reader truth(truth_path.string());
  check_scene_text_matches(truth, trial_dir);
  const samples::SynthConfig& cfg = trial.config();
  const samples::LoadHistory& history = trial.history();
  const std::pair<const char*, double> recomputed[] = {
      {"seed", static_cast<double>(cfg.seed)},
      {"width_px", static_cast<double>(trial.width())},
      {"height_px", static_cast<double>(trial.height())},
      {"px_per_mm", cfg.scene.px_per_mm},
      {"young_Pa", cfg.scene.tissue.young_Pa},
      {"poisson", cfg.scene.tissue.poisson},
      {"friction", cfg.loading.friction},
      {"direction_rad", history.direction_rad()},
      {"contact_centre_x_px", history.contact_centre_px().x},
      {"contact_centre_y_px", history.contact_centre_px().y},
      {"contact_semi_axis_1_px", history.contact_semi_axes_px().x},
      {"contact_semi_axis_2_px", history.contact_semi_axes_px().y},
      {"contact_angle_rad", history.contact_angle_rad()},
      {"contact_radius_m", history.contact_radius_m()},
      {"max_rigid_shift_m", history.max_rigid_shift_m()}};
  for (const auto& [name, value] : recomputed) {
    const double recorded = truth.attribute_number("/", name);
    if (std::abs(recorded - value) <= 1e-9 * std::max(1.0, std::abs(recorded))) continue;
    std::ostringstream message;
    message.precision(10);
    message << "the trial's scene.yaml no longer describes its frames: truth.h5 records " << name << " = "
            << recorded << ", the scene now gives " << value
            << " (edited since `tirstrain synth`?); to process the trial with other settings, leave its "
               "scene as it is and pass them with --process-scene";
    throw Error(message.str(), {.file = (fs::path(trial_dir) / "scene.yaml").string()});
  }
}

// The trial processed into OUT/result (unless --result gives a result): report.result_dir and the time taken.
void process_trial(const ValidateOptions& options, const std::string& trial_dir,
                   const StagingDirectory& staging, ValidationReport& report) {
  if (options.result_dir) {
    report.result_dir = *options.result_dir;
    return;
  }
  report.result_dir = (fs::path(staging.path()) / "result").string();
  ProcessOptions process;
  process.input = trial_dir;
  if (options.process_defaults) {
    if (options.process_scene_path)
      throw Error("validate takes --process-scene or --process-defaults, not both");
    process.folder_scene = false;
  } else {
    process.scene_path = options.process_scene_path.value_or((fs::path(trial_dir) / "scene.yaml").string());
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

// Each frame's contact (hull, ellipse, area) against the truth's mask and ellipse.
struct ContactValidation {
  std::vector<ContactErrors> frames;
  ErrorAccumulator iou_deficit, centre, major, minor, area;
  // Each frame's own centre, before the smoothing in time (results that have it).
  ErrorAccumulator centre_measured;
  bool has_measured = false;

  void append_rows(std::vector<ErrorStats>& rows) const {
    rows.push_back(iou_deficit.stats("contact_1-IoU", "truth mask", "", ""));
    rows.push_back(centre.stats("contact_centre", "truth ellipse", "", "px"));
    if (has_measured)
      rows.push_back(centre_measured.stats("contact_centre_measured", "truth ellipse", "", "px"));
    rows.push_back(major.stats("contact_semi_major", "truth ellipse", "", "%"));
    rows.push_back(minor.stats("contact_semi_minor", "truth ellipse", "", "%"));
    rows.push_back(area.stats("contact_area", "truth mask", "", "%"));
  }
  // IoU, centre error (px), semi-axes errors (%) per frame, for validation_frames.csv.
  std::vector<std::array<double, 4>> per_frame() const {
    std::vector<std::array<double, 4>> v;
    for (const ContactErrors& e : frames)
      v.push_back({e.iou, e.centre_px, e.semi_major_pct, e.semi_minor_pct});
    return v;
  }
};

ContactValidation validate_contact(const ValidatedResult& r, const ContactTruth& truth, double px_per_mm) {
  ContactValidation v;
  for (std::size_t i = 0; i < r.frames; ++i) {
    const ContactErrors e = contact_errors(
        truth, r.contact_status[i], std::span<const double>(r.hull).subspan(i * r.hull_values, r.hull_values),
        std::span<const double>(r.ellipses).subspan(i * 5, 5), r.contact_area[i], px_per_mm);
    v.frames.push_back(e);
    v.iou_deficit.add(1.0 - e.iou);
    v.centre.add(e.centre_px);
    if (!r.measured_centres.empty() && std::isfinite(e.centre_px) && truth.ellipse) {
      v.has_measured = true;
      v.centre_measured.add(std::hypot(r.measured_centres[i * 2] - truth.ellipse->cx_px,
                                       r.measured_centres[i * 2 + 1] - truth.ellipse->cy_px));
    }
    v.major.add(e.semi_major_pct);
    v.minor.add(e.semi_minor_pct);
    v.area.add(e.area_pct);
  }
  return v;
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
    throw Error("validate needs exactly one of --scene (synthesise) and --trial (an existing trial folder)",
                {.key = "--scene"});
  check_validate_output(options);
  // Built in "<out>.partial" and swapped in whole: a failed or killed run leaves the earlier output as it
  // was.
  StagingDirectory staging(options.out_dir);
  const fs::path out(staging.path());
  ValidationReport report;
  const std::string trial_dir = prepare_trial(options, out);
  const samples::Trial trial(load_trial_config(trial_dir));
  check_scene_matches_truth(trial, trial_dir);
  // Before the trial is processed, which takes the time.
  if (options.map_frame >= trial.frames())
    throw Error("frame " + std::to_string(options.map_frame) + " is past the trial's last frame (" +
                    std::to_string(trial.frames() - 1) + ")",
                {.key = "--map-frame"});
  check_result_of_trial(options, trial_dir);
  process_trial(options, trial_dir, staging, report);
  const std::string result_path = (fs::path(report.result_dir) / "result.h5").string();
  if (!fs::exists(result_path))
    throw Error("no result.h5 (incomplete or missing run)", {.file = report.result_dir});
  const ValidatedResult result = read_validated_result(result_path, trial);
  report.frames = static_cast<int>(result.frames);

  if (const auto differences = calibration_differences(result, trial.config().scene); !differences.empty()) {
    std::string list;
    for (const std::string& d : differences) list += (list.empty() ? "" : ", ") + d;
    report.warnings.push_back(
        "the result was processed with " + list +
        ": validate takes its areas and stick radii back to pixels through its own px_per_mm, and recomputes "
        "the other energies from its tracks with the trial's values, but U in the result's strain mode, "
        "U_triangle_truth and U_whole_contact are result.h5's own /energy/total_J");
  }
  const ContactTruth true_contact = contact_truth(trial);
  const ContactValidation contact =
      validate_contact(result, true_contact,
                       std::isfinite(result.px_per_mm) ? result.px_per_mm : trial.config().scene.px_per_mm);
  if (!true_contact.ellipse)
    throw Error("the trial's contact mask does not fit an ellipse", {.file = trial_dir});
  RingValidation rings(true_contact.mask, *true_contact.ellipse);
  FieldValidation field(trial, result, options, rings);
  for (std::size_t i = 0; i < result.frames; ++i) field.add_frame(i);
  field.finish();

  const std::size_t map_frame =
      options.map_frame >= 0 ? static_cast<std::size_t>(options.map_frame) : field.energy_peak_frame();
  write_tracks_csv(out / "validation_tracks.csv", trial, map_frame, result.reference,
                   frame_rows(result, map_frame).position);
  report.outputs.push_back((out / "validation_tracks.csv").string());
  field.append_rows(report.rows);
  contact.append_rows(report.rows);
  for (ErrorStats& row : rings.rows()) report.rows.push_back(std::move(row));
  rings.write_csv((out / "validation_rings.csv").string());
  report.outputs.push_back((out / "validation_rings.csv").string());
  write_rows_csv(out / "validation.csv", report.rows);
  report.outputs.push_back((out / "validation.csv").string());
  field.write_frames_csv((out / "validation_frames.csv").string(), contact.per_frame());
  report.outputs.push_back((out / "validation_frames.csv").string());
  const H5Reader h5(result_path);
  for (std::string& path :
       write_side_by_side_maps(options, h5, result_path, trial, result.mode, out, result.frames, map_frame))
    report.outputs.push_back(std::move(path));
  const ValidationReport final_paths = with_final_paths(report, staging);
  write_provenance(out, trial_dir, report.result_dir, final_paths.result_dir, result.frames);
  report.outputs.push_back((out / "validation.json").string());
  staging.commit();
  return with_final_paths(std::move(report), staging);
}

}  // namespace tirstrain::pipeline
