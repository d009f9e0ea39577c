#pragma once
// Per-frame fit of the Hertz + Cattaneo–Mindlin surface displacement field to tracked displacements
// (docs/model.md, docs/formats.md "fit.csv / fit.h5"). Four fields compete on each frame — rest (no
// tangential load), full stick, partial slip, full slip (c = 0) — each a robust (Huber) Ceres fit of the
// contact centre, the load direction, the contact radius a and the load scale (and c/a for partial slip);
// AIC and BIC on the robust cost choose the field. An elliptical contact is fitted in the frame that maps the
// segmented ellipse onto a circle of the same area (the convention of tirstrain synth's truth). Given the
// trial's μP (fit/fit_result.hpp, trial_limit), partial slip is fitted with μP held there.
#include <array>
#include <cstdint>
#include <vector>

#include "core/tensor2.hpp"
#include "fit/cm_field.hpp"

namespace tirstrain::fit {

struct FitOptions {
  int min_tracks = 20;           // fewer usable tracks: status too_few_tracks, no fit (default 20)
  double loss_scale_px = 0.3;    // Huber loss scale, px: residuals beyond it count linearly (default 0.3)
  double contact_margin = 1.05;  // tracks used: reference within this many ellipse radii (default 1.05)
  double radius_prior_sd =
      0.01;  // SD of the segmented centre and radius over a, a prior on them; 0: none (0.01)
  double prior_noise_px = 0.05;  // tracking noise that prior is weighed against, px (default 0.05)
  // A loaded field that moves no used track by more than this is reported as rest, px: below the tracker's
  // own rest tolerance a fit's load is not a measured one, however significant its criteria find it
  // (default 0.01)
  double rest_tolerance_px = 0.01;
  int max_iterations = 30;  // Ceres iterations per field (default 30)
  int threads = 1;          // Ceres threads per solve (default 1)
};

// The segmented contact ellipse, as /contact/ellipse stores it.
struct ContactEllipse {
  double cx_px = 0.0, cy_px = 0.0;
  double semi_major_px = 0.0, semi_minor_px = 0.0;
  double angle_rad = 0.0;  // major axis from +x towards +y
};

// One frame's observations: tracks alive in it and the scene's calibration and tissue.
struct FrameObservations {
  std::vector<Vec2> reference_px;     // X per track
  std::vector<Vec2> displacement_px;  // x − X per track; a non-finite entry marks a track absent this frame
  bool has_contact = false;           // false: no ellipse in this frame
  ContactEllipse contact;
  double px_per_mm = 0.0;  // calibration
  double young_Pa = 0.0;   // tissue E
  double poisson = 0.0;    // tissue nu
};

enum class FitStatus : int {
  ok = 0,
  no_contact = 1,      // no ellipse in the frame: nothing fitted
  too_few_tracks = 2,  // fewer than min_tracks usable tracks: nothing fitted
  no_covariance = 3,   // fitted, but the Jacobian is rank deficient: the SDs are NaN
};
const char* fit_status_name(FitStatus s);

// A value and its standard deviation; NaN where the chosen field does not define it (e.g. μP for full
// stick) or the frame was not fitted (see FrameFit::status).
struct Estimate {
  double value = 0.0;
  double sd = 0.0;
};

struct FrameFit {
  FitStatus status = FitStatus::ok;
  FieldModel model = FieldModel::rest;  // the field chosen (lowest BIC; rest: see shared_residuals)
  int tracks_used = 0;
  Estimate centre_x_px, centre_y_px;
  Estimate direction_deg;        // tangential traction on the skin, from +x towards +y, in (−180, 180]
  Estimate a_mm;                 // contact radius (equivalent radius √(a₁a₂) for an ellipse)
  Estimate c_mm;                 // stick radius: a for full stick, 0 for full slip
  Estimate tangential_N;         // Q; 0 for rest
  Estimate limit_N;              // μP; partial and full slip only
  double residual_rms_px = 0.0;  // RMS of |measured − model| over the tracks used
  // How many tracks' worth of residual each track shares with its neighbours (≥ 1), measured from the
  // partial-slip fit's residuals (overlapping subsets and any spatial averaging make neighbours' errors
  // alike). Rest against any load is decided by BIC over 2 × tracks_used / shared_residuals independent
  // residuals; among the loaded fields by `bic` (every residual counted).
  double shared_residuals = 1.0;
  std::array<double, kFieldModels> aic{}, bic{};  // by FieldModel value
  std::vector<Vec2> residual_px;  // measured − model per input track; NaN for tracks not used
  // The used tracks' 90th-percentile distance from the fitted centre, in units of the fitted a (NaN at rest):
  // how far out the frame is observed, and so whether its slip annulus is.
  double tracked_radius = 0.0;
  // Partial slip with μP held at the trial's (TrialLimit) rather than fitted: c then follows from the stick
  // zone's shift, which the tracks see even where the annulus lies beyond them.
  bool limit_from_trial = false;
};

// The trial's friction limit μP, measured on its frames whose slip annulus the tracks resolve
// (fit/fit_result.hpp, trial_limit).
struct TrialLimit {
  double limit_N = 0.0;
  double sd_N = 0.0;
  int frames = 0;  // frames it was measured on
};

// Fits one frame. Throws nothing for data problems (they are statuses); invalid calibration or tissue
// (non-positive px_per_mm or E, nu outside (−1, 0.5)) throws Error.
//
// With `limit`, partial slip is fitted with μP held at the trial's, and full stick (the μP → ∞ limit of
// partial slip, which the trial's own frames contradict) is no longer a candidate: a frame is at rest, in
// partial slip at the trial's μP, or in full slip. Its criteria are still reported.
FrameFit fit_frame(const FrameObservations& obs, const FitOptions& options,
                   const TrialLimit* limit = nullptr);

}  // namespace tirstrain::fit
