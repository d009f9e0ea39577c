#include "pipeline/validate_rings.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/csv.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t kWhole = 4;  // coverage_pct_ slot of the whole contact

double mean_of(const std::vector<double>& v) {
  return v.empty() ? kNaN : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double min_of(const std::vector<double>& v) {
  return v.empty() ? kNaN : *std::min_element(v.begin(), v.end());
}

}  // namespace

const std::array<ContactRing, 4>& contact_rings() {
  static const std::array<ContactRing, 4> rings = {
      ContactRing{0.0, 0.5, "0-0.5"}, ContactRing{0.5, 0.85, "0.5-0.85"},
      ContactRing{0.85, 0.95, "0.85-0.95"}, ContactRing{0.95, 1.0, "0.95-1"}};
  return rings;
}

RingValidation::RingValidation(const cv::Mat& truth_mask, const contact::Ellipse& ellipse)
    : ring_index_(truth_mask.size(), CV_8S, cv::Scalar(-1)), ellipse_(ellipse) {
  for (int y = 0; y < truth_mask.rows; ++y)
    for (int x = 0; x < truth_mask.cols; ++x) {
      if (truth_mask.at<std::uint8_t>(y, x) == 0) continue;
      // The outline's pixels beyond the fitted ellipse belong to the outermost ring.
      const double rho = std::min(normalised_radius({static_cast<double>(x), static_cast<double>(y)}), 1.0);
      const int ring = ring_of_radius(rho);
      ring_index_.at<std::int8_t>(y, x) = static_cast<std::int8_t>(ring);
      ring_area_px_[static_cast<std::size_t>(ring)] += 1.0;
    }
}

double RingValidation::normalised_radius(Vec2 p) const {
  const double c = std::cos(ellipse_.angle_rad), s = std::sin(ellipse_.angle_rad);
  const double dx = p.x - ellipse_.cx_px, dy = p.y - ellipse_.cy_px;
  const double along = (c * dx + s * dy) / ellipse_.semi_major_px;
  const double across = (-s * dx + c * dy) / ellipse_.semi_minor_px;
  return std::hypot(along, across);
}

int RingValidation::ring_of_radius(double rho) {
  const auto& rings = contact_rings();
  for (std::size_t r = 0; r < rings.size(); ++r)
    if (rho < rings[r].outer || (r + 1 == rings.size() && rho <= rings[r].outer)) return static_cast<int>(r);
  return -1;
}

int RingValidation::ring_of(Vec2 p) const {
  return ring_of_radius(normalised_radius(p));
}

void RingValidation::add_track(Vec2 true_current_px, Vec2 error_px, const std::array<double, 3>& c) {
  const int ring = ring_of(true_current_px);
  if (ring < 0) return;
  const auto r = static_cast<std::size_t>(ring);
  displacement_[r].add(std::hypot(error_px.x, error_px.y));
  const double det = c[0] * c[2] - c[1] * c[1];
  if (!(det > 0.0)) return;
  // eᵀC⁻¹e, per coordinate.
  const double d2 = (c[2] * error_px.x * error_px.x - 2.0 * c[1] * error_px.x * error_px.y +
                     c[0] * error_px.y * error_px.y) /
                    det;
  displacement_z_[r].add(std::sqrt(0.5 * d2));
}

void RingValidation::add_triangle(Vec2 true_current_centroid_px, const Strain2& error, const Strain2& sd) {
  const int ring = ring_of(true_current_centroid_px);
  if (ring < 0) return;
  const auto r = static_cast<std::size_t>(ring);
  auto& acc = strain_[r];
  acc[0].add(error.xx);
  acc[1].add(error.yy);
  acc[2].add(error.xy);
  if (sd.xx > 0.0) strain_z_[r].add(error.xx / sd.xx);
  if (sd.yy > 0.0) strain_z_[r].add(error.yy / sd.yy);
  if (sd.xy > 0.0) strain_z_[r].add(error.xy / sd.xy);
}

void RingValidation::add_frame_coverage(const std::vector<std::array<Vec2, 3>>& triangles_px) {
  cv::Mat covered(ring_index_.size(), CV_8U, cv::Scalar(0));
  // Sub-pixel vertices (4 fractional bits) so that adjacent triangles tile without gaps or overlaps.
  constexpr int kShift = 4;
  for (const auto& t : triangles_px) {
    std::array<cv::Point, 3> v;
    for (std::size_t i = 0; i < 3; ++i)
      v[i] = {static_cast<int>(std::lround(t[i].x * (1 << kShift))),
              static_cast<int>(std::lround(t[i].y * (1 << kShift)))};
    cv::fillConvexPoly(covered, v.data(), 3, cv::Scalar(1), cv::LINE_8, kShift);
  }
  std::array<double, 4> hit{};
  for (int y = 0; y < covered.rows; ++y)
    for (int x = 0; x < covered.cols; ++x) {
      const int ring = ring_index_.at<std::int8_t>(y, x);
      if (ring >= 0 && covered.at<std::uint8_t>(y, x) != 0) hit[static_cast<std::size_t>(ring)] += 1.0;
    }
  double hit_all = 0.0, area_all = 0.0;
  for (std::size_t r = 0; r < hit.size(); ++r) {
    if (ring_area_px_[r] > 0.0) coverage_pct_[r].push_back(100.0 * hit[r] / ring_area_px_[r]);
    hit_all += hit[r];
    area_all += ring_area_px_[r];
  }
  if (area_all > 0.0) coverage_pct_[kWhole].push_back(100.0 * hit_all / area_all);
}

double RingValidation::mean_coverage_pct(int ring) const {
  return mean_of(coverage_pct_[ring < 0 ? kWhole : static_cast<std::size_t>(ring)]);
}

double RingValidation::min_coverage_pct(int ring) const {
  return min_of(coverage_pct_[ring < 0 ? kWhole : static_cast<std::size_t>(ring)]);
}

std::vector<ErrorStats> RingValidation::rows() const {
  std::vector<ErrorStats> rows;
  const auto coverage_row = [&](const std::string& label, std::size_t slot) {
    ErrorAccumulator deficit;
    for (double pct : coverage_pct_[slot]) deficit.add(100.0 - pct);
    rows.push_back(deficit.stats("coverage_deficit_" + label, "truth mask", "", "%"));
  };
  coverage_row("contact", kWhole);
  const auto& rings = contact_rings();
  for (std::size_t r = 0; r < rings.size(); ++r) coverage_row("ring_" + rings[r].label, r);
  static constexpr const char* kNames[3] = {"E_xx", "E_yy", "E_xy"};
  for (std::size_t r = 0; r < rings.size(); ++r) {
    rows.push_back(displacement_[r].stats("displacement_ring_" + rings[r].label, "tracks", "", "px"));
    for (std::size_t c = 0; c < 3; ++c)
      rows.push_back(
          strain_[r][c].stats(std::string(kNames[c]) + "_ring_" + rings[r].label, "point", "", ""));
    rows.push_back(displacement_z_[r].stats("displacement_z_ring_" + rings[r].label, "predicted sd", "", ""));
    rows.push_back(strain_z_[r].stats("strain_z_ring_" + rings[r].label, "predicted sd", "", ""));
  }
  return rows;
}

void RingValidation::write_csv(const std::string& path) const {
  CsvWriter csv(path, {"ring", "rho_from", "rho_to", "area_px", "coverage_mean_pct", "coverage_min_pct",
                       "displacement_rms_px", "E_xx_rms", "E_yy_rms", "E_xy_rms", "displacement_z_rms",
                       "strain_z_rms", "tracks", "triangles"});
  const auto& rings = contact_rings();
  double area_all = 0.0;
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const ErrorStats d = displacement_[r].stats("", "", "", "");
    std::array<double, 3> e{};
    for (std::size_t c = 0; c < 3; ++c) e[c] = strain_[r][c].stats("", "", "", "").rms;
    csv.row_text({rings[r].label, format_double(rings[r].inner), format_double(rings[r].outer),
                  format_double(ring_area_px_[r]), format_double(mean_of(coverage_pct_[r])),
                  format_double(min_of(coverage_pct_[r])), format_double(d.rms), format_double(e[0]),
                  format_double(e[1]), format_double(e[2]),
                  format_double(displacement_z_[r].stats("", "", "", "").rms),
                  format_double(strain_z_[r].stats("", "", "", "").rms), std::to_string(d.samples),
                  std::to_string(strain_[r][0].n)});
    area_all += ring_area_px_[r];
  }
  csv.row_text({"contact", "0", "1", format_double(area_all), format_double(mean_of(coverage_pct_[kWhole])),
                format_double(min_of(coverage_pct_[kWhole])), "", "", "", "", "", "", "", ""});
  csv.commit();
}

}  // namespace tirstrain::pipeline
