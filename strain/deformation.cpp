#include "strain/deformation.hpp"

#include "core/error.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace tirstrain::strain {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool finite(const Vec2& p) {
  return std::isfinite(p.x) && std::isfinite(p.y);
}

}  // namespace

Gradient2 displacement_gradient(const std::array<Vec2, 3>& reference, const std::array<Vec2, 3>& current) {
  // Reference edge matrix D = [X2−X1, X3−X1] (columns), current d likewise; F = d·D⁻¹.
  const double d11 = reference[1].x - reference[0].x, d12 = reference[2].x - reference[0].x;
  const double d21 = reference[1].y - reference[0].y, d22 = reference[2].y - reference[0].y;
  const double c11 = current[1].x - current[0].x, c12 = current[2].x - current[0].x;
  const double c21 = current[1].y - current[0].y, c22 = current[2].y - current[0].y;
  const double inv_det = 1.0 / (d11 * d22 - d12 * d21);
  const double i11 = d22 * inv_det, i12 = -d12 * inv_det, i21 = -d21 * inv_det, i22 = d11 * inv_det;
  // F − I is formed from the displacement differences (d − D)·D⁻¹ rather than F then subtracting I, which
  // keeps full relative precision when strains are tiny.
  const double u11 = c11 - d11, u12 = c12 - d12, u21 = c21 - d21, u22 = c22 - d22;
  return {u11 * i11 + u12 * i21, u11 * i12 + u12 * i22, u21 * i11 + u22 * i21, u21 * i12 + u22 * i22};
}

double polar_rotation_rad(const Gradient2& h) {
  // For a 2×2 F with det F > 0, R = rotation by atan2(F21 − F12, F11 + F22).
  return std::atan2(h.yx - h.xy, 2.0 + h.xx + h.yy);
}

Gradient2 incremental_gradient(const Gradient2& current, const Gradient2& previous) {
  const double p11 = 1.0 + previous.xx, p12 = previous.xy, p21 = previous.yx, p22 = 1.0 + previous.yy;
  const double inv_det = 1.0 / (p11 * p22 - p12 * p21);
  const double i11 = p22 * inv_det, i12 = -p12 * inv_det, i21 = -p21 * inv_det, i22 = p11 * inv_det;
  // F_inc − I = (F_t − F_{t−1})·F_{t−1}⁻¹ = (H_t − H_{t−1})·F_{t−1}⁻¹.
  const double d11 = current.xx - previous.xx, d12 = current.xy - previous.xy;
  const double d21 = current.yx - previous.yx, d22 = current.yy - previous.yy;
  return {d11 * i11 + d12 * i21, d11 * i12 + d12 * i22, d21 * i11 + d22 * i21, d21 * i12 + d22 * i22};
}

namespace {

// Every per-triangle output NaN (or "not labelled"), every triangle valid until checked.
FrameStrain empty_frame_strain(std::size_t count) {
  FrameStrain out;
  out.status.assign(count, TriangleStatus::kValid);
  out.gradient.assign(count, {kNaN, kNaN, kNaN, kNaN});
  out.total.assign(count, {kNaN, kNaN, kNaN});
  out.principal.assign(count, {kNaN, kNaN, kNaN});
  out.rotation_small_rad.assign(count, kNaN);
  out.rotation_polar_rad.assign(count, kNaN);
  out.area_ratio.assign(count, kNaN);
  out.energy_density_J_m3.assign(count, kNaN);
  out.reference_area_m2.assign(count, kNaN);
  out.increment.assign(count, {kNaN, kNaN, kNaN});
  out.rate_per_s.assign(count, {kNaN, kNaN, kNaN});
  out.stuck.assign(count, -1);
  return out;
}

std::array<Vec2, 3> corners(std::span<const Vec2> points_px, const Triangle& tri) {
  return {points_px[tri[0]], points_px[tri[1]], points_px[tri[2]]};
}

// Whether a triangle's strain can be measured: every vertex tracked, a well-shaped reference, not turned
// inside out; `h` receives its displacement gradient when it is valid.
TriangleStatus triangle_status(const std::array<Vec2, 3>& ref, const std::array<Vec2, 3>& cur,
                               const QualityCriteria& quality, Gradient2& h) {
  for (int k = 0; k < 3; ++k)
    if (!finite(cur[k]) || !finite(ref[k])) return TriangleStatus::kMissingVertex;
  const TriangleStatus shape = check_reference_shape(ref[0], ref[1], ref[2], quality);
  if (shape != TriangleStatus::kValid) return shape;
  h = displacement_gradient(ref, cur);
  return area_ratio(h) > 0.0 ? TriangleStatus::kValid : TriangleStatus::kInverted;
}

void count_status(TriangleStatus status, TriangleCounts& counts) {
  switch (status) {
    case TriangleStatus::kValid:
      ++counts.valid;
      break;
    case TriangleStatus::kMissingVertex:
      ++counts.missing_vertex;
      break;
    case TriangleStatus::kSmallArea:
      ++counts.small_area;
      break;
    case TriangleStatus::kSmallAngle:
      ++counts.small_angle;
      break;
    case TriangleStatus::kHighAspect:
      ++counts.high_aspect;
      break;
    case TriangleStatus::kInverted:
      ++counts.inverted;
      break;
  }
}

// The strain since the previous frame and its rate, where the previous frame tracked every vertex.
void fill_increment(const FrameInput& input, const Triangle& tri, const std::array<Vec2, 3>& ref,
                    const Gradient2& h, std::size_t t, FrameStrain& out) {
  const std::array<Vec2, 3> prev = corners(input.previous_px, tri);
  if (!finite(prev[0]) || !finite(prev[1]) || !finite(prev[2])) return;
  const Gradient2 h_prev = displacement_gradient(ref, prev);
  if (!(area_ratio(h_prev) > 0.0)) return;
  const Strain2 inc = green_lagrange(incremental_gradient(h, h_prev));
  out.increment[t] = inc;
  if (input.dt_s > 0.0) out.rate_per_s[t] = {inc.xx / input.dt_s, inc.yy / input.dt_s, inc.xy / input.dt_s};
}

// Stuck: the triangle's mean displacement within the tolerance of the plate's.
bool moves_with_plate(const FrameInput& input, const std::array<Vec2, 3>& ref, const std::array<Vec2, 3>& cur,
                      double tolerance_px) {
  const double ux = (cur[0].x + cur[1].x + cur[2].x - ref[0].x - ref[1].x - ref[2].x) / 3.0;
  const double uy = (cur[0].y + cur[1].y + cur[2].y - ref[0].y - ref[1].y - ref[2].y) / 3.0;
  return std::hypot(ux - input.plate_displacement_px.x, uy - input.plate_displacement_px.y) <= tolerance_px;
}

}  // namespace

// The arrays describe the same tracks and every triangle names three of them: a mismatch would read past
// an array's end or pair one track's reference with another's position.
void check_frame_input(const FrameInput& input) {
  const std::size_t tracks = input.reference_px.size();
  if (input.current_px.size() != tracks)
    throw Error("current_px has " + std::to_string(input.current_px.size()) +
                " positions but reference_px has " + std::to_string(tracks) + ": one per track in both");
  if (!input.previous_px.empty() && input.previous_px.size() != tracks)
    throw Error("previous_px has " + std::to_string(input.previous_px.size()) +
                " positions but reference_px has " + std::to_string(tracks) +
                ": one per track, or none for the first frame");
  for (std::size_t t = 0; t < input.triangles.size(); ++t)
    for (const auto v : input.triangles[t])
      if (v < 0 || static_cast<std::size_t>(v) >= tracks)
        throw Error("triangle " + std::to_string(t) + " names track " + std::to_string(v) +
                    ", but there are " + std::to_string(tracks) + " tracks");
}

FrameStrain compute_frame_strain(const FrameInput& input, const StrainOptions& settings) {
  settings.check();
  check_frame_input(input);
  const std::size_t count = input.triangles.size();
  FrameStrain out = empty_frame_strain(count);
  const double m_per_px = 1.0e-3 / settings.px_per_mm;
  double energy_J = 0.0, valid_area = 0.0, stuck_area = 0.0;
  for (std::size_t t = 0; t < count; ++t) {
    const Triangle& tri = input.triangles[t];
    const std::array<Vec2, 3> ref = corners(input.reference_px, tri), cur = corners(input.current_px, tri);
    Gradient2 h;
    const TriangleStatus status = triangle_status(ref, cur, settings.quality, h);
    out.status[t] = status;
    count_status(status, out.counts);
    if (status != TriangleStatus::kValid) continue;

    const Strain2 e = green_lagrange(h);
    const double area_m2 = std::abs(signed_area(ref[0], ref[1], ref[2])) * m_per_px * m_per_px;
    const double w = plane_strain_energy_density_J_m3(e, settings.young_Pa, settings.poisson);
    out.gradient[t] = h;
    out.total[t] = e;
    out.principal[t] = principal_strains(e);
    out.rotation_small_rad[t] = infinitesimal_rotation_rad(h);
    out.rotation_polar_rad[t] = polar_rotation_rad(h);
    out.area_ratio[t] = area_ratio(h);
    out.energy_density_J_m3[t] = w;
    out.reference_area_m2[t] = area_m2;
    energy_J += w * area_m2;
    valid_area += area_m2;
    if (!input.previous_px.empty()) fill_increment(input, tri, ref, h, t, out);
    if (input.plate_known) {
      const bool stuck = moves_with_plate(input, ref, cur, settings.stick_tolerance_px);
      out.stuck[t] = stuck ? 1 : 0;
      if (stuck) stuck_area += area_m2;
    }
  }
  out.total_energy_J = settings.depth_m * energy_J;
  out.stick_ratio = input.plate_known && valid_area > 0.0 ? stuck_area / valid_area : kNaN;
  return out;
}

IncrementalStrain::IncrementalStrain(std::size_t triangle_count) {
  resize(triangle_count);
}

void IncrementalStrain::resize(std::size_t triangle_count) {
  sum_.resize(triangle_count, Strain2{});
  gaps_.resize(triangle_count, 0);
}

void IncrementalStrain::add(const FrameStrain& frame) {
  if (frame.increment.size() > sum_.size()) resize(frame.increment.size());
  for (std::size_t t = 0; t < frame.increment.size(); ++t) {
    const Strain2& inc = frame.increment[t];
    if (std::isfinite(inc.xx) && std::isfinite(inc.yy) && std::isfinite(inc.xy)) {
      sum_[t].xx += inc.xx;
      sum_[t].yy += inc.yy;
      sum_[t].xy += inc.xy;
    } else {
      ++gaps_[t];
    }
  }
}

}  // namespace tirstrain::strain
