#include "fit/fit_result.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/median.hpp"
#include "core/scene.hpp"
#include "fit/fit_plots.hpp"

namespace tirstrain::fit {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string result_file(const std::string& result) {
  const fs::path p(result);
  return fs::is_directory(p) ? (p / "result.h5").string() : p.string();
}

std::vector<double> require(const H5Reader& h5, const std::string& name, const std::string& why,
                            H5Shape* shape = nullptr) {
  if (!h5.has(name)) throw Error("no " + name + " in the result (" + why + ")", {.file = h5.path()});
  return h5.read_doubles(name, shape);
}

void read_contacts(const H5Reader& h5, ResultForFit& r) {
  const std::vector<double> e = require(h5, "/contact/ellipse", "the contact stage writes it");
  if (e.size() != 5 * r.frames())
    throw Error("/contact/ellipse has " + std::to_string(e.size() / 5) + " rows for " +
                    std::to_string(r.frames()) + " frames",
                {.file = h5.path()});
  // Each frame's own centre where the contact stage smoothed it in time after the trial: the fit stage
  // fits while the frames are read, before that, and the two must give the same numbers.
  std::vector<double> measured;
  if (h5.has("/contact/centre_measured_px")) measured = h5.read_doubles("/contact/centre_measured_px");
  if (!measured.empty() && measured.size() != 2 * r.frames())
    throw Error("/contact/centre_measured_px has " + std::to_string(measured.size() / 2) + " rows for " +
                    std::to_string(r.frames()) + " frames",
                {.file = h5.path()});
  for (std::size_t i = 0; i < r.frames(); ++i) {
    const double* row = &e[5 * i];
    const bool has = row[2] > 0.0 && row[3] > 0.0;
    const double cx = has && !measured.empty() ? measured[2 * i] : row[0];
    const double cy = has && !measured.empty() ? measured[2 * i + 1] : row[1];
    r.ellipse.push_back({cx, cy, row[2], row[3], row[4]});
    r.has_contact.push_back(has ? 1 : 0);
  }
}

void read_tracks(const H5Reader& h5, ResultForFit& r) {
  const std::string why = "processed without the tracking stage? run process with compute: [tracking]";
  H5Shape shape;
  const std::vector<double> ref = require(h5, "/tracks/reference_px", why, &shape);
  for (std::size_t k = 0; k + 1 < ref.size(); k += 2) r.reference_px.push_back({ref[k], ref[k + 1]});
  r.position_px = require(h5, "/tracks/position_px", why, &shape);
  if (r.position_px.size() != r.frames() * r.tracks() * 2)
    throw Error("/tracks/position_px is not [frames, tracks, 2] = [" + std::to_string(r.frames()) + ", " +
                    std::to_string(r.tracks()) + ", 2]",
                {.file = h5.path()});
}

// Calibration and tissue from the scene the result was computed with (root attribute scene_yaml).
void read_scene(const H5Reader& h5, ResultForFit& r) {
  const Scene scene = parse_scene_text(h5.attribute_text("/", "scene_yaml"), h5.path() + " scene_yaml");
  r.px_per_mm = scene.px_per_mm;
  r.young_Pa = scene.tissue.young_Pa;
  r.poisson = scene.tissue.poisson;
}

// A force channel at the frames (NaN outside its span); empty when the result has none.
std::vector<double> channel_at_frames(const H5Reader& h5, const std::string& name) {
  if (!h5.has(name) || !h5.has("/channels/at_frames/in_span")) return {};
  std::vector<double> v = h5.read_doubles(name);
  const std::vector<double> in_span = h5.read_doubles("/channels/at_frames/in_span");
  for (std::size_t i = 0; i < v.size() && i < in_span.size(); ++i)
    if (in_span[i] == 0.0) v[i] = kNaN;
  return v;
}

void read_channel(const H5Reader& h5, ResultForFit& r) {
  r.tangential_channel_N = channel_at_frames(h5, "/channels/at_frames/tangential_force_N");
  r.normal_channel_N = channel_at_frames(h5, "/channels/at_frames/normal_force_N");
}

// μ = fitted μP over the measured normal load, where both exist.
double friction(const ResultForFit& r, std::size_t i, const FrameFit& f) {
  if (i >= r.normal_channel_N.size() || !(r.normal_channel_N[i] > 0.0)) return kNaN;
  return f.limit_N.value / r.normal_channel_N[i];
}

// Cells: full precision, empty where the value does not exist.
std::string cell(double v) {
  return std::isfinite(v) ? format_double(v) : std::string();
}

const char* const kModelNames[kFieldModels] = {"rest", "full_stick", "partial_slip", "full_slip"};

std::vector<std::string> csv_header() {
  std::vector<std::string> h = {"frame", "t_s", "status", "model", "tracks"};
  for (const char* q :
       {"centre_x_px", "centre_y_px", "direction_deg", "a_mm", "c_mm", "tangential_N", "limit_N"}) {
    h.emplace_back(q);
    h.push_back(std::string(q) + "_sd");
  }
  for (const char* q : {"tangential_channel_N", "residual_rms_px", "aic", "bic"}) h.emplace_back(q);
  for (const char* c : {"aic_", "bic_"})
    for (const char* m : kModelNames) h.push_back(std::string(c) + m);
  for (const char* q : {"tracked_radius", "limit_from_trial", "normal_channel_N", "friction"})
    h.emplace_back(q);
  return h;
}

bool fitted(const FrameFit& f) {
  return f.status == FitStatus::ok || f.status == FitStatus::no_covariance;
}

std::vector<std::string> csv_row(std::size_t i, const ResultForFit& r, const FrameFit& f) {
  const bool ok = fitted(f);
  std::vector<std::string> row = {std::to_string(i), cell(r.t_s[i]), fit_status_name(f.status),
                                  ok ? field_model_name(f.model) : "", std::to_string(f.tracks_used)};
  for (const Estimate* e :
       {&f.centre_x_px, &f.centre_y_px, &f.direction_deg, &f.a_mm, &f.c_mm, &f.tangential_N, &f.limit_N}) {
    row.push_back(cell(e->value));
    row.push_back(cell(e->sd));
  }
  row.push_back(r.tangential_channel_N.empty() ? "" : cell(r.tangential_channel_N[i]));
  row.push_back(cell(f.residual_rms_px));
  const int m = static_cast<int>(f.model);
  row.push_back(ok ? cell(f.aic[m]) : "");
  row.push_back(ok ? cell(f.bic[m]) : "");
  for (const auto* crit : {&f.aic, &f.bic})
    for (int k = 0; k < kFieldModels; ++k) row.push_back(cell((*crit)[k]));
  row.push_back(ok ? cell(f.tracked_radius) : "");
  row.push_back(ok ? (f.limit_from_trial ? "1" : "0") : "");
  row.push_back(r.normal_channel_N.empty() ? "" : cell(r.normal_channel_N[i]));
  row.push_back(ok ? cell(friction(r, i, f)) : "");
  return row;
}

void write_csv(const std::string& path, const ResultForFit& r, const std::vector<FrameFit>& fits) {
  CsvWriter csv(path, csv_header());
  for (std::size_t i = 0; i < fits.size(); ++i) csv.row_text(csv_row(i, r, fits[i]));
  csv.commit();
}

void write_estimate(H5Writer& h5, const std::string& name, const std::vector<FrameFit>& fits,
                    Estimate FrameFit::*member) {
  std::vector<double> v, sd;
  for (const FrameFit& f : fits) {
    v.push_back((f.*member).value);
    sd.push_back((f.*member).sd);
  }
  h5.write("/fit/" + name, v, {v.size()});
  h5.write("/fit/" + name + "_sd", sd, {sd.size()});
}

void write_per_frame(H5Writer& h5, const ResultForFit& r, const std::vector<FrameFit>& fits) {
  const std::size_t n = fits.size();
  std::vector<std::int64_t> frame(n);
  std::vector<std::int32_t> status(n), model(n), tracks(n), from_trial(n);
  std::vector<double> rms(n), shared(n), aic(n), bic(n), reach(n), aic_all, bic_all;
  for (std::size_t i = 0; i < n; ++i) {
    const FrameFit& f = fits[i];
    const int m = static_cast<int>(f.model);
    frame[i] = static_cast<std::int64_t>(i);
    status[i] = static_cast<std::int32_t>(f.status);
    model[i] = fitted(f) ? m : -1;
    tracks[i] = f.tracks_used;
    rms[i] = f.residual_rms_px;
    shared[i] = fitted(f) ? f.shared_residuals : kNaN;
    aic[i] = fitted(f) ? f.aic[m] : kNaN;
    bic[i] = fitted(f) ? f.bic[m] : kNaN;
    reach[i] = fitted(f) ? f.tracked_radius : kNaN;
    from_trial[i] = fitted(f) && f.limit_from_trial ? 1 : 0;
    aic_all.insert(aic_all.end(), f.aic.begin(), f.aic.end());
    bic_all.insert(bic_all.end(), f.bic.begin(), f.bic.end());
  }
  h5.write("/fit/frame", frame, {n});
  h5.write("/fit/t_s", r.t_s, {n});
  h5.write("/fit/status", status, {n});
  h5.write("/fit/model", model, {n});
  h5.write("/fit/tracks", tracks, {n});
  h5.write("/fit/residual_rms_px", rms, {n});
  h5.write("/fit/shared_residuals", shared, {n});
  h5.write("/fit/aic", aic, {n});
  h5.write("/fit/bic", bic, {n});
  h5.write("/fit/aic_by_model", aic_all, {n, kFieldModels});
  h5.write("/fit/bic_by_model", bic_all, {n, kFieldModels});
  h5.write("/fit/tracked_radius", reach, {n});
  h5.write("/fit/limit_from_trial", from_trial, {n});
  if (!r.tangential_channel_N.empty()) h5.write("/fit/tangential_channel_N", r.tangential_channel_N, {n});
  if (!r.normal_channel_N.empty()) {
    std::vector<double> mu(n);
    for (std::size_t i = 0; i < n; ++i) mu[i] = fitted(fits[i]) ? friction(r, i, fits[i]) : kNaN;
    h5.write("/fit/normal_channel_N", r.normal_channel_N, {n});
    h5.write("/fit/friction", mu, {n});
  }
}

void write_residuals(H5Writer& h5, const ResultForFit& r, const std::vector<FrameFit>& fits) {
  const std::size_t k = r.tracks();
  std::vector<double> res;
  res.reserve(fits.size() * k * 2);
  for (const FrameFit& f : fits)
    for (const Vec2& v : f.residual_px) {
      res.push_back(v.x);
      res.push_back(v.y);
    }
  h5.write("/fit/residual_px", res, {fits.size(), k, 2});
  std::vector<double> ref;
  for (const Vec2& v : r.reference_px) {
    ref.push_back(v.x);
    ref.push_back(v.y);
  }
  h5.write("/fit/track_reference_px", ref, {k, 2});
}

void write_h5(const std::string& path, const ResultForFit& r, const FitRun& run, const FitOptions& options) {
  const std::vector<FrameFit>& fits = run.frames;
  H5Writer h5(path);
  write_per_frame(h5, r, fits);
  const std::pair<const char*, Estimate FrameFit::*> estimates[] = {
      {"centre_x_px", &FrameFit::centre_x_px},
      {"centre_y_px", &FrameFit::centre_y_px},
      {"direction_deg", &FrameFit::direction_deg},
      {"a_mm", &FrameFit::a_mm},
      {"c_mm", &FrameFit::c_mm},
      {"tangential_N", &FrameFit::tangential_N},
      {"limit_N", &FrameFit::limit_N}};
  for (const auto& [name, member] : estimates) write_estimate(h5, name, fits, member);
  write_residuals(h5, r, fits);
  h5.attribute("/", "format", "tirstrain fit");
  h5.attribute("/", "format_version", 1.0);
  h5.attribute("/", "result", r.result_path);
  h5.attribute("/fit", "model_codes", "-1 not fitted, 0 rest, 1 full_stick, 2 partial_slip, 3 full_slip");
  h5.attribute("/fit", "status_codes", "0 ok, 1 no_contact, 2 too_few_tracks, 3 no_covariance");
  h5.attribute("/fit", "criteria_columns", "rest, full_stick, partial_slip, full_slip");
  h5.attribute("/fit", "px_per_mm", r.px_per_mm);
  h5.attribute("/fit", "young_Pa", r.young_Pa);
  h5.attribute("/fit", "poisson", r.poisson);
  h5.attribute("/fit", "loss_scale_px", options.loss_scale_px);
  h5.attribute("/fit", "rest_tolerance_px", options.rest_tolerance_px);
  h5.attribute("/fit", "min_tracks", static_cast<double>(options.min_tracks));
  h5.attribute("/fit", "contact_margin", options.contact_margin);
  h5.attribute("/fit", "trial_limit_N", run.trial_limit ? run.trial_limit->limit_N : kNaN);
  h5.attribute("/fit", "trial_limit_sd_N", run.trial_limit ? run.trial_limit->sd_N : kNaN);
  h5.attribute("/fit", "trial_limit_frames",
               run.trial_limit ? static_cast<double>(run.trial_limit->frames) : 0.0);
  h5.commit();
}

// OUT is replaced as a whole: refuse one that holds the result or anything a fit run does not write.
void check_out_dir(const std::string& out_dir, const ResultForFit& r) {
  if (path_is_within(r.result_path, out_dir))
    throw Error("--out " + out_dir + " holds the result being fitted; choose another folder",
                {.key = "--out"});
  // Beside the result, never in it: `process` replaces its folder as a whole and refuses one holding
  // files it does not write, so a fit inside would block the next run there.
  const fs::path result_folder = fs::path(r.result_path).parent_path();
  if (!result_folder.empty() && path_is_within(out_dir, result_folder.string()))
    throw Error("--out " + out_dir + " lies inside the result folder " + result_folder.string() +
                    "; write the fit beside it",
                {.key = "--out"});
  if (!fs::exists(out_dir)) return;
  if (!fs::is_directory(out_dir)) throw Error("--out " + out_dir + " is not a folder", {.key = "--out"});
  for (const auto& entry : fs::directory_iterator(out_dir)) {
    const std::string name = entry.path().filename().string();
    const bool ours =
        name == "fit.csv" || name == "fit.h5" || name == "c_q_vs_time.png" || name.rfind("residual_", 0) == 0;
    if (!ours)
      throw Error("--out " + out_dir + " holds " + name +
                      ", which replacing the folder would delete; choose an empty folder or an earlier fit's",
                  {.key = "--out"});
  }
}

// Frames `frames` of `result` fitted (with `limit` when given) into fits[frame], in parallel.
void fit_frames_in_parallel(const ResultForFit& result, const RunOptions& options, const TrialLimit* limit,
                            const std::vector<std::size_t>& frames, std::vector<FrameFit>& fits) {
  std::atomic<std::size_t> next{0};
  std::exception_ptr failure;
  std::atomic<bool> failed{false};
  auto worker = [&] {
    for (std::size_t j = next++; j < frames.size() && !failed; j = next++) {
      try {
        fits[frames[j]] = fit_frame(result.frame(frames[j]), options.fit, limit);
      } catch (...) {
        if (!failed.exchange(true)) failure = std::current_exception();
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, options.frame_threads); ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

}  // namespace

FrameObservations ResultForFit::frame(std::size_t i) const {
  FrameObservations o;
  o.reference_px = reference_px;
  o.displacement_px.resize(tracks());
  for (std::size_t k = 0; k < tracks(); ++k) {
    const double* p = &position_px[(i * tracks() + k) * 2];
    o.displacement_px[k] = {p[0] - reference_px[k].x, p[1] - reference_px[k].y};
  }
  o.has_contact = has_contact[i] != 0;
  o.contact = ellipse[i];
  o.px_per_mm = px_per_mm;
  o.young_Pa = young_Pa;
  o.poisson = poisson;
  return o;
}

ResultForFit read_result_for_fit(const std::string& result) {
  ResultForFit r;
  r.result_path = result_file(result);
  if (!fs::is_regular_file(r.result_path))
    throw Error("no result.h5 here (a `tirstrain process` output folder is expected)",
                {.file = r.result_path});
  const H5Reader h5(r.result_path);
  r.t_s = require(h5, "/frames/t_s", "not a tirstrain process result?");
  read_contacts(h5, r);
  read_tracks(h5, r);
  read_scene(h5, r);
  read_channel(h5, r);
  return r;
}

FitRun fit_result(const ResultForFit& result, const RunOptions& options) {
  FitRun run;
  run.frames = fit_each_frame(result, options);
  if (options.trial_limit) run.trial_limit = trial_limit(run.frames);
  if (run.trial_limit) refit_at_trial_limit(result, options, *run.trial_limit, run.frames);
  return run;
}

std::vector<FrameFit> fit_each_frame(const ResultForFit& result, const RunOptions& options) {
  std::vector<std::size_t> all(result.frames());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  std::vector<FrameFit> fits(result.frames());
  fit_frames_in_parallel(result, options, nullptr, all, fits);
  return fits;
}

std::optional<TrialLimit> trial_limit(const std::vector<FrameFit>& fits) {
  std::vector<double> limits, sds;
  for (const FrameFit& f : fits) {
    if (f.status != FitStatus::ok || f.model != FieldModel::partial_slip || f.limit_from_trial) continue;
    const double c_over_a = f.c_mm.value / f.a_mm.value;
    if (!(c_over_a >= kResolvedStick && c_over_a <= f.tracked_radius - kResolvedAnnulus)) continue;
    if (!(std::isfinite(f.limit_N.value) && f.limit_N.value > 0.0 && std::isfinite(f.limit_N.sd))) continue;
    limits.push_back(f.limit_N.value);
    sds.push_back(f.limit_N.sd);
  }
  if (limits.empty()) return std::nullopt;
  TrialLimit limit;
  limit.frames = static_cast<int>(limits.size());
  limit.limit_N = median(limits);
  std::vector<double> deviation;
  for (const double v : limits) deviation.push_back(std::abs(v - limit.limit_N));
  const double spread = std::max(median(sds), 1.4826 * median(deviation));
  limit.sd_N = spread / std::sqrt(static_cast<double>(limits.size()));
  return limit;
}

bool refits_at_trial_limit(const FrameFit& fit) {
  return fitted(fit) && (fit.model == FieldModel::full_stick || fit.model == FieldModel::partial_slip) &&
         !fit.limit_from_trial;
}

std::vector<std::size_t> refit_at_trial_limit(const ResultForFit& result, const RunOptions& options,
                                              const TrialLimit& limit, std::vector<FrameFit>& fits) {
  std::vector<std::size_t> frames;
  for (std::size_t i = 0; i < fits.size(); ++i)
    if (refits_at_trial_limit(fits[i])) frames.push_back(i);
  fit_frames_in_parallel(result, options, &limit, frames, fits);
  return frames;
}

void write_fit_outputs(const std::string& out_dir, const ResultForFit& result, const FitRun& fits,
                       const FitOptions& options) {
  check_out_dir(out_dir, result);
  StagingDirectory staging(out_dir);
  write_csv((fs::path(staging.path()) / "fit.csv").string(), result, fits.frames);
  write_h5((fs::path(staging.path()) / "fit.h5").string(), result, fits, options);
  write_fit_plots(staging.path(), result, fits.frames);
  staging.commit();
}

}  // namespace tirstrain::fit
