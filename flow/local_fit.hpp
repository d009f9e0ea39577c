#pragma once
// Spatially adaptive averaging of the tracks' own matches, only as far as the frame's own evidence allows.
//
// A subset small enough to follow a field that varies over a few ridge periods is noisy where the field is
// smooth; a large window is quiet there and wrong where the field bends. Which one a place needs is not
// known in advance and differs across the frame (a creep under a hold, a slip annulus at the rim). For
// every track, local polynomial fits (second order, or affine) of its neighbours' displacements over growing
// windows are compared with each other and with the track's own match, and the widest window is kept whose
// fit (a) agrees with every smaller window's fit and with the own match within their predicted noise (the
// intersection of confidence intervals rule of local polynomial approximation) and (b) describes the
// matches inside it within their predicted noise (χ² of the residuals). A field that bends inside a window
// shows as a disagreement between the scales or as residuals above the noise, and stops the window from
// growing. Where no window passes, the track keeps its own match.
//
// Where the joint windows stop short of the whole frame, each component is tried alone against the frame's
// affine fit of that component: a field that bends in x and is affine in y (a chirp along x) stops the
// joint windows where x bends, while y is described by the whole frame. The component's fit is weighted by
// its own variances (the joint fit's correlated weights would carry the other component's misfit into it)
// and must pass the same two rules in that variance; it then reports the frame's fit
// (`component_radius_px`). The windows in between are not tried per component: a field with a shear step
// biases the matches' other component near the step, and a per-component window there spreads that bias
// while the residual test, diluted over a wide window, does not see it.
#include <Eigen/Core>

#include <array>
#include <limits>
#include <vector>

#include "flow/model_check.hpp"

namespace tirstrain::flow {

struct LocalFitOptions {
  // Window radii tried, px, smallest first (reference coordinates).
  std::vector<double> radii_px;
  // Two estimates agree when their difference, in the finer one's predicted covariance, is within this χ²
  // with 2 degrees of freedom (9.21: 99 %).
  double agreement_chi2 = 9.21;
  // The residuals of the matches inside a window must stay below this quantile of their χ² distribution
  // (0.999), counting overlapping subsets' shared noise (`correlation_side_px`).
  double residual_quantile_z = 3.09;
  // Side of the square over which one match's noise is shared with a neighbour's (the subset's side plus
  // the prefilter's reach), px: two matches whose subsets overlap by a fraction f share about f of their
  // noise, so an average over overlapping matches is quieter only by the independent area it covers.
  double correlation_side_px = 27.0;
  // After the largest radius, the affine fit of every match in the frame is tried as the widest window.
  bool whole_frame = true;
  // A window needs at least this many matches (an affine fit has 6 parameters in 2 n equations), and at
  // least as many as the fit has parameters.
  int min_tracks = 6;
  // The local fits' polynomial order: 2 (default) with the second-order terms, so a field that bends
  // smoothly is followed over wider windows before the scales disagree; 1 affine.
  int order = 2;
  // Where the joint windows stop, each displacement component tried alone against the frame's fit of it.
  bool per_component = true;
};

// What one track reports.
struct LocalFit {
  int window = -1;  // index into radii_px of the chosen window; -1: the own match; radii_px.size(): the frame
  double radius_px =
      0.0;         // the chosen window's radius (0: the own match; the whole frame: its farthest corner)
  int tracks = 1;  // matches inside the chosen window
  Vec2 displacement_px;                                      // at the track's reference position
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Zero();  // predicted, of displacement_px
  // The largest squared Mahalanobis distance between the chosen fit and a finer estimate (the own match
  // included), in that estimate's covariance; NaN for the own match.
  double agreement_chi2 = std::numeric_limits<double>::quiet_NaN();
  // The chosen fit's squared Mahalanobis distance from the own match, in the own match's covariance (with
  // its 0.001 px floor), as the agreement test took it (NaN for the own match).
  double own_mahalanobis2 = std::numeric_limits<double>::quiet_NaN();
  // The chosen window's residual χ² per degree of freedom (NaN for the own match).
  double residual_chi2_per_dof = std::numeric_limits<double>::quiet_NaN();
  // The radius each component's value comes from (x, y), px: radius_px, or the frame's reach where that
  // component alone passed the frame's fit (0: the own match).
  std::array<double, 2> component_radius_px{0.0, 0.0};

  // Whether any component reports a fit rather than the own match.
  bool reports_fit() const { return component_radius_px[0] > 0.0 || component_radius_px[1] > 0.0; }
};

// One LocalFit per match, in order. Matches with a singular covariance take part in no fit and keep
// their own.
std::vector<LocalFit> choose_local_fits(const std::vector<OwnMatch>& matches, const LocalFitOptions& options);

}  // namespace tirstrain::flow
