#include "pipeline/strain_stage.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <limits>

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
};

bool finite(const Strain2& e) {
  return std::isfinite(e.xx) && std::isfinite(e.yy) && std::isfinite(e.xy);
}

class StrainStage final : public Stage {
 public:
  explicit StrainStage(const Scene& scene) : settings_(strain::parse_strain_settings(scene)) {}

  std::string name() const override { return "strain"; }

  void start(const TrialInfo& info) override { keep_history_ = info.keep_history; }

  void process(FrameContext& context) override {
    StrainFrame record;
    record.t_s = context.frame ? context.frame->device_time_s : kNaN;
    if (!context.tracking) {
      remember(frames_, std::move(record), keep_history_);
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const auto& tracks = *context.tracking->tracks;
    if (context.tracking->reference_frame) {
      reference_normalization_ = *context.tracking->reference_normalization;
      reference_has_ellipse_ = context.tracking->reference_has_ellipse;
      // The reference contact as a disk map for the stick-radius fit: centre, axes and angle of the
      // normalisation (q = s R(−φ)(X − centre), semi-major 1/s, semi-minor aspect/s).
      const cv::Matx23d m = reference_normalization_.forward_matrix();
      const double scale = reference_normalization_.scale_per_px();
      const cv::Point2d centre = reference_normalization_.denormalize({0.0, 0.0});
      disk_ = reference_has_ellipse_ ? strain::contact_disk({centre.x, centre.y}, 1.0 / scale,
                                                            reference_normalization_.aspect() / scale,
                                                            std::atan2(m(0, 1), m(0, 0)))
                                     : strain::ContactDisk{};
    }
    reference_px_.resize(tracks.size());
    current_px_.assign(tracks.size(), Vec2{kNaN, kNaN});
    covariance_px2_.assign(tracks.size(), {kNaN, kNaN, kNaN});
    vertex_source_.assign(tracks.size(), 0);
    alive_.clear();
    for (std::size_t k = 0; k < tracks.size(); ++k) {
      reference_px_[k] = tracks[k].reference_px;
      if (flow::is_alive(tracks[k].status)) {
        current_px_[k] = tracks[k].position_px;
        covariance_px2_[k] = tracks[k].covariance_px2;
        vertex_source_[k] = vertex_source(tracks[k]);
        alive_.push_back(static_cast<std::int32_t>(k));
      }
    }
    mesh_.update(alive_, reference_px_);
    previous_px_.resize(tracks.size(), Vec2{kNaN, kNaN});

    strain::FrameInput input;
    input.triangles = mesh_.active_triangles();
    input.reference_px = reference_px_;
    input.current_px = current_px_;
    if (!context.tracking->reference_frame) input.previous_px = previous_px_;
    input.dt_s = record.t_s - previous_t_s_;
    if (context.plate_displacement_px) {
      input.plate_known = true;
      input.plate_displacement_px = *context.plate_displacement_px;
    }
    const strain::FrameStrain fs = strain::compute_frame_strain(input, settings_.strain);

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
      // The paper's running sum of increments. A triangle that joins the mesh after the reference frame
      // (re-triangulation around births and retirements) has no increments before it: its sum starts from
      // its exact total at that frame, so the two modes differ only by what accumulates afterwards.
      Strain2& sum = incremental_[static_cast<std::size_t>(record.active[t])];
      if (!finite(sum)) {
        sum = context.tracking->reference_frame ? Strain2{} : fs.total[t];
      } else if (finite(fs.increment[t])) {
        sum.xx += fs.increment[t].xx;
        sum.yy += fs.increment[t].yy;
        sum.xy += fs.increment[t].xy;
      }
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
      for (std::size_t v = 0; v < 3; ++v)
        record.sources[t] |= vertex_source_[static_cast<std::size_t>(tri[v])];
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
    if (reference_has_ellipse_)
      record.stick_zone = strain::fit_stick_zone(reference_px_, current_px_, disk_, settings_.strain.poisson,
                                                 settings_.stick_zone);
    if (std::isfinite(record.energy_J)) context.strain_energy_J = record.energy_J;

    previous_px_ = current_px_;
    previous_t_s_ = record.t_s;
    strain_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++strained_frames_;
    remember(frames_, std::move(record), keep_history_);
  }

  void draw(cv::Mat& bgr, const FrameContext& context) const override {
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
    draw_colour_bar(bgr, energy);
    const double scale = std::max(1.0, bgr.cols / 640.0);
    char text[200];
    std::snprintf(text, sizeof text, "strain (%s): %d triangles, %d excluded  U = %.3g uJ  stick %.2f",
                  strain::to_string(settings_.mode), f.counts.valid, f.counts.excluded(), f.energy_J * 1e6,
                  f.stick_ratio);
    cv::putText(bgr, text, cv::Point(8, static_cast<int>(92 * scale)), cv::FONT_HERSHEY_SIMPLEX, 0.5 * scale,
                cv::Scalar(255, 255, 255), static_cast<int>(std::lround(scale)), cv::LINE_AA);
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

  void write(H5Writer& out) const override {
    const std::size_t n = frames_.size();
    const auto& triangles = mesh_.triangles();
    const std::size_t t_count = triangles.size();
    std::vector<std::int32_t> mesh(t_count * 3);
    for (std::size_t t = 0; t < t_count; ++t)
      for (int v = 0; v < 3; ++v)
        mesh[t * 3 + static_cast<std::size_t>(v)] = triangles[t][static_cast<std::size_t>(v)];
    std::vector<double> total(n * t_count * 3, kNaN), other(n * t_count * 3, kNaN), sd(n * t_count * 3, kNaN),
        rate(n * t_count * 3, kNaN), principal(n * t_count * 3, kNaN), rotation(n * t_count, kNaN),
        density(n * t_count, kNaN);
    std::vector<std::uint8_t> status(n * t_count, kNotInMesh);
    std::vector<std::int8_t> stuck(n * t_count, -1);
    std::vector<std::uint8_t> source(n * t_count, 0);
    std::vector<double> energy(n, kNaN), stick(n, kNaN), energy_rate(n, kNaN);
    std::vector<double> radius_mm(n, kNaN), radius_ratio(n, kNaN), slip_px(n, kNaN), residual_px(n, kNaN),
        shift_px(n * 2, kNaN), amplitude_px(n * 2, kNaN), chi2(n * 2, kNaN);
    std::vector<std::int8_t> radius_status(n, -1);
    std::vector<std::int32_t> counts(n * 6, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const StrainFrame& f = frames_[i];
      energy[i] = f.energy_J;
      stick[i] = f.stick_ratio;
      if (f.computed && reference_has_ellipse_) {
        const strain::StickZoneFit& z = f.stick_zone;
        radius_mm[i] = stick_radius_mm(f);
        radius_ratio[i] = z.ratio;
        slip_px[i] = z.max_slip_px;
        residual_px[i] = z.residual_rms_px;
        shift_px[2 * i] = z.shift_px.x;
        shift_px[2 * i + 1] = z.shift_px.y;
        amplitude_px[2 * i] = z.amplitude_px.x;
        amplitude_px[2 * i + 1] = z.amplitude_px.y;
        radius_status[i] = static_cast<std::int8_t>(z.status);
        chi2[2 * i] = z.chi2_slip;
        chi2[2 * i + 1] = z.chi2_stick;
      }
      const strain::TriangleCounts& c = f.counts;
      const std::int32_t row[6] = {c.valid,       c.missing_vertex, c.small_area,
                                   c.small_angle, c.high_aspect,    c.inverted};
      std::copy(row, row + 6, counts.begin() + static_cast<std::ptrdiff_t>(i * 6));
      for (std::size_t a = 0; a < f.active.size(); ++a) {
        const std::size_t cell = i * t_count + static_cast<std::size_t>(f.active[a]);
        status[cell] = f.status[a];
        stuck[cell] = f.stuck[a];
        source[cell] = f.sources[a];
        const double* v = &f.values[a * kValueCount];
        for (int c3 = 0; c3 < 3; ++c3) {
          total[cell * 3 + static_cast<std::size_t>(c3)] = v[kExx + c3];
          other[cell * 3 + static_cast<std::size_t>(c3)] = v[kOtherExx + c3];
          rate[cell * 3 + static_cast<std::size_t>(c3)] = v[kRateXx + c3];
          sd[cell * 3 + static_cast<std::size_t>(c3)] = v[kSdXx + c3];
        }
        if (std::isfinite(v[kExx])) {
          const Principal2 p = principal_strains({v[kExx], v[kEyy], v[kExy]});
          principal[cell * 3] = p.e1;
          principal[cell * 3 + 1] = p.e2;
          principal[cell * 3 + 2] = p.angle_rad;
        }
        rotation[cell] = v[kRotation];
        density[cell] = v[kEnergy];
      }
    }
    // dU/dt by central differences on the frame times (one-sided at the ends and next to gaps).
    for (std::size_t i = 0; i < n; ++i) {
      const bool has_prev = i > 0 && std::isfinite(energy[i - 1]);
      const bool has_next = i + 1 < n && std::isfinite(energy[i + 1]);
      const std::size_t lo = has_prev ? i - 1 : i, hi = has_next ? i + 1 : i;
      if (lo == hi || !std::isfinite(energy[lo]) || !std::isfinite(energy[hi])) continue;
      const double dt = frames_[hi].t_s - frames_[lo].t_s;
      if (dt > 0.0) energy_rate[i] = (energy[hi] - energy[lo]) / dt;
    }
    const bool incremental = settings_.mode == strain::StrainMode::kIncremental;
    out.write("/mesh/triangles", std::span<const std::int32_t>(mesh), {t_count, 3});
    out.write("/mesh/status", std::span<const std::uint8_t>(status), {n, t_count});
    out.write("/mesh/counts", std::span<const std::int32_t>(counts), {n, 6});
    out.attribute("/mesh", "status_codes",
                  "0 valid; 1 missing vertex; 2 small area; 3 small angle; 4 high aspect; 5 inverted; "
                  "255 not in this frame's mesh");
    out.attribute("/mesh", "counts_columns",
                  "valid,missing_vertex,small_area,small_angle,high_aspect,inverted");
    out.attribute("/mesh", "min_area_px2", settings_.strain.quality.min_area_px2);
    out.attribute("/mesh", "min_angle_deg", settings_.strain.quality.min_angle_deg);
    out.attribute("/mesh", "max_aspect", settings_.strain.quality.max_aspect);
    out.attribute("/mesh", "rebuilds", static_cast<double>(mesh_.rebuilds()));
    out.write("/strain/total", std::span<const double>(total), {n, t_count, 3});
    out.write(incremental ? "/strain/total_exact" : "/strain/total_incremental",
              std::span<const double>(other), {n, t_count, 3});
    out.write("/strain/total_sd", std::span<const double>(sd), {n, t_count, 3});
    out.attribute("/strain", "total_sd",
                  "predicted standard deviation of each total strain component from the vertices' match "
                  "covariances (/tracks/covariance_px2), vertices taken as independent: an upper bound of "
                  "the noise; NaN where a vertex has no covariance");
    out.write("/strain/source", std::span<const std::uint8_t>(source), {n, t_count});
    out.attribute(
        "/strain", "source_bits",
        "0 every vertex matched; bit 1: a vertex's reference position is extrapolated "
        "(/tracks/reference_extrapolated); bit 2: a vertex reports a model this frame (/tracks/model)");
    out.write("/strain/rate", std::span<const double>(rate), {n, t_count, 3});
    out.write("/strain/principal", std::span<const double>(principal), {n, t_count, 3});
    out.write("/strain/rotation_rad", std::span<const double>(rotation), {n, t_count});
    out.attribute("/strain", "mode", strain::to_string(settings_.mode));
    out.attribute("/strain", "components", "E_xx,E_yy,E_xy (Green-Lagrange, tensor shear)");
    out.attribute("/strain", "rate_unit", "1/s (Green-Lagrange strain of frame t-1 -> t over dt)");
    out.write("/energy/density_J_m3", std::span<const double>(density), {n, t_count});
    out.write("/energy/total_J", std::span<const double>(energy), {n});
    out.write("/energy/rate_W", std::span<const double>(energy_rate), {n});
    out.attribute("/energy", "young_Pa", settings_.strain.young_Pa);
    out.attribute("/energy", "poisson", settings_.strain.poisson);
    out.attribute("/energy", "depth_m", settings_.strain.depth_m);
    out.write("/stick/ratio", std::span<const double>(stick), {n});
    out.write("/stick/stuck", std::span<const std::int8_t>(stuck), {n, t_count});
    out.attribute("/stick", "tolerance_px", settings_.strain.stick_tolerance_px);
    out.write("/stick/radius_mm", std::span<const double>(radius_mm), {n});
    out.write("/stick/radius_ratio", std::span<const double>(radius_ratio), {n});
    out.write("/stick/radius_status", std::span<const std::int8_t>(radius_status), {n});
    out.write("/stick/slip_max_px", std::span<const double>(slip_px), {n});
    out.write("/stick/fit_residual_px", std::span<const double>(residual_px), {n});
    out.write("/stick/core_shift_px", std::span<const double>(shift_px), {n, 2});
    out.write("/stick/slip_amplitude_px", std::span<const double>(amplitude_px), {n, 2});
    out.write("/stick/fit_chi2", std::span<const double>(chi2), {n, 2});
    out.attribute(
        "/stick", "radius_method",
        "cattaneo_mindlin_fit: least-squares fit of the Cattaneo-Mindlin slip profile (stuck-core shift "
        "+ slip amplitudes, c/a by 1-D search) to the tracks within stick_fit_extent of the reference "
        "contact ellipse; c = (c/a) * sqrt(semi_major * semi_minor)");
    out.attribute(
        "/stick", "radius_status_codes",
        "0 fitted (c = 0: full slip); 1 no detectable slip (c = a); 2 too few tracks (NaN); -1 not computed");
    out.attribute("/stick", "contact_radius_mm",
                  reference_has_ellipse_ ? disk_.radius_px / settings_.strain.px_per_mm : kNaN);
    out.attribute("/stick", "fit_extent", settings_.stick_zone.extent);
    out.attribute("/stick", "fit_significance", settings_.stick_zone.significance);
    write_maps(out);
  }

  void summarize(nlohmann::json& summary) const override {
    nlohmann::json s;
    s["mode"] = strain::to_string(settings_.mode);
    s["triangles_total"] = mesh_.triangles().size();
    s["mesh_rebuilds"] = mesh_.rebuilds();
    std::int64_t valid = 0, excluded = 0, missing = 0;
    double energy_max = 0.0;
    const StrainFrame* last = nullptr;
    for (const StrainFrame& f : frames_) {
      if (!f.computed) continue;
      valid += f.counts.valid;
      excluded += f.counts.excluded();
      missing += f.counts.missing_vertex;
      if (std::isfinite(f.energy_J)) energy_max = std::max(energy_max, f.energy_J);
      last = &f;
    }
    s["triangle_frames_valid"] = valid;
    s["triangle_frames_excluded"] = excluded;
    s["triangle_frames_missing_vertex"] = missing;
    s["strain_energy_max_J"] = energy_max;
    s["strain_energy_last_J"] = last && std::isfinite(last->energy_J) ? last->energy_J : 0.0;
    if (last && std::isfinite(last->stick_ratio)) s["stick_ratio_last"] = last->stick_ratio;
    if (last && std::isfinite(stick_radius_mm(*last))) s["stick_radius_last_mm"] = stick_radius_mm(*last);
    s["strain_ms_per_frame"] =
        strained_frames_ > 0 ? 1e3 * strain_s_ / static_cast<double>(strained_frames_) : 0.0;
    s["maps"] = {{"cells", settings_.map_cells}, {"reference_has_ellipse", reference_has_ellipse_}};
    summary["strain"] = s;
  }

 private:
  double stick_radius_mm(const StrainFrame& f) const {
    return f.computed && reference_has_ellipse_ ? f.stick_zone.radius_px / settings_.strain.px_per_mm : kNaN;
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

  void draw_colour_bar(cv::Mat& bgr, bool energy) const {
    const double scale = std::max(1.0, bgr.cols / 640.0);
    const int height = static_cast<int>(150 * scale), width = static_cast<int>(12 * scale);
    const int x0 = bgr.cols - width - static_cast<int>(60 * scale), y0 = static_cast<int>(30 * scale);
    if (x0 < 0 || y0 + height >= bgr.rows) return;
    for (int y = 0; y < height; ++y) {
      const double t = 1.0 - static_cast<double>(y) / (height - 1);
      const cv::Vec3b c = energy ? sequential_colour(t) : diverging_colour(t);
      cv::line(bgr, {x0, y0 + y}, {x0 + width - 1, y0 + y}, cv::Scalar(c[0], c[1], c[2]));
    }
    const double range = settings_.overlay_range;
    char top[32], bottom[32];
    std::snprintf(top, sizeof top, "%+.3g", range);
    std::snprintf(bottom, sizeof bottom, "%+.3g", energy ? 0.0 : -range);
    const cv::Scalar white(255, 255, 255);
    const double font = 0.4 * scale;
    cv::putText(bgr, top, {x0 + width + 3, y0 + static_cast<int>(8 * scale)}, cv::FONT_HERSHEY_SIMPLEX, font,
                white, 1, cv::LINE_AA);
    cv::putText(bgr, bottom, {x0 + width + 3, y0 + height}, cv::FONT_HERSHEY_SIMPLEX, font, white, 1,
                cv::LINE_AA);
    const std::string label = energy ? "W (J/m3)" : settings_.overlay;
    cv::putText(bgr, label, {x0 - static_cast<int>(10 * scale), y0 - static_cast<int>(8 * scale)},
                cv::FONT_HERSHEY_SIMPLEX, font, white, 1, cv::LINE_AA);
  }

  // Maps on the standard ellipse of the reference frame: /maps/strain_total [N,G,G,3], its predicted SD
  // /maps/strain_total_sd [N,G,G,3] (where the measurement is weak), /maps/principal [N,G,G,2] (e1, e2),
  // /maps/energy_density_J_m3 [N,G,G].
  void write_maps(H5Writer& out) const {
    const std::size_t n = frames_.size();
    const auto g = static_cast<std::size_t>(settings_.map_cells);
    strain::NormalisedGrid grid;
    grid.cells = settings_.map_cells;
    grid.to_normalised = reference_normalization_.forward_matrix();
    std::vector<double> total(n * g * g * 3, kNaN), principal(n * g * g * 2, kNaN), density(n * g * g, kNaN);
    std::vector<double> total_sd(n * g * g * 3, kNaN);
    std::vector<Triangle> triangles;
    std::vector<std::uint8_t> usable;
    for (std::size_t i = 0; i < n && reference_has_ellipse_; ++i) {
      const StrainFrame& f = frames_[i];
      if (!f.computed) continue;
      triangles.clear();
      usable.clear();
      for (std::size_t a = 0; a < f.active.size(); ++a) {
        triangles.push_back(mesh_.triangles()[static_cast<std::size_t>(f.active[a])]);
        usable.push_back(std::isfinite(f.values[a * kValueCount + kExx]) ? 1 : 0);
      }
      const std::vector<std::int32_t> owner =
          strain::rasterise_triangles(grid, triangles, reference_px_, usable);
      for (std::size_t cell = 0; cell < owner.size(); ++cell) {
        if (owner[cell] < 0) continue;
        const double* v = &f.values[static_cast<std::size_t>(owner[cell]) * kValueCount];
        const std::size_t base = i * g * g + cell;
        total[base * 3] = v[kExx];
        total[base * 3 + 1] = v[kEyy];
        total[base * 3 + 2] = v[kExy];
        for (std::size_t c = 0; c < 3; ++c) total_sd[base * 3 + c] = v[kSdXx + static_cast<int>(c)];
        const Principal2 p = principal_strains({v[kExx], v[kEyy], v[kExy]});
        principal[base * 2] = p.e1;
        principal[base * 2 + 1] = p.e2;
        density[base] = v[kEnergy];
      }
    }
    out.write("/maps/strain_total", std::span<const double>(total), {n, g, g, 3});
    out.write("/maps/strain_total_sd", std::span<const double>(total_sd), {n, g, g, 3});
    out.write("/maps/principal", std::span<const double>(principal), {n, g, g, 2});
    out.write("/maps/energy_density_J_m3", std::span<const double>(density), {n, g, g});
    out.attribute("/maps", "grid",
                  "cells on [-1,1]x[-1,1] of the standard ellipse (x along the major axis, semi-major 1, y "
                  "down), centres at -1 + 2i/(cells-1); each cell the value of the reference triangle "
                  "containing it; NaN outside the mesh");
    out.attribute("/maps", "cells", static_cast<double>(g));
    out.attribute("/maps", "aspect", reference_normalization_.aspect());
    out.attribute("/maps", "reference_has_ellipse", reference_has_ellipse_ ? 1.0 : 0.0);
    const cv::Matx23d m = grid.to_normalised;
    out.attribute("/maps", "to_normalised",
                  format_double(m(0, 0)) + "," + format_double(m(0, 1)) + "," + format_double(m(0, 2)) + ";" +
                      format_double(m(1, 0)) + "," + format_double(m(1, 1)) + "," + format_double(m(1, 2)));
  }

  static std::uint8_t vertex_source(const flow::Track& t) {
    return static_cast<std::uint8_t>((t.reference_extrapolated ? kSourceExtrapolatedReference : 0) |
                                     (t.model != flow::TrackModel::kOwnMatch ? kSourceVertexModel : 0));
  }

  Strain2 total_standard_deviation(const Triangle& tri) const {
    std::array<Vec2, 3> X, x;
    std::array<strain::PositionCovariance, 3> c;
    for (std::size_t v = 0; v < 3; ++v) {
      const auto k = static_cast<std::size_t>(tri[v]);
      X[v] = reference_px_[k];
      x[v] = current_px_[k];
      c[v] = covariance_px2_[k];
    }
    return strain::strain_standard_deviation(X, x, c);
  }

  strain::StrainStageSettings settings_;
  strain::EvolvingMesh mesh_;
  contact::EllipseNormalization reference_normalization_;
  bool reference_has_ellipse_ = false;
  strain::ContactDisk disk_;
  std::vector<Vec2> reference_px_, current_px_, previous_px_;
  std::vector<strain::PositionCovariance> covariance_px2_;  // per track, this frame's match covariance
  std::vector<std::uint8_t> vertex_source_;                 // per track, kSource* bits this frame
  std::vector<std::int32_t> alive_;
  std::vector<Strain2> incremental_;  // per union triangle; NaN until the triangle is first usable
  double previous_t_s_ = kNaN;
  std::vector<StrainFrame> frames_;
  bool keep_history_ = true;
  double strain_s_ = 0.0;
  std::int64_t strained_frames_ = 0;
};

}  // namespace

std::unique_ptr<Stage> make_strain_stage(const Scene& scene) {
  return std::make_unique<StrainStage>(scene);
}

}  // namespace tirstrain::pipeline
