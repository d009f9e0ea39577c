#pragma once
// `validate`'s accounting of a processed trial against its exact field (pipeline/validate.cpp): what it reads
// of result.h5, and the errors of the tracks, plate, strain, energy and stick zone, frame by frame.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/h5_file.hpp"
#include "core/tensor2.hpp"
#include "pipeline/error_accumulator.hpp"
#include "pipeline/validate.hpp"
#include "pipeline/validate_rings.hpp"
#include "samples/trial.hpp"

namespace tirstrain::pipeline {

// The datasets of result.h5 that validate compares, flat as H5Reader returns them.
// The result's per-frame track and strain rows of one frame: a long trial's whole arrays do not fit in
// memory, so they are read a frame at a time (ValidatedResult::frame_rows).
struct FrameRows {
  std::vector<double> position, covariance;    // [K, 2], [K, 3]
  std::vector<double> total, other, total_sd;  // [T, 3]
  std::vector<double> stuck;                   // [T]: 1 stuck, 0 slipping, −1 not labelled
};

struct ValidatedResult {
  std::string path;
  std::shared_ptr<const H5Reader> h5;  // open for the per-frame rows
  std::size_t frames = 0, tracks = 0, triangles_count = 0;
  std::vector<double> t_s;
  std::vector<double> reference;                   // [K, 2]
  std::vector<double> plate;                       // [N, 2]
  std::vector<double> triangles;                   // [T, 3] vertex track ids
  std::string mode, other_mode;                    // strain mode of /strain/total and the other one
  std::vector<double> energy, stick_ratio, c_fit;  // [N]
  // Where no slip shows within the tracks although the core moved (/stick/radius_status 3): the tracks'
  // reach × a, mm (NaN on other frames).
  std::vector<double> c_reach;
  double tolerance_px = 0.0;                         // the stick test's
  std::size_t reference_row = 0;                     // the tracks' reference frame
  std::vector<std::int64_t> contact_status;          // [N]
  std::vector<double> hull, ellipses, contact_area;  // [N, H, 2], [N, 5], [N]
  std::size_t hull_values = 0;                       // H × 2
  // [N, 2]: each frame's own ellipse centre before the smoothing in time (empty in results without it).
  std::vector<double> measured_centres;
  // What the result was processed with (its /contact and /energy attributes; NaN where absent). Lengths
  // and areas in mm, and U, are in these: validate takes measured lengths back to pixels through
  // px_per_mm, and says when any of them differs from the trial's.
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  double px_per_mm = kUnknown, young_Pa = kUnknown, poisson = kUnknown, depth_m = kUnknown;
};

// Reads and checks RESULT_DIR/result.h5 against the trial (frame count and times).
ValidatedResult read_validated_result(const std::string& result_path, const samples::Trial& trial);
// What the result was processed with that differs from the trial's scene ("px_per_mm 52 where the trial's
// is 100"), one entry per value; empty when they agree.
std::vector<std::string> calibration_differences(const ValidatedResult& result, const Scene& trial_scene);
// Frame i's rows of the per-frame track and strain datasets (NaN where a dataset is absent).
FrameRows frame_rows(const ValidatedResult& result, std::size_t i);

// Errors against the exact field, accumulated frame by frame; rings: the same errors by ring of the contact.
class FieldValidation {
 public:
  FieldValidation(const samples::Trial& trial, const ValidatedResult& result, const ValidateOptions& options,
                  RingValidation& rings);

  void add_frame(std::size_t i);
  // After the last frame: the errors taken over frames (energy, stick radius).
  void finish();
  // validation.csv's rows for these quantities, in its order.
  void append_rows(std::vector<ErrorStats>& rows) const;
  // validation_frames.csv: per frame, these errors and the contact's (IoU, centre px, semi-axes %).
  void write_frames_csv(const std::string& path, const std::vector<std::array<double, 4>>& contact) const;
  // The frame of largest true energy (the default map frame).
  std::size_t energy_peak_frame() const { return u_argmax_; }

 private:
  using Accumulator = ErrorAccumulator;
  void add_tracks(std::size_t i, const samples::FrameField& field, const samples::LoadState& load);
  void add_triangles(std::size_t i, const samples::FrameField& field, const samples::LoadState& load);
  struct FrameSums;
  void add_triangle(std::size_t i, std::size_t t, const samples::FrameField& field,
                    const samples::LoadState& load, FrameSums& sums);
  const Strain2& advance_truth_increments(std::size_t i, std::size_t t, const std::array<Vec2, 3>& X,
                                          const Gradient2& h_true, const Strain2& e_triangle);
  void add_interior_errors(std::size_t cell, const Strain2& measured, const Strain2& e_point,
                           const Strain2& e_triangle, const Strain2& sum_truth);
  // The strain sum of the incremental mode, whichever mode /strain/total holds (this frame's rows).
  const std::vector<double>& incremental_total() const {
    return r_.mode == "incremental" ? rows_.total : rows_.other;
  }
  void add_contact_energy(std::size_t i);
  void add_stick_fits(std::size_t i, const samples::FrameField& field);
  void finish_energy();
  void finish_stick_radius();
  Accumulator& acc(const std::string& quantity, const std::string& reference, const std::string& mode);
  Accumulator acc_or_empty(const std::string& quantity, const std::string& reference,
                           const std::string& mode) const;

  const samples::Trial& trial_;
  const ValidatedResult& r_;
  const ValidateOptions& options_;
  RingValidation& rings_;
  double young_, nu_, depth_, px_per_mm_, m_per_px_, border_px_;

  std::map<std::string, Accumulator> acc_;  // key: quantity|reference|mode
  double gain_mt_ = 0.0, gain_tt_ = 0.0;
  Accumulator c_exact_error_, c_true_contact_error_;
  Accumulator energy_triangle_error_, energy_interior_error_, energy_contact_error_;
  std::array<Accumulator, 3> displacement_by_depth_;  // tracks < 0.5, 0.5-1, > 1 mm inside the border
  Accumulator displacement_, displacement_interior_, plate_error_, energy_error_, stick_error_, c_error_,
      c_label_error_, c_all_error_, c_of_a_error_, c_unseen_;
  Accumulator energy_other_error_, energy_increments_error_;
  std::vector<double> c_exact_tracks_, c_true_contact_;
  std::vector<double> u_truth_triangle_, u_interior_, u_truth_interior_;
  std::vector<double> u_truth_, u_truth_contact_, ratio_truth_, c_labels_, c_model_, disp_rms_, exx_rms_;
  std::vector<double> u_other_, u_truth_increments_;
  // The paper's running sum of increments applied to the exact vertex positions, per triangle.
  std::vector<Strain2> increments_truth_;
  std::vector<Vec2> true_now_, true_before_;
  FrameRows rows_;                         // the frame being added
  std::vector<double> previous_position_;  // the frame before's /tracks/position_px row
  std::size_t previous_frame_ = SIZE_MAX;  // which frame that is
  std::size_t u_argmax_ = 0;
};

}  // namespace tirstrain::pipeline
