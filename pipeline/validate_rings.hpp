#pragma once
// Coverage and accuracy by ring of the true contact, for `validate`. Slip starts at the contact's periphery
// and the slip annulus grows inward, so an accuracy taken over the interior alone says nothing about where
// slip is measured. Rings are bands of the true contact ellipse's normalised radius ρ = r/a:
// [0, 0.5), [0.5, 0.85), [0.85, 0.95) and [0.95, 1] (the irregular true outline's few pixels beyond ρ = 1
// count in the last ring). Per ring:
//   coverage:     the fraction of the true contact's pixels covered by a triangle with a valid strain, the
//                 triangle drawn at its vertices' measured positions, every frame;
//   displacement: the tracks' error, by the ring of their true current position;
//   strain:       each valid triangle's E_xx, E_yy, E_xy against the exact strain at its centroid, by the
//                 ring of the centroid's true current position;
//   calibration:  the RMS of the errors in units of their predicted standard deviation (a track's
//                 Mahalanobis distance per coordinate, a strain component's error over its σ): 1 when the
//                 predicted uncertainty is right, below 1 when it is conservative.
#include <opencv2/core.hpp>

#include <array>
#include <string>
#include <vector>

#include "contact/ellipse.hpp"
#include "core/tensor2.hpp"
#include "pipeline/error_accumulator.hpp"
#include "pipeline/validate.hpp"

namespace tirstrain::pipeline {

struct ContactRing {
  double inner = 0.0;  // ρ from (inclusive)
  double outer = 0.0;  // ρ to (exclusive but for the last ring)
  std::string label;   // "0-0.5" ...
};

// The four rings the report uses.
const std::array<ContactRing, 4>& contact_rings();

class RingValidation {
 public:
  // truth_mask: CV_8U, non-zero inside the true contact (the same in every frame); ellipse: its direct fit.
  RingValidation(const cv::Mat& truth_mask, const contact::Ellipse& ellipse);

  // Index of the ring holding an image point, or −1 when it lies outside the last ring.
  int ring_of(Vec2 point_px) const;
  double normalised_radius(Vec2 point_px) const;

  // error_px: the track's error vector; covariance_px2 (xx, xy, yy): its predicted covariance (NaN: none).
  void add_track(Vec2 true_current_px, Vec2 error_px, const std::array<double, 3>& covariance_px2);
  // error: measured − exact strain; sd: its predicted standard deviation (NaN: none).
  void add_triangle(Vec2 true_current_centroid_px, const Strain2& error, const Strain2& sd);
  // One frame's valid triangles at their measured current positions.
  void add_frame_coverage(const std::vector<std::array<Vec2, 3>>& triangles_px);

  // Rows for validation.csv: coverage_deficit_ring_* (100 − covered % of the ring's area; mean over frames,
  // max_abs the worst frame), displacement_ring_*, E_xx_ring_* ... (RMS errors).
  std::vector<ErrorStats> rows() const;
  // Mean and lowest coverage (%) of the whole contact and of each ring.
  double mean_coverage_pct(int ring) const;  // ring −1: the whole contact
  double min_coverage_pct(int ring) const;
  void write_csv(const std::string& path) const;

 private:
  static int ring_of_radius(double rho);

  cv::Mat ring_index_;  // CV_8S: ring per pixel inside the truth mask, −1 elsewhere
  std::array<double, 4> ring_area_px_{};
  contact::Ellipse ellipse_;
  std::array<ErrorAccumulator, 4> displacement_, displacement_z_;
  std::array<ErrorAccumulator, 4> strain_z_;  // the three components pooled
  std::array<std::array<ErrorAccumulator, 3>, 4> strain_;
  std::array<std::vector<double>, 5> coverage_pct_;  // per ring, then the whole contact; one per frame
};

}  // namespace tirstrain::pipeline
