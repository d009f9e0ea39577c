#include "pipeline/strain_stage.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>

#include "core/csv.hpp"
#include "core/heatmap.hpp"
#include "strain/evolving_mesh.hpp"
#include "strain/normalised_map.hpp"
#include "strain/settings.hpp"
#include "strain/stick_zone.hpp"
#include "strain/uncertainty.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using strain::Triangle;
// /mesh/status for a triangle that is not part of a frame's mesh.
constexpr std::uint8_t kNotInMesh = 255;
// Per-triangle and map values are stored as float32: 7 significant digits (strains to 1e-7 and better)
// are far below their measurement noise, and they are half the file. Computed in double.
constexpr H5Precision kStored = H5Precision::kFloat32;
// /strain/source bits: where a triangle's strain is partly a model rather than matches.
constexpr std::uint8_t kSourceExtrapolatedReference = 1;  // a vertex's reference position is extrapolated
constexpr std::uint8_t kSourceVertexModel = 2;  // a vertex reports a model this frame (/tracks/model)

// Per active triangle of a frame, in this order (NaN where the triangle was not usable).
enum Value : int {
  kExx,
  kEyy,
  kExy,
  kOtherExx,
  kOtherEyy,
  kOtherExy,
  kRateXx,
  kRateYy,
  kRateXy,
  kRotation,
  kEnergy,
  kSdXx,  // predicted standard deviations of the total strain (strain/uncertainty.hpp)
  kSdYy,
  kSdXy,
  kValueCount
};

struct StrainFrame {
  bool computed = false;
  std::vector<std::int32_t> active;  // union triangle indices
  std::vector<std::uint8_t> status;  // strain::TriangleStatus per active triangle
  std::vector<std::int8_t> stuck;
  std::vector<std::uint8_t> sources;  // per active triangle: kSource* bits of its vertices
  std::vector<double> values;         // active.size() × kValueCount
  strain::TriangleCounts counts;
  double energy_J = kNaN;
  double stick_ratio = kNaN;
  strain::StickZoneFit stick_zone;  // stick radius c from the Cattaneo–Mindlin slip-profile fit
  double t_s = kNaN;

  // Once written to result.h5 and drawn, only the scalars are kept (frames.csv, summary.json, dU/dt).
  void archive(Archive& a) {
    a.layout(sizeof(strain::StickZoneFit), "stick zone fit");
    a(computed, active, status, stuck, sources, values, counts, energy_J, stick_ratio, stick_zone, t_s);
  }

  void drop_arrays() {
    // Swapped with empty vectors: assigning {} would keep their capacity.
    std::vector<std::int32_t>().swap(active);
    std::vector<std::uint8_t>().swap(status);
    std::vector<std::int8_t>().swap(stuck);
    std::vector<std::uint8_t>().swap(sources);
    std::vector<double>().swap(values);
  }
};

bool finite(const Strain2& e) {
  return std::isfinite(e.xx) && std::isfinite(e.yy) && std::isfinite(e.xy);
}

class StrainStage final : public Stage {
 public:
  explicit StrainStage(const Scene& scene) : settings_(strain::parse_strain_options(scene)) {}

  std::string name() const override { return "strain"; }

  void start(const TrialInfo& info) override {
    keep_history_ = info.keep_history;
    out_ = info.out;
  }

  void archive(Archive& a) override {
    a(mesh_, reference_normalization_, reference_has_ellipse_, disk_, reference_px_, current_px_,
      previous_px_, covariance_px2_, vertex_source_, alive_, incremental_, previous_t_s_, frames_, strain_s_,
      strained_frames_);
  }

  void process(FrameContext& context) override {
    StrainFrame record;
    record.t_s = context.frame ? context.frame->device_time_s : kNaN;
    if (!context.tracking) {
      keep(std::move(record));
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const bool reference_frame = context.tracking->reference_frame;
    if (reference_frame) take_reference(*context.tracking);
    gather_vertices(*context.tracking->tracks);
    mesh_.update(alive_, reference_px_);
    previous_px_.resize(reference_px_.size(), Vec2{kNaN, kNaN});
    const strain::FrameStrain fs = frame_strain(context, record.t_s);
    fill_record(record, fs, reference_frame);
    if (reference_has_ellipse_)
      record.stick_zone = strain::fit_stick_zone(reference_px_, unsmoothed_px_, disk_,
                                                 settings_.strain.poisson, settings_.stick_zone);
    if (std::isfinite(record.energy_J)) context.strain_energy_J = record.energy_J;

    previous_px_ = current_px_;
    previous_t_s_ = record.t_s;
    strain_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++strained_frames_;
    keep(std::move(record));
  }

  void draw(cv::Mat& bgr, const FrameContext& context, const OverlayText& overlay) const override {
    if (!context.tracking || frames_.empty() || !frames_.back().computed) return;
    const StrainFrame& f = frames_.back();
    const bool energy = settings_.overlay == "energy";
    cv::Mat layer = bgr.clone();
    constexpr int kShift = 4;
    const auto fixed = [](const Vec2& p) {
      return cv::Point(static_cast<int>(std::lround(p.x * (1 << kShift))),
                       static_cast<int>(std::lround(p.y * (1 << kShift))));
    };
    for (std::size_t t = 0; t < f.active.size(); ++t) {
      const double value = overlay_value(&f.values[t * kValueCount]);
      if (!std::isfinite(value)) continue;
      const Triangle& tri = mesh_.triangles()[static_cast<std::size_t>(f.active[t])];
      const cv::Point pts[3] = {fixed(current_px_[static_cast<std::size_t>(tri[0])]),
                                fixed(current_px_[static_cast<std::size_t>(tri[1])]),
                                fixed(current_px_[static_cast<std::size_t>(tri[2])])};
      const double range = settings_.overlay_range;
      const cv::Vec3b c =
          energy ? sequential_colour(value / range) : diverging_colour(0.5 + 0.5 * value / range);
      cv::fillConvexPoly(layer, pts, 3, cv::Scalar(c[0], c[1], c[2]), cv::LINE_8, kShift);
    }
    cv::addWeighted(bgr, 0.45, layer, 0.55, 0.0, bgr);
    draw_colour_bar(bgr, energy, overlay);
    char text[200];
    std::snprintf(text, sizeof text, "strain (%s): %d triangles, %d excluded  U = %.3g uJ  stick %.2f",
                  strain::to_string(settings_.mode), f.counts.valid, f.counts.excluded(), f.energy_J * 1e6,
                  f.stick_ratio);
    overlay.status_line(bgr, 3, text);
  }

  std::vector<std::string> csv_header() const override {
    return {"triangles_valid", "triangles_excluded", "strain_energy_J", "stick_ratio", "stick_radius_mm"};
  }

  void csv_row(std::size_t row, std::vector<std::string>& cells) const override {
    const StrainFrame& f = frames_.at(row);
    cells.push_back(std::to_string(f.counts.valid));
    cells.push_back(std::to_string(f.counts.excluded()));
    cells.push_back(format_double(f.energy_J));
    cells.push_back(format_double(f.stick_ratio));
    cells.push_back(format_double(stick_radius_mm(f)));
  }

  // What is not per frame (the union mesh), the energy rate from the kept energies, and the attributes; the
  // per-frame rows are written as frames are done.
  void write(H5Stream& out) const override {
    const auto& triangles = mesh_.triangles();
    const std::size_t t_count = triangles.size();
    std::vector<std::int32_t> mesh(t_count * 3);
    for (std::size_t t = 0; t < t_count; ++t)
      for (int v = 0; v < 3; ++v)
        mesh[t * 3 + static_cast<std::size_t>(v)] = triangles[t][static_cast<std::size_t>(v)];
    out.write("/mesh/triangles", std::span<const std::int32_t>(mesh), {t_count, 3});
    const std::vector<double> energy_rate = energy_rate_W();
    out.write("/energy/rate_W", std::span<const double>(energy_rate), {energy_rate.size()});
    write_attributes(out);
  }

  // The reference frame's normalisation, and its contact as a disk map for the stick-radius fit: centre,
  // axes and angle of the normalisation (q = s R(−φ)(X − centre), semi-major 1/s, semi-minor aspect/s).
  void take_reference(const FrameContext::Tracking& tracking) {
    reference_normalization_ = *tracking.reference_normalization;
    reference_has_ellipse_ = tracking.reference_has_ellipse;
    const cv::Matx23d m = reference_normalization_.forward_matrix();
    const double scale = reference_normalization_.scale_per_px();
    const cv::Point2d centre = reference_normalization_.denormalize({0.0, 0.0});
    disk_ = reference_has_ellipse_ ? strain::contact_disk({centre.x, centre.y}, 1.0 / scale,
                                                          reference_normalization_.aspect() / scale,
                                                          std::atan2(m(0, 1), m(0, 0)))
                                   : strain::ContactDisk{};
  }

  // A track's own match where the local fit stands in for it; otherwise what it reports (the own match, or
  // the neighbour fusion on low-SNR texture, where a subset slides along its ridges and the fusion is the
  // better evidence).
  static Vec2 unsmoothed_position(const flow::Track& t) {
    const bool own = std::isfinite(t.own_position_px.x) && std::isfinite(t.own_position_px.y);
    return t.model == flow::TrackModel::kLocalFit && own ? t.own_position_px : t.position_px;
  }

  // Every track's reference position; the alive ones' current and unsmoothed positions, covariance and
  // source bits.
  void gather_vertices(const std::vector<flow::Track>& tracks) {
    reference_px_.resize(tracks.size());
    current_px_.assign(tracks.size(), Vec2{kNaN, kNaN});
    unsmoothed_px_.assign(tracks.size(), Vec2{kNaN, kNaN});
    covariance_px2_.assign(tracks.size(), {kNaN, kNaN, kNaN});
    vertex_source_.assign(tracks.size(), 0);
    alive_.clear();
    for (std::size_t k = 0; k < tracks.size(); ++k) {
      reference_px_[k] = tracks[k].reference_px;
      if (flow::is_alive(tracks[k].status)) {
        current_px_[k] = tracks[k].position_px;
        unsmoothed_px_[k] = unsmoothed_position(tracks[k]);
        covariance_px2_[k] = tracks[k].covariance_px2;
        vertex_source_[k] = vertex_source(tracks[k]);
        alive_.push_back(static_cast<std::int32_t>(k));
      }
    }
  }

  strain::FrameStrain frame_strain(const FrameContext& context, double t_s) const {
    strain::FrameInput input;
    input.triangles = mesh_.active_triangles();
    input.reference_px = reference_px_;
    input.current_px = current_px_;
    if (!context.tracking->reference_frame) input.previous_px = previous_px_;
    input.dt_s = t_s - previous_t_s_;
    if (context.plate_displacement_px) {
      input.plate_known = true;
      input.plate_displacement_px = *context.plate_displacement_px;
    }
    return strain::compute_frame_strain(input, settings_.strain);
  }

  // The frame's per-triangle values (in the order of Value) and its energy U.
  void fill_record(StrainFrame& record, const strain::FrameStrain& fs, bool reference_frame) {
    const std::size_t n = mesh_.active().size();
    record.computed = true;
    record.active = mesh_.active();
    record.status.resize(n);
    record.stuck = fs.stuck;
    record.sources.assign(n, 0);
    record.values.assign(n * kValueCount, kNaN);
    record.counts = fs.counts;
    incremental_.resize(mesh_.triangles().size(), Strain2{kNaN, kNaN, kNaN});
    const double m_per_px = 1.0e-3 / settings_.strain.px_per_mm;
    double energy = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      record.status[t] = static_cast<std::uint8_t>(fs.status[t]);
      if (fs.status[t] != strain::TriangleStatus::kValid) continue;
      const Strain2& sum = running_sum(static_cast<std::size_t>(record.active[t]), fs, t, reference_frame);
      const bool incremental = settings_.mode == strain::StrainMode::kIncremental;
      const Strain2& chosen = incremental ? sum : fs.total[t];
      const Strain2& other = incremental ? fs.total[t] : sum;
      double* v = &record.values[t * kValueCount];
      v[kExx] = chosen.xx;
      v[kEyy] = chosen.yy;
      v[kExy] = chosen.xy;
      v[kOtherExx] = other.xx;
      v[kOtherEyy] = other.yy;
      v[kOtherExy] = other.xy;
      v[kRateXx] = fs.rate_per_s[t].xx;
      v[kRateYy] = fs.rate_per_s[t].yy;
      v[kRateXy] = fs.rate_per_s[t].xy;
      v[kRotation] = fs.rotation_polar_rad[t];
      v[kEnergy] =
          plane_strain_energy_density_J_m3(chosen, settings_.strain.young_Pa, settings_.strain.poisson);
      const Triangle& tri = mesh_.active_triangles()[t];
      const Strain2 sd = total_standard_deviation(tri);
      for (std::size_t c = 0; c < 3; ++c)
        record.sources[t] |= vertex_source_[static_cast<std::size_t>(tri[c])];
      v[kSdXx] = sd.xx;
      v[kSdYy] = sd.yy;
      v[kSdXy] = sd.xy;
      const double area_m2 = std::abs(strain::signed_area(reference_px_[static_cast<std::size_t>(tri[0])],
                                                          reference_px_[static_cast<std::size_t>(tri[1])],
                                                          reference_px_[static_cast<std::size_t>(tri[2])])) *
                             m_per_px * m_per_px;
      energy += v[kEnergy] * area_m2;
    }
    record.energy_J = fs.counts.valid > 0 ? settings_.strain.depth_m * energy : kNaN;
    record.stick_ratio = fs.stick_ratio;
  }

  // The paper's running sum of increments. A triangle that joins the mesh after the reference frame
  // (re-triangulation around births and retirements) has no increments before it: its sum starts from
  // its exact total at that frame, so the two modes differ only by what accumulates afterwards.
  const Strain2& running_sum(std::size_t triangle, const strain::FrameStrain& fs, std::size_t t,
                             bool reference_frame) {
    Strain2& sum = incremental_[triangle];
    if (!finite(sum)) {
      sum = reference_frame ? Strain2{} : fs.total[t];
    } else if (finite(fs.increment[t])) {
      sum.xx += fs.increment[t].xx;
      sum.yy += fs.increment[t].yy;
      sum.xy += fs.increment[t].xy;
    }
    return sum;
  }

  // Appends a frame's record, writes its rows, and keeps its per-triangle arrays only until the next frame
  // (draw() shows the newest).
  void keep(StrainFrame&& record) {
    if (out_) write_row(record, frames_.size());
    if (!frames_.empty()) frames_.back().drop_arrays();
    remember(frames_, std::move(record), keep_history_);
  }

  // dU/dt by central differences on the frame times (one-sided at the ends and next to gaps): the only
  // per-frame result that needs neighbours in time, one frame either side, from the energies kept.
  std::vector<double> energy_rate_W() const {
    const std::size_t n = frames_.size();
    std::vector<double> rate(n, kNaN);
    for (std::size_t i = 0; i < n; ++i) {
      const bool has_prev = i > 0 && std::isfinite(frames_[i - 1].energy_J);
      const bool has_next = i + 1 < n && std::isfinite(frames_[i + 1].energy_J);
      const std::size_t lo = has_prev ? i - 1 : i, hi = has_next ? i + 1 : i;
      if (lo == hi || !std::isfinite(frames_[lo].energy_J) || !std::isfinite(frames_[hi].energy_J)) continue;
      const double dt = frames_[hi].t_s - frames_[lo].t_s;
      if (dt > 0.0) rate[i] = (frames_[hi].energy_J - frames_[lo].energy_J) / dt;
    }
    return rate;
  }

  // Frame `row`'s rows of /mesh, /strain, /energy, /stick and /maps: as wide as the union mesh so far.
  void write_row(const StrainFrame& f, std::size_t row) const {
    write_triangle_rows(f, row);
    write_scalar_rows(f, row);
    write_map_rows(f, row);
  }

  // The frame's active triangles only: a long trial's union mesh holds many times more triangles than are
  // in the mesh at once, and the rest of each row is the fill value.
  void write_triangle_rows(const StrainFrame& f, std::size_t r) const {
    H5Stream& out = *out_;
    const std::size_t t_count = f.computed ? mesh_.triangles().size() : 0;
    const std::size_t n = f.computed ? f.active.size() : 0;
    std::vector<std::size_t> cells(n);
    std::vector<double> total(n * 3), other(n * 3), sd(n * 3), rate(n * 3), principal(n * 3, kNaN),
        rotation(n), density(n);
    for (std::size_t a = 0; a < n; ++a) {
      cells[a] = static_cast<std::size_t>(f.active[a]);
      const double* v = &f.values[a * kValueCount];
      for (std::size_t c = 0; c < 3; ++c) {
        total[a * 3 + c] = v[kExx + static_cast<int>(c)];
        other[a * 3 + c] = v[kOtherExx + static_cast<int>(c)];
        rate[a * 3 + c] = v[kRateXx + static_cast<int>(c)];
        sd[a * 3 + c] = v[kSdXx + static_cast<int>(c)];
      }
      if (std::isfinite(v[kExx])) {
        const Principal2 p = principal_strains({v[kExx], v[kEyy], v[kExy]});
        principal[a * 3] = p.e1;
        principal[a * 3 + 1] = p.e2;
        principal[a * 3 + 2] = p.angle_rad;
      }
      rotation[a] = v[kRotation];
      density[a] = v[kEnergy];
    }
    const std::span<const std::uint8_t> status(f.status.data(), n), source(f.sources.data(), n);
    const std::span<const std::int8_t> stuck(f.stuck.data(), n);
    const bool incremental = settings_.mode == strain::StrainMode::kIncremental;
    const H5Shape tensors{t_count, 3}, scalars{t_count};
    out.write_columns("/mesh/status", r, cells, status, scalars, kNotInMesh);
    out.write_columns("/strain/total", r, cells, std::span<const double>(total), tensors, kNaN, kStored);
    out.write_columns(incremental ? "/strain/total_exact" : "/strain/total_incremental", r, cells,
                      std::span<const double>(other), tensors, kNaN, kStored);
    out.write_columns("/strain/total_sd", r, cells, std::span<const double>(sd), tensors, kNaN, kStored);
    out.write_columns("/strain/source", r, cells, source, scalars, std::uint8_t{0});
    out.write_columns("/strain/rate", r, cells, std::span<const double>(rate), tensors, kNaN, kStored);
    out.write_columns("/strain/principal", r, cells, std::span<const double>(principal), tensors, kNaN,
                      kStored);
    out.write_columns("/strain/rotation_rad", r, cells, std::span<const double>(rotation), scalars, kNaN,
                      kStored);
    out.write_columns("/energy/density_J_m3", r, cells, std::span<const double>(density), scalars, kNaN,
                      kStored);
    out.write_columns("/stick/stuck", r, cells, stuck, scalars, std::int8_t{-1});
  }

  void write_scalar_rows(const StrainFrame& f, std::size_t r) const {
    H5Stream& out = *out_;
    const strain::TriangleCounts& c = f.counts;
    const std::int32_t counts[6] = {c.valid,       c.missing_vertex, c.small_area,
                                    c.small_angle, c.high_aspect,    c.inverted};
    out.write_row("/mesh/counts", r, std::span<const std::int32_t>(counts), {6}, 0);
    out.write_row("/energy/total_J", r, std::span<const double>(&f.energy_J, 1), {}, kNaN);
    out.write_row("/stick/ratio", r, std::span<const double>(&f.stick_ratio, 1), {}, kNaN);
    const bool fitted = f.computed && reference_has_ellipse_;
    const strain::StickZoneFit& z = f.stick_zone;
    const auto one = [&](const char* name, double value) {
      out.write_row(name, r, std::span<const double>(&value, 1), {}, kNaN);
    };
    const auto two = [&](const char* name, double a, double b) {
      const double pair[2] = {a, b};
      out.write_row(name, r, std::span<const double>(pair), {2}, kNaN);
    };
    one("/stick/radius_mm", stick_radius_mm(f));
    one("/stick/radius_ratio", fitted ? z.ratio : kNaN);
    const std::int8_t radius_status = fitted ? static_cast<std::int8_t>(z.status) : std::int8_t{-1};
    out.write_row("/stick/radius_status", r, std::span<const std::int8_t>(&radius_status, 1), {},
                  std::int8_t{-1});
    one("/stick/tracks_reach_ratio", fitted ? z.reach : kNaN);
    one("/stick/slip_max_px", fitted ? z.max_slip_px : kNaN);
    one("/stick/fit_residual_px", fitted ? z.residual_rms_px : kNaN);
    two("/stick/core_shift_px", fitted ? z.shift_px.x : kNaN, fitted ? z.shift_px.y : kNaN);
    two("/stick/slip_amplitude_px", fitted ? z.amplitude_px.x : kNaN, fitted ? z.amplitude_px.y : kNaN);
    two("/stick/fit_chi2", fitted ? z.chi2_slip : kNaN, fitted ? z.chi2_stick : kNaN);
  }

  void write_attributes(H5Stream& out) const {
    out.attribute("/mesh", "status_codes",
                  "0 valid; 1 missing vertex; 2 small area; 3 small angle; 4 high aspect; 5 inverted; "
                  "255 not in this frame's mesh");
    out.attribute("/mesh", "counts_columns",
                  "valid,missing_vertex,small_area,small_angle,high_aspect,inverted");
    out.attribute("/mesh", "min_area_px2", settings_.strain.quality.min_area_px2);
    out.attribute("/mesh", "min_angle_deg", settings_.strain.quality.min_angle_deg);
    out.attribute("/mesh", "max_aspect", settings_.strain.quality.max_aspect);
    out.attribute("/mesh", "rebuilds", static_cast<double>(mesh_.rebuilds()));
    out.attribute("/strain", "total_sd",
                  "predicted standard deviation of each total strain component from the vertices' match "
                  "covariances (/tracks/covariance_px2), vertices taken as independent: an upper bound of "
                  "the noise; NaN where a vertex has no covariance");
    out.attribute(
        "/strain", "source_bits",
        "0 every vertex matched; bit 1: a vertex's reference position is extrapolated "
        "(/tracks/reference_extrapolated); bit 2: a vertex reports a model this frame (/tracks/model)");
    out.attribute("/strain", "mode", strain::to_string(settings_.mode));
    out.attribute("/strain", "components", "E_xx,E_yy,E_xy (Green-Lagrange, tensor shear)");
    out.attribute("/strain", "rate_unit", "1/s (Green-Lagrange strain of frame t-1 -> t over dt)");
    out.attribute("/energy", "young_Pa", settings_.strain.young_Pa);
    out.attribute("/energy", "poisson", settings_.strain.poisson);
    out.attribute("/energy", "depth_m", settings_.strain.depth_m);
    out.attribute("/stick", "tolerance_px", settings_.strain.stick_tolerance_px);
    out.attribute(
        "/stick", "radius_method",
        "cattaneo_mindlin_fit: least-squares fit of the Cattaneo-Mindlin slip profile (stuck-core shift "
        "+ slip amplitudes, c/a by 1-D search) to the tracks within stick_fit_extent of the reference "
        "contact ellipse; c = (c/a) * sqrt(semi_major * semi_minor)");
    out.attribute("/stick", "radius_status_codes",
                  "0 fitted (c = 0: full slip); 1 no detectable slip and the stuck core at rest (c = a); "
                  "2 too few tracks (NaN); 3 the stuck core moved but no slip shows within the tracks, which "
                  "reach tracks_reach_ratio of a (NaN: the slip annulus, if any, is not measured); "
                  "-1 not computed");
    out.attribute("/stick", "contact_radius_mm",
                  reference_has_ellipse_ ? disk_.radius_px / settings_.strain.px_per_mm : kNaN);
    out.attribute("/stick", "fit_extent", settings_.stick_zone.extent);
    out.attribute("/stick", "fit_significance", settings_.stick_zone.significance);
    write_map_attributes(out);
  }

  void summarize(nlohmann::json& summary) const override {
    nlohmann::json s;
    s["mode"] = strain::to_string(settings_.mode);
    s["triangles_total"] = mesh_.triangles().size();
    s["mesh_rebuilds"] = mesh_.rebuilds();
    std::int64_t valid = 0, excluded = 0, missing = 0;
    double energy_max = kNaN;
    const StrainFrame* last = nullptr;
    // Frames by what the stick radius is: fitted, c = a at rest, not measured (no slip seen although the core
    // moved), too few tracks.
    std::map<std::string, int> radius_frames{
        {"fit", 0}, {"no_slip", 0}, {"slip_beyond_tracks", 0}, {"too_few_points", 0}};
    for (const StrainFrame& f : frames_) {
      if (!f.computed) continue;
      if (reference_has_ellipse_) ++radius_frames[strain::to_string(f.stick_zone.status)];
      valid += f.counts.valid;
      excluded += f.counts.excluded();
      missing += f.counts.missing_vertex;
      if (std::isfinite(f.energy_J) && !(f.energy_J <= energy_max)) energy_max = f.energy_J;
      last = &f;
    }
    s["triangle_frames_valid"] = valid;
    s["triangle_frames_excluded"] = excluded;
    s["triangle_frames_missing_vertex"] = missing;
    // null where no frame had a strain energy (no triangle): 0 J would read as a measured skin at rest.
    s["strain_energy_max_J"] = std::isfinite(energy_max) ? nlohmann::json(energy_max) : nlohmann::json();
    s["energy_scope"] =
        "the meshed triangles only: a lower bound of the contact's strain energy (the rim beyond the "
        "tracks is left out; docs/formats.md, /energy/total_J)";
    s["strain_energy_last_J"] =
        last && std::isfinite(last->energy_J) ? nlohmann::json(last->energy_J) : nlohmann::json();
    if (last && std::isfinite(last->stick_ratio)) s["stick_ratio_last"] = last->stick_ratio;
    if (last && std::isfinite(stick_radius_mm(*last))) s["stick_radius_last_mm"] = stick_radius_mm(*last);
    s["stick_radius_frames"] = radius_frames;
    s["strain_ms_per_frame"] =
        strained_frames_ > 0 ? 1e3 * strain_s_ / static_cast<double>(strained_frames_) : 0.0;
    s["maps"] = {{"cells", settings_.map_cells}, {"reference_has_ellipse", reference_has_ellipse_}};
    summary["strain"] = s;
  }

 private:
  double stick_radius_mm(const StrainFrame& f) const {
    return f.computed && reference_has_ellipse_ ? f.stick_zone.radius_px / settings_.strain.px_per_mm : kNaN;
  }

  // The colour bar's title: the quantity drawn and its unit.
  std::string overlay_label(bool energy) const {
    if (energy) return "energy density (J/m3)";
    static const std::map<std::string, std::string> names = {
        {"exx", "E_xx"}, {"eyy", "E_yy"}, {"exy", "E_xy"}, {"e1", "e1"}, {"e2", "e2"}};
    const auto it = names.find(settings_.overlay);
    return (it == names.end() ? settings_.overlay : it->second) + " (strain, -)";
  }

  double overlay_value(const double* v) const {
    const std::string& c = settings_.overlay;
    if (c == "exx") return v[kExx];
    if (c == "eyy") return v[kEyy];
    if (c == "exy") return v[kExy];
    if (c == "energy") return v[kEnergy];
    if (!std::isfinite(v[kExx])) return kNaN;
    const Principal2 p = principal_strains({v[kExx], v[kEyy], v[kExy]});
    return c == "e2" ? p.e2 : p.e1;
  }

  // The colour bar at the right edge, below (or above) the status block, labelled with the component and
  // its unit and with the ends of its scale.
  void draw_colour_bar(cv::Mat& bgr, bool energy, const OverlayText& overlay) const {
    const double scale = std::max(1.0, bgr.cols / 640.0);
    const int height = static_cast<int>(150 * scale), width = static_cast<int>(12 * scale);
    const int x0 = bgr.cols - width - static_cast<int>(70 * scale);
    const cv::Rect block = overlay.status_block(6);
    const int y0 = block.y == 0 ? block.height + overlay.line_height_px()
                                : block.y - height - overlay.line_height_px() / 2;
    if (x0 < 0 || y0 < 0 || y0 + height >= bgr.rows) return;
    for (int y = 0; y < height; ++y) {
      const double t = 1.0 - static_cast<double>(y) / (height - 1);
      const cv::Vec3b c = energy ? sequential_colour(t) : diverging_colour(t);
      cv::line(bgr, {x0, y0 + y}, {x0 + width - 1, y0 + y}, cv::Scalar(c[0], c[1], c[2]));
    }
    const double range = settings_.overlay_range;
    char top[32], bottom[32];
    std::snprintf(top, sizeof top, "%+.3g", range);
    std::snprintf(bottom, sizeof bottom, "%+.3g", energy ? 0.0 : -range);
    overlay.label(bgr, {x0 + width + 4, y0 + static_cast<int>(10 * scale)}, top);
    overlay.label(bgr, {x0 + width + 4, y0 + height}, bottom);
    overlay.label(bgr, {x0 - static_cast<int>(60 * scale), y0 - static_cast<int>(6 * scale)},
                  overlay_label(energy));
  }

  // Maps on the standard ellipse of the reference frame: /maps/strain_total [N,G,G,3], its predicted SD
  // /maps/strain_total_sd [N,G,G,3] (where the measurement is weak), /maps/principal [N,G,G,2] (e1, e2),
  // /maps/energy_density_J_m3 [N,G,G]; NaN rows for frames without strain.
  void write_map_rows(const StrainFrame& f, std::size_t r) const {
    const auto g = static_cast<std::size_t>(settings_.map_cells);
    std::vector<double> total(g * g * 3, kNaN), principal(g * g * 2, kNaN), density(g * g, kNaN);
    std::vector<double> total_sd(g * g * 3, kNaN);
    if (f.computed && reference_has_ellipse_) {
      std::vector<Triangle> triangles;
      std::vector<std::uint8_t> usable;
      for (std::size_t a = 0; a < f.active.size(); ++a) {
        triangles.push_back(mesh_.triangles()[static_cast<std::size_t>(f.active[a])]);
        usable.push_back(std::isfinite(f.values[a * kValueCount + kExx]) ? 1 : 0);
      }
      const std::vector<std::int32_t> owner =
          strain::rasterise_triangles(map_grid(), triangles, reference_px_, usable);
      // The components in the map's axes, so that maps of contacts turned differently average as they lie
      // on the finger; the standard deviations from the vertices' covariances turned the same way.
      const double angle_rad = reference_normalization_.angle_rad();
      std::vector<Strain2> sd_in_axes(triangles.size());
      if (angle_rad != 0.0)
        for (std::size_t a = 0; a < triangles.size(); ++a)
          if (usable[a]) sd_in_axes[a] = total_standard_deviation(triangles[a], angle_rad);
      for (std::size_t cell = 0; cell < owner.size(); ++cell) {
        if (owner[cell] < 0) continue;
        const auto a = static_cast<std::size_t>(owner[cell]);
        const double* v = &f.values[a * kValueCount];
        const Strain2 e = in_axes({v[kExx], v[kEyy], v[kExy]}, angle_rad);
        const Strain2 sd = angle_rad != 0.0 ? sd_in_axes[a] : Strain2{v[kSdXx], v[kSdYy], v[kSdXy]};
        total[cell * 3] = e.xx;
        total[cell * 3 + 1] = e.yy;
        total[cell * 3 + 2] = e.xy;
        total_sd[cell * 3] = sd.xx;
        total_sd[cell * 3 + 1] = sd.yy;
        total_sd[cell * 3 + 2] = sd.xy;
        const Principal2 p = principal_strains(e);
        principal[cell * 2] = p.e1;
        principal[cell * 2 + 1] = p.e2;
        density[cell] = v[kEnergy];
      }
    }
    H5Stream& out = *out_;
    out.write_row("/maps/strain_total", r, std::span<const double>(total), {g, g, 3}, kNaN, kStored);
    out.write_row("/maps/strain_total_sd", r, std::span<const double>(total_sd), {g, g, 3}, kNaN, kStored);
    out.write_row("/maps/principal", r, std::span<const double>(principal), {g, g, 2}, kNaN, kStored);
    out.write_row("/maps/energy_density_J_m3", r, std::span<const double>(density), {g, g}, kNaN, kStored);
  }

  strain::NormalisedGrid map_grid() const {
    strain::NormalisedGrid grid;
    grid.cells = settings_.map_cells;
    grid.to_normalised = reference_normalization_.forward_matrix();
    return grid;
  }

  void write_map_attributes(H5Stream& out) const {
    const auto g = static_cast<std::size_t>(settings_.map_cells);
    out.attribute(
        "/maps", "grid",
        reference_normalization_.angle_rad() != 0.0
            ? "cells on [-1,1]x[-1,1] of the standard ellipse (x along the major axis towards the "
              "image's bottom, semi-major 1; y 90 degrees clockwise from x on screen), centres at -1 + "
              "2i/(cells-1), stored [frame, y index, x index]; each cell the value of the reference "
              "triangle containing it, its components in the map's axes (axes_angle_rad); NaN outside "
              "the mesh"
            : "cells on [-1,1]x[-1,1] of the reference contact scaled to semi-major 1 in the image's "
              "axes (a contact within 5 % of a circle keeps them: x right, y down), centres at -1 + "
              "2i/(cells-1), stored [frame, y index, x index]; each cell the value of the reference "
              "triangle containing it, its components in image axes; NaN outside the mesh");
    out.attribute("/maps", "axes_angle_rad", reference_normalization_.angle_rad());
    out.attribute("/maps", "cells", static_cast<double>(g));
    out.attribute("/maps", "aspect", reference_normalization_.aspect());
    out.attribute("/maps", "reference_has_ellipse", reference_has_ellipse_ ? 1.0 : 0.0);
    const cv::Matx23d m = map_grid().to_normalised;
    out.attribute("/maps", "to_normalised",
                  format_double(m(0, 0)) + "," + format_double(m(0, 1)) + "," + format_double(m(0, 2)) + ";" +
                      format_double(m(1, 0)) + "," + format_double(m(1, 1)) + "," + format_double(m(1, 2)));
  }

  static std::uint8_t vertex_source(const flow::Track& t) {
    return static_cast<std::uint8_t>((t.reference_extrapolated ? kSourceExtrapolatedReference : 0) |
                                     (t.model != flow::TrackModel::kOwnMatch ? kSourceVertexModel : 0));
  }

  // In the image's axes, or in axes turned by `angle_rad` (the positions and covariances turned with them).
  Strain2 total_standard_deviation(const Triangle& tri, double angle_rad = 0.0) const {
    const double cs = std::cos(angle_rad), sn = std::sin(angle_rad);
    const auto turned = [&](Vec2 p) { return Vec2{cs * p.x + sn * p.y, -sn * p.x + cs * p.y}; };
    std::array<Vec2, 3> X, x;
    std::array<strain::PositionCovariance, 3> c;
    for (std::size_t v = 0; v < 3; ++v) {
      const auto k = static_cast<std::size_t>(tri[v]);
      X[v] = turned(reference_px_[k]);
      x[v] = turned(current_px_[k]);
      const strain::PositionCovariance& image = covariance_px2_[k];
      const Strain2 axes = in_axes({image[0], image[2], image[1]}, angle_rad);  // stored (xx, xy, yy)
      c[v] = {axes.xx, axes.xy, axes.yy};
    }
    return strain::strain_standard_deviation(X, x, c);
  }

  strain::StrainStageOptions settings_;
  strain::EvolvingMesh mesh_;
  contact::EllipseNormalization reference_normalization_;
  bool reference_has_ellipse_ = false;
  strain::ContactDisk disk_;
  std::vector<Vec2> reference_px_, current_px_, previous_px_;
  // The stick fit's input: each track's position without the local fit (flow/local_fit.hpp), whose windows
  // smooth across the stick zone's edge the fit looks for and round c.
  std::vector<Vec2> unsmoothed_px_;
  std::vector<strain::PositionCovariance> covariance_px2_;  // per track, this frame's match covariance
  std::vector<std::uint8_t> vertex_source_;                 // per track, kSource* bits this frame
  std::vector<std::int32_t> alive_;
  std::vector<Strain2> incremental_;  // per union triangle; NaN until the triangle is first usable
  double previous_t_s_ = kNaN;
  std::vector<StrainFrame> frames_;
  bool keep_history_ = true;
  H5Stream* out_ = nullptr;  // result.h5, where rows go as frames are done (null in the live view)
  double strain_s_ = 0.0;
  std::int64_t strained_frames_ = 0;
};

}  // namespace

std::unique_ptr<Stage> make_strain_stage(const Scene& scene) {
  return std::make_unique<StrainStage>(scene);
}

}  // namespace tirstrain::pipeline
