#include "pipeline/validate_field.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "strain/deformation.hpp"
#include "strain/stick_zone.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

Vec2 vec(const std::vector<double>& v, std::size_t i) {
  return {v[2 * i], v[2 * i + 1]};
}

std::string key(const std::string& q, const std::string& r, const std::string& m) {
  return q + "|" + r + "|" + m;
}

void read_frames(const H5Reader& h5, const samples::Trial& trial, ValidatedResult& r) {
  if (h5.has_attribute("/frames", "width_px")) {
    const double width_px = h5.attribute_number("/frames", "width_px");
    const double height_px = h5.attribute_number("/frames", "height_px");
    if (width_px != trial.width() || height_px != trial.height())
      throw Error("the result's frames are " + format_double(width_px) + " x " + format_double(height_px) +
                      " px but the trial's " + std::to_string(trial.width()) + " x " +
                      std::to_string(trial.height()) + ": a result of another trial",
                  {.file = r.path});
  }
  H5Shape shape;
  r.t_s = read(h5, "/frames/t_s", &shape);
  r.frames = shape[0];
  if (static_cast<int>(r.frames) != trial.frames())
    throw Error("the result has " + std::to_string(r.frames) + " frames but the trial " +
                    std::to_string(trial.frames()),
                {.file = r.path});
  for (std::size_t i = 0; i < r.frames; ++i)
    if (std::abs(r.t_s[i] - trial.frame_times_s()[i]) > 1e-6)
      throw Error("frame times differ from the trial's (a different trial or seed?)",
                  {.file = r.path, .frame = static_cast<std::int64_t>(i)});
}

// The calibration and tissue the result was processed with. Its stick radii (mm) are taken to the trial's
// mm through the pixels they were measured in, so that a result processed with another px_per_mm (no scene)
// is judged on its measurement, not on its calibration.
void read_calibration(const H5Reader& h5, const samples::Trial& trial, ValidatedResult& r) {
  const auto attribute = [&](const char* object, const char* name) {
    return h5.has(object) && h5.has_attribute(object, name) ? h5.attribute_number(object, name) : kNaN;
  };
  r.px_per_mm = attribute("/contact", "px_per_mm");
  r.young_Pa = attribute("/energy", "young_Pa");
  r.poisson = attribute("/energy", "poisson");
  r.depth_m = attribute("/energy", "depth_m");
  const double to_trial_mm = std::isfinite(r.px_per_mm) ? r.px_per_mm / trial.config().scene.px_per_mm : 1.0;
  for (std::vector<double>* mm : {&r.c_fit, &r.c_reach})
    for (double& v : *mm) v *= to_trial_mm;
}

void read_tracks_and_strain(const H5Reader& h5, ValidatedResult& r) {
  H5Shape shape;
  r.reference = read(h5, "/tracks/reference_px", &shape);
  r.tracks = shape[0];
  for (const char* name : {"/tracks/position_px", "/strain/total", "/stick/stuck"})
    if (!h5.has(name))
      throw Error(std::string("the result has no ") + name + " (was it processed with tracking and strain?)",
                  {.file = h5.path()});
  r.plate = read(h5, "/plate/displacement_px", &shape);
  r.triangles = read(h5, "/mesh/triangles", &shape);
  r.triangles_count = shape[0];
  r.mode = h5.attribute_text("/strain", "mode");
  r.other_mode = r.mode == "exact" ? "incremental" : "exact";
  if (!h5.has("/strain/total_" + r.other_mode))
    throw Error(
        "the result has no /strain/total_" + r.other_mode + " (was it processed with tracking and strain?)",
        {.file = h5.path()});
  r.energy = read(h5, "/energy/total_J", &shape);
  r.stick_ratio = read(h5, "/stick/ratio", &shape);
  r.tolerance_px = h5.attribute_number("/stick", "tolerance_px");
  // c from the strain stage's slip-profile fit (older results have only the stuck labels).
  r.c_fit = h5.has("/stick/radius_mm") ? h5.read_doubles("/stick/radius_mm", &shape)
                                       : std::vector<double>(r.frames, kNaN);
  r.c_reach.assign(r.frames, kNaN);
  if (h5.has("/stick/tracks_reach_ratio") && h5.has("/stick/radius_status")) {
    const std::vector<double> reach = h5.read_doubles("/stick/tracks_reach_ratio", &shape);
    const std::vector<std::int64_t> status = h5.read_integers("/stick/radius_status");
    const double a_mm = h5.attribute_number("/stick", "contact_radius_mm");
    for (std::size_t i = 0; i < r.frames && i < reach.size() && i < status.size(); ++i)
      if (status[i] == static_cast<std::int64_t>(strain::StickZoneStatus::kSlipBeyondTracks))
        r.c_reach[i] = reach[i] * a_mm;
  }
  r.reference_row = static_cast<std::size_t>(h5.attribute_number("/tracks", "reference_frame_row"));
}

void read_contact(const H5Reader& h5, ValidatedResult& r) {
  H5Shape shape;
  r.contact_status = h5.read_integers("/contact/status");
  r.hull = read(h5, "/contact/hull_px", &shape);
  r.hull_values = shape.size() == 3 ? shape[1] * shape[2] : 0;
  r.ellipses = read(h5, "/contact/ellipse", &shape);
  r.contact_area = read(h5, "/contact/area_mm2", &shape);
  if (h5.has("/contact/centre_measured_px"))
    r.measured_centres = read(h5, "/contact/centre_measured_px", &shape);
  const std::size_t n = r.frames;
  if (r.contact_status.size() != n || r.hull.size() != n * r.hull_values || r.hull_values % 2 != 0 ||
      r.ellipses.size() != n * 5 || r.contact_area.size() != n ||
      (!r.measured_centres.empty() && r.measured_centres.size() != n * 2))
    throw Error("the /contact datasets do not have one row per frame", {.file = r.path});
}

}  // namespace

ValidatedResult read_validated_result(const std::string& result_path, const samples::Trial& trial) {
  ValidatedResult r;
  r.h5 = std::make_shared<const H5Reader>(result_path);
  r.path = result_path;
  read_frames(*r.h5, trial, r);
  read_tracks_and_strain(*r.h5, r);
  read_contact(*r.h5, r);
  read_calibration(*r.h5, trial, r);
  return r;
}

std::vector<std::string> calibration_differences(const ValidatedResult& result, const Scene& trial_scene) {
  std::vector<std::string> out;
  const auto differs = [](double used, double truth) {
    return std::isfinite(used) && std::abs(used - truth) > 1e-9 * std::abs(truth);
  };
  const auto say = [&](const char* what, double used, double truth) {
    if (differs(used, truth))
      out.push_back(std::string(what) + " " + format_double(used) + " where the trial's is " +
                    format_double(truth));
  };
  say("px_per_mm", result.px_per_mm, trial_scene.px_per_mm);
  say("E_Pa", result.young_Pa, trial_scene.tissue.young_Pa);
  say("nu", result.poisson, trial_scene.tissue.poisson);
  say("depth_m", result.depth_m, trial_scene.tissue.depth_m);
  return out;
}

FrameRows frame_rows(const ValidatedResult& result, std::size_t i) {
  const H5Reader& h5 = *result.h5;
  const auto row_or_nan = [&](const std::string& name, std::size_t values) {
    return h5.has(name) ? h5.read_row_doubles(name, i) : std::vector<double>(values, kNaN);
  };
  FrameRows rows;
  rows.position = h5.read_row_doubles("/tracks/position_px", i);
  rows.covariance = row_or_nan("/tracks/covariance_px2", 3 * result.tracks);
  rows.total = h5.read_row_doubles("/strain/total", i);
  rows.other = h5.read_row_doubles("/strain/total_" + result.other_mode, i);
  rows.total_sd = row_or_nan("/strain/total_sd", 3 * result.triangles_count);
  rows.stuck = h5.read_row_doubles("/stick/stuck", i);
  return rows;
}

FieldValidation::FieldValidation(const samples::Trial& trial, const ValidatedResult& result,
                                 const ValidateOptions& options, RingValidation& rings)
    : trial_(trial), r_(result), options_(options), rings_(rings) {
  const Scene& scene = trial.config().scene;
  young_ = scene.tissue.young_Pa;
  nu_ = scene.tissue.poisson;
  depth_ = scene.tissue.depth_m;
  px_per_mm_ = scene.px_per_mm;
  m_per_px_ = 1e-3 / px_per_mm_;
  border_px_ = options.border_exclusion_mm * px_per_mm_;
  const std::size_t n = r_.frames;
  for (std::vector<double>* v : {&c_exact_tracks_, &c_true_contact_, &u_truth_triangle_, &u_interior_,
                                 &u_truth_interior_, &u_truth_, &u_truth_contact_, &ratio_truth_, &c_labels_,
                                 &c_model_, &disp_rms_, &exx_rms_, &u_other_, &u_truth_increments_})
    v->assign(n, kNaN);
  increments_truth_.assign(r_.triangles_count, Strain2{kNaN, kNaN, kNaN});
  true_now_.resize(r_.tracks);
  true_before_.resize(r_.tracks);
}

FieldValidation::Accumulator& FieldValidation::acc(const std::string& quantity, const std::string& reference,
                                                   const std::string& mode) {
  return acc_[key(quantity, reference, mode)];
}

FieldValidation::Accumulator FieldValidation::acc_or_empty(const std::string& quantity,
                                                           const std::string& reference,
                                                           const std::string& mode) const {
  const auto it = acc_.find(key(quantity, reference, mode));
  return it == acc_.end() ? Accumulator{} : it->second;
}

void FieldValidation::add_frame(std::size_t i) {
  if (i > 0 && previous_frame_ != i - 1) {
    previous_position_ = frame_rows(r_, i - 1).position;
    previous_frame_ = i - 1;
  }
  rows_ = frame_rows(r_, i);
  const samples::FrameField field = trial_.field(static_cast<int>(i));
  const samples::LoadState load = trial_.load(static_cast<int>(i));
  add_tracks(i, field, load);
  add_triangles(i, field, load);
  add_contact_energy(i);
  add_stick_fits(i, field);
  c_model_[i] = load.stick_radius_m * 1e3;
  if (std::isfinite(r_.stick_ratio[i]) && std::isfinite(ratio_truth_[i]))
    stick_error_.add(r_.stick_ratio[i] - ratio_truth_[i]);
  previous_position_ = std::move(rows_.position);
  previous_frame_ = i;
}

// Each live track against the exact displacement of its reference point; the plate against its truth.
void FieldValidation::add_tracks(std::size_t i, const samples::FrameField& field,
                                 const samples::LoadState& load) {
  const std::size_t k = r_.tracks;
  Accumulator frame_disp;
  for (std::size_t j = 0; j < k; ++j) {
    const Vec2 x = vec(rows_.position, j);
    if (!std::isfinite(x.x)) continue;
    const Vec2 X = vec(r_.reference, j);
    const Vec2 u = field.displacement_px(X);
    const double error = std::hypot(x.x - X.x - u.x, x.y - X.y - u.y);
    displacement_.add(error);
    frame_disp.add(error);
    const std::size_t c = 3 * j;
    rings_.add_track({X.x + u.x, X.y + u.y}, {x.x - X.x - u.x, x.y - X.y - u.y},
                     {rows_.covariance[c], rows_.covariance[c + 1], rows_.covariance[c + 2]});
    const double inside_px = -std::max(trial_.contact_signed_distance_px(X),
                                       trial_.contact_signed_distance_px({X.x + u.x, X.y + u.y}));
    if (inside_px > border_px_) displacement_interior_.add(error);
    const double inside_mm = inside_px / px_per_mm_;
    displacement_by_depth_[inside_mm < 0.5 ? 0 : inside_mm < 1.0 ? 1 : 2].add(error);
  }
  disp_rms_[i] = frame_disp.stats("", "", "", "").rms;
  if (std::isfinite(r_.plate[2 * i]))
    plate_error_.add(std::hypot(r_.plate[2 * i] - load.plate_px.x, r_.plate[2 * i + 1] - load.plate_px.y));
}

// One frame's sums over its valid triangles.
struct FieldValidation::FrameSums {
  double other_energy = 0.0;             // U of the other strain mode, same triangles
  double truth_increments_energy = 0.0;  // U of the running sum of increments of the exact positions
  double truth_energy = 0.0, stuck_area_mm2 = 0.0, stuck_truth_area = 0.0, valid_area = 0.0;
  double interior_energy = 0.0, interior_truth_energy = 0.0, truth_triangle_energy = 0.0;
  ErrorAccumulator exx;
  std::vector<std::array<Vec2, 3>> measured_triangles;
};

// Each valid triangle's strain against the exact strain at its centroid (point) and of its exact vertices
// (triangle); energies, stick labels and coverage of the frame.
void FieldValidation::add_triangles(std::size_t i, const samples::FrameField& field,
                                    const samples::LoadState& load) {
  // Their vertices' true positions, once per track.
  for (std::size_t j = 0; j < r_.tracks; ++j) {
    const Vec2 X = vec(r_.reference, j);
    const Vec2 u = field.displacement_px(X);
    true_now_[j] = {X.x + u.x, X.y + u.y};
  }
  FrameSums sums;
  for (std::size_t t = 0; t < r_.triangles_count; ++t) add_triangle(i, t, field, load, sums);
  exx_rms_[i] = sums.exx.stats("", "", "", "").rms;
  rings_.add_frame_coverage(sums.measured_triangles);
  std::swap(true_now_, true_before_);
  if (sums.valid_area > 0.0) {
    u_truth_[i] = depth_ * sums.truth_energy;
    u_other_[i] = depth_ * sums.other_energy;
    u_truth_increments_[i] = depth_ * sums.truth_increments_energy;
    u_truth_triangle_[i] = depth_ * sums.truth_triangle_energy;
    u_interior_[i] = depth_ * sums.interior_energy;
    u_truth_interior_[i] = depth_ * sums.interior_truth_energy;
    ratio_truth_[i] = sums.stuck_truth_area / sums.valid_area;
  }
  c_labels_[i] = std::sqrt(sums.stuck_area_mm2 / std::numbers::pi);
}

void FieldValidation::add_triangle(std::size_t i, std::size_t t, const samples::FrameField& field,
                                   const samples::LoadState& load, FrameSums& sums) {
  const std::size_t cell = t;  // in this frame's rows
  if (!std::isfinite(rows_.total[cell * 3])) return;
  std::array<Vec2, 3> X, x_true;
  for (std::size_t v = 0; v < 3; ++v) {
    const auto id = static_cast<std::size_t>(r_.triangles[t * 3 + v]);
    X[v] = vec(r_.reference, id);
    x_true[v] = true_now_[id];
  }
  const Vec2 centroid{(X[0].x + X[1].x + X[2].x) / 3.0, (X[0].y + X[1].y + X[2].y) / 3.0};
  const samples::FieldValue at = field.evaluate(centroid);
  const Strain2 e_point = green_lagrange(at.gradient);
  const double area_m2 = std::abs(strain::signed_area(X[0], X[1], X[2])) * m_per_px_ * m_per_px_;
  sums.truth_energy += plane_strain_energy_density_J_m3(e_point, young_, nu_) * area_m2;
  const Strain2 other_value = {rows_.other[cell * 3], rows_.other[cell * 3 + 1], rows_.other[cell * 3 + 2]};
  if (std::isfinite(other_value.xx))
    sums.other_energy += plane_strain_energy_density_J_m3(other_value, young_, nu_) * area_m2;
  sums.valid_area += area_m2;
  const bool truth_stuck = std::hypot(at.displacement_px.x - load.plate_px.x,
                                      at.displacement_px.y - load.plate_px.y) <= r_.tolerance_px;
  if (truth_stuck) sums.stuck_truth_area += area_m2;
  if (rows_.stuck[cell] == 1.0) sums.stuck_area_mm2 += area_m2 * 1e6;

  const Gradient2 h_true = strain::displacement_gradient(X, x_true);
  const Strain2 e_triangle = green_lagrange(h_true);
  const Strain2& sum_truth = advance_truth_increments(i, t, X, h_true, e_triangle);
  if (std::isfinite(incremental_total()[cell * 3]))
    sums.truth_increments_energy += plane_strain_energy_density_J_m3(sum_truth, young_, nu_) * area_m2;
  sums.truth_triangle_energy += plane_strain_energy_density_J_m3(e_triangle, young_, nu_) * area_m2;
  const Strain2 measured = {rows_.total[cell * 3], rows_.total[cell * 3 + 1], rows_.total[cell * 3 + 2]};
  const Vec2 current{centroid.x + at.displacement_px.x, centroid.y + at.displacement_px.y};
  rings_.add_triangle(current, {measured.xx - e_point.xx, measured.yy - e_point.yy, measured.xy - e_point.xy},
                      {rows_.total_sd[cell * 3], rows_.total_sd[cell * 3 + 1], rows_.total_sd[cell * 3 + 2]});
  std::array<Vec2, 3> x_measured;
  for (std::size_t v = 0; v < 3; ++v)
    x_measured[v] = vec(rows_.position, static_cast<std::size_t>(r_.triangles[t * 3 + v]));
  sums.measured_triangles.push_back(x_measured);
  if (trial_.contact_signed_distance_px(centroid) >= -border_px_ ||
      trial_.contact_signed_distance_px(current) >= -border_px_)
    return;
  sums.interior_energy += plane_strain_energy_density_J_m3(measured, young_, nu_) * area_m2;
  sums.interior_truth_energy += plane_strain_energy_density_J_m3(e_point, young_, nu_) * area_m2;
  add_interior_errors(cell, measured, e_point, e_triangle, sum_truth);
  sums.exx.add(measured.xx - e_point.xx);
}

// The paper's running sum of increments applied to the exact vertex positions, triangle by triangle and over
// the same frames as the measured sum (it starts at 0 on the reference frame, or at the exact total when the
// triangle joins later, and adds no increment for a frame in which the triangle is not valid or a vertex was
// not tracked in the frame before). Against it, the incremental mode's measurement error; against the point
// truth, how far the paper's definition itself lies from the exact Green–Lagrange strain.
const Strain2& FieldValidation::advance_truth_increments(std::size_t i, std::size_t t,
                                                         const std::array<Vec2, 3>& X,
                                                         const Gradient2& h_true, const Strain2& e_triangle) {
  Strain2& sum_truth = increments_truth_[t];
  if (!std::isfinite(incremental_total()[t * 3])) return sum_truth;
  if (!std::isfinite(sum_truth.xx)) {
    sum_truth = i == r_.reference_row ? Strain2{0.0, 0.0, 0.0} : e_triangle;
    return sum_truth;
  }
  // The strain stage adds an increment when all three vertices were tracked in the frame before.
  std::array<Vec2, 3> x_before;
  bool tracked_before = i > 0;
  for (std::size_t v = 0; v < 3 && tracked_before; ++v) {
    const auto id = static_cast<std::size_t>(r_.triangles[t * 3 + v]);
    tracked_before = std::isfinite(previous_position_[2 * id]);
    x_before[v] = true_before_[id];
  }
  if (tracked_before) {
    const Gradient2 h_before = strain::displacement_gradient(X, x_before);
    const Strain2 inc = green_lagrange(strain::incremental_gradient(h_true, h_before));
    sum_truth = {sum_truth.xx + inc.xx, sum_truth.yy + inc.yy, sum_truth.xy + inc.xy};
  }
  return sum_truth;
}

// An interior triangle's six quantities in both strain modes against both truths, and the strain gain.
void FieldValidation::add_interior_errors(std::size_t cell, const Strain2& measured, const Strain2& e_point,
                                          const Strain2& e_triangle, const Strain2& sum_truth) {
  const Strain2 measured_other = {rows_.other[cell * 3], rows_.other[cell * 3 + 1],
                                  rows_.other[cell * 3 + 2]};
  const auto truth_point = components(e_point, young_, nu_);
  const auto truth_triangle = components(e_triangle, young_, nu_);
  if (std::isfinite(sum_truth.xx)) {
    const std::vector<double>& inc_total = incremental_total();
    const Strain2 measured_incremental = {inc_total[cell * 3], inc_total[cell * 3 + 1],
                                          inc_total[cell * 3 + 2]};
    const auto c = components(measured_incremental, young_, nu_);
    const auto truth_increments = components(sum_truth, young_, nu_);
    for (int q = 0; q < kComponentCount; ++q) {
      const auto qi = static_cast<std::size_t>(q);
      acc(kComponents[q], "truth increments", "incremental").add(c[qi] - truth_increments[qi]);
      acc(kComponents[q], "point", "incremental of truth").add(truth_increments[qi] - truth_point[qi]);
    }
  }
  for (const auto& [m, value] : {std::pair{r_.mode, measured}, std::pair{r_.other_mode, measured_other}}) {
    const auto c = components(value, young_, nu_);
    for (int q = 0; q < kComponentCount; ++q) {
      const auto qi = static_cast<std::size_t>(q);
      acc(kComponents[q], "point", m).add(c[qi] - truth_point[qi]);
      acc(kComponents[q], "triangle", m).add(c[qi] - truth_triangle[qi]);
    }
  }
  // Least-squares gain of the measured strain on the truth (pooled components): 1 when the errors are
  // unbiased noise; a scale error shows here and in U as 2 × (gain − 1).
  for (const auto& [m_value, t_value] :
       {std::pair{measured.xx, e_point.xx}, std::pair{measured.yy, e_point.yy},
        std::pair{measured.xy, e_point.xy}}) {
    gain_mt_ += m_value * t_value;
    gain_tt_ += t_value * t_value;
  }
}

// The exact energy over the whole true contact, on the truth's grid.
void FieldValidation::add_contact_energy(std::size_t i) {
  const samples::GridTruth grid = trial_.grid_truth(static_cast<int>(i));
  const double step_px = trial_.config().truth.grid_step_px;
  const double cell_m2 = step_px * step_px * m_per_px_ * m_per_px_;
  double contact_energy = 0.0;
  for (std::size_t g = 0; g < grid.in_contact.size(); ++g)
    if (grid.in_contact[g]) contact_energy += grid.energy_J_m3[g] * cell_m2;
  u_truth_contact_[i] = depth_ * contact_energy;
}

// The strain stage's slip-profile fit on the exact displacements of the live tracks, with the true contact:
// what the estimator gives without tracking error (separates its bias from the tracks'); and on the tracked
// displacements with the true contact (separates the measured ellipse's share).
void FieldValidation::add_stick_fits(std::size_t i, const samples::FrameField& field) {
  if (!field.model()) return;
  const std::size_t k = r_.tracks;
  std::vector<Vec2> ref_px, exact_px, tracked_px;
  for (std::size_t j = 0; j < k; ++j) {
    if (!std::isfinite(rows_.position[2 * j])) continue;
    const Vec2 X = vec(r_.reference, j);
    const Vec2 u = field.displacement_px(X);
    ref_px.push_back(X);
    exact_px.push_back({X.x + u.x, X.y + u.y});
    tracked_px.push_back(vec(rows_.position, j));
  }
  const samples::LoadHistory& history = trial_.history();
  const strain::ContactDisk disk =
      strain::contact_disk(history.contact_centre_px(), history.contact_semi_axes_px().x,
                           history.contact_semi_axes_px().y, history.contact_angle_rad());
  c_exact_tracks_[i] = strain::fit_stick_zone(ref_px, exact_px, disk, nu_).radius_px / px_per_mm_;
  c_true_contact_[i] = strain::fit_stick_zone(ref_px, tracked_px, disk, nu_).radius_px / px_per_mm_;
}

void FieldValidation::finish() {
  finish_energy();
  finish_stick_radius();
}

// Energy: relative error on the frames carrying at least 10 % of the largest true energy, if that is at least
// the energy of a uniform strain of 1e-4 over the contact to the tissue depth. A rigid motion's true energy
// is rounding (1e-30 J), and relative to it every error read 1e28 %.
void FieldValidation::finish_energy() {
  const std::size_t n = r_.frames;
  const Vec2 semi_axes_px = trial_.history().contact_semi_axes_px();
  const double contact_m2 = std::numbers::pi * semi_axes_px.x * semi_axes_px.y * m_per_px_ * m_per_px_;
  const double u_floor = 0.5 * young_ * 1e-8 * contact_m2 * depth_;
  double u_max = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    if (std::isfinite(u_truth_[i]) && u_truth_[i] > u_max) {
      u_max = u_truth_[i];
      u_argmax_ = i;
    }
  const std::vector<double>& energy = r_.energy;
  for (std::size_t i = 0; i < n && u_max >= u_floor; ++i) {
    if (!(std::isfinite(u_truth_[i]) && u_truth_[i] >= 0.1 * u_max && std::isfinite(energy[i]))) continue;
    energy_error_.add(100.0 * (energy[i] - u_truth_[i]) / u_truth_[i]);
    if (std::isfinite(u_other_[i]))
      energy_other_error_.add(100.0 * (u_other_[i] - u_truth_[i]) / u_truth_[i]);
    const double u_incremental = r_.mode == "incremental" ? energy[i] : u_other_[i];
    if (std::isfinite(u_incremental) && u_truth_increments_[i] > 0.0)
      energy_increments_error_.add(100.0 * (u_incremental - u_truth_increments_[i]) / u_truth_increments_[i]);
    energy_triangle_error_.add(100.0 * (energy[i] - u_truth_triangle_[i]) / u_truth_triangle_[i]);
    if (u_truth_interior_[i] > 0.0)
      energy_interior_error_.add(100.0 * (u_interior_[i] - u_truth_interior_[i]) / u_truth_interior_[i]);
    if (u_truth_contact_[i] > 0.0)
      energy_contact_error_.add(100.0 * (energy[i] - u_truth_contact_[i]) / u_truth_contact_[i]);
  }
}

// Stick radius: frames in partial slip whose stick zone lies well inside the meshed interior and is not tiny
// (the tracks resolve neither a stick zone near the border nor one a few track spacings wide). The fitted c
// (/stick/radius_mm) is the reference row; the radius of the stuck labels' area is reported next to it; every
// frame once the plate moves (full slip c = 0 and c near a included) as an absolute error.
void FieldValidation::finish_stick_radius() {
  const double a_mm = trial_.history().contact_radius_m() * 1e3;
  const std::vector<double>& c_fit = r_.c_fit;
  for (std::size_t i = 0; i < r_.frames; ++i) {
    const double c = c_model_[i];
    if (c > 0.2 * a_mm && c < a_mm - 2.0 * options_.border_exclusion_mm) {
      if (std::isfinite(c_fit[i])) c_error_.add(100.0 * (c_fit[i] - c) / c);
      if (std::isfinite(c_labels_[i])) c_label_error_.add(100.0 * (c_labels_[i] - c) / c);
      if (std::isfinite(c_exact_tracks_[i])) c_exact_error_.add(100.0 * (c_exact_tracks_[i] - c) / c);
      if (std::isfinite(c_true_contact_[i])) c_true_contact_error_.add(100.0 * (c_true_contact_[i] - c) / c);
    }
    if (trial_.load(static_cast<int>(i)).tangential_N > 0.0 && std::isfinite(c_fit[i]))
      c_all_error_.add(c_fit[i] - c);
    // Every frame in partial slip, in % of the contact radius.
    if (c > 0.0 && c < a_mm && std::isfinite(c_fit[i])) c_of_a_error_.add(100.0 * (c_fit[i] - c) / a_mm);
    // Where slip was not seen within the tracks: how far inside their reach the model's slip annulus began,
    // % of a (> 0: slip the fit did not detect among the outermost tracks).
    if (std::isfinite(r_.c_reach[i])) c_unseen_.add(100.0 * (r_.c_reach[i] - c) / a_mm);
  }
}

void FieldValidation::append_rows(std::vector<ErrorStats>& rows) const {
  for (const std::string& m : {r_.mode, r_.other_mode})
    for (const char* reference_name : {"point", "triangle"})
      for (int q = 0; q < kComponentCount; ++q)
        rows.push_back(acc_or_empty(kComponents[q], reference_name, m)
                           .stats(kComponents[q], reference_name, m, q == 5 ? "J/m3" : ""));
  for (const auto& [reference_name, m] :
       {std::pair{"truth increments", "incremental"}, std::pair{"point", "incremental of truth"}})
    for (int q = 0; q < kComponentCount; ++q)
      rows.push_back(acc_or_empty(kComponents[q], reference_name, m)
                         .stats(kComponents[q], reference_name, m, q == 5 ? "J/m3" : ""));
  rows.push_back(displacement_.stats("displacement", "tracks", "", "px"));
  rows.push_back(displacement_interior_.stats("displacement_interior", "tracks", "", "px"));
  // Where the error lives: the ridge contrast fades near the border, and there the ridges often run along it.
  rows.push_back(displacement_by_depth_[0].stats("displacement_border_0-0.5mm", "tracks", "", "px"));
  rows.push_back(displacement_by_depth_[1].stats("displacement_border_0.5-1mm", "tracks", "", "px"));
  rows.push_back(displacement_by_depth_[2].stats("displacement_beyond_1mm", "tracks", "", "px"));
  rows.push_back(plate_error_.stats("plate_displacement", "truth", "", "px"));
  rows.push_back(energy_error_.stats("U", "same triangles", r_.mode, "%"));
  rows.push_back(energy_other_error_.stats("U", "same triangles", r_.other_mode, "%"));
  rows.push_back(energy_increments_error_.stats("U", "truth increments", "incremental", "%"));
  ErrorStats gain{"strain_gain", "point", r_.mode, "", kNaN, kNaN, kNaN, 0};
  if (gain_tt_ > 0.0) gain.rms = gain.mean = gain_mt_ / gain_tt_;
  gain.samples = acc_or_empty("E_xx", "point", r_.mode).n;
  rows.push_back(gain);
  rows.push_back(energy_triangle_error_.stats("U_triangle_truth", "same triangles", r_.mode, "%"));
  rows.push_back(energy_interior_error_.stats("U_interior", "interior triangles", r_.mode, "%"));
  rows.push_back(energy_contact_error_.stats("U_whole_contact", "truth grid", r_.mode, "%"));
  rows.push_back(stick_error_.stats("stick_ratio", "same triangles", "", ""));
  rows.push_back(c_error_.stats("stick_radius_c", "model", "", "%"));
  rows.push_back(c_label_error_.stats("stick_radius_c_labels", "model", "", "%"));
  rows.push_back(c_exact_error_.stats("stick_radius_c_exact_tracks", "model", "", "%"));
  rows.push_back(c_true_contact_error_.stats("stick_radius_c_true_contact", "model", "", "%"));
  rows.push_back(c_all_error_.stats("stick_radius_c_all_frames", "model", "", "mm"));
  rows.push_back(c_of_a_error_.stats("stick_radius_c_of_a", "model", "", "%"));
  rows.push_back(c_unseen_.stats("stick_radius_c_beyond_tracks", "tracks reach", "", "%"));
}

void FieldValidation::write_frames_csv(const std::string& path,
                                       const std::vector<std::array<double, 4>>& contact) const {
  CsvWriter csv(path, {"index",
                       "t_s",
                       "U_J",
                       "U_truth_J",
                       "U_truth_contact_J",
                       "U_truth_triangle_J",
                       "U_interior_J",
                       "U_truth_interior_J",
                       "stick_ratio",
                       "stick_ratio_truth",
                       "c_mm",
                       "c_unmeasured_reach_mm",
                       "c_labels_mm",
                       "c_model_mm",
                       "displacement_rms_px",
                       "E_xx_rms",
                       "contact_iou",
                       "contact_centre_error_px",
                       "contact_semi_major_error_pct",
                       "contact_semi_minor_error_pct"});
  for (std::size_t i = 0; i < r_.frames; ++i) {
    std::vector<std::string> row = {std::to_string(i)};
    for (const double v :
         {r_.t_s[i], r_.energy[i], u_truth_[i], u_truth_contact_[i], u_truth_triangle_[i], u_interior_[i],
          u_truth_interior_[i], r_.stick_ratio[i], ratio_truth_[i], r_.c_fit[i], r_.c_reach[i], c_labels_[i],
          c_model_[i], disp_rms_[i], exx_rms_[i], contact[i][0], contact[i][1], contact[i][2], contact[i][3]})
      row.push_back(format_double(v));
    csv.row_text(row);
  }
  csv.commit();
}

}  // namespace tirstrain::pipeline
