#pragma once
// When the tracker may report a model in place of a track's own match (the affine fit of a frame at rest,
// the neighbour fusion): only where that frame's own evidence accepts it. The evidence is each track's own
// match, with the covariance its subset predicts for it (the subset's Hessian and the match's residual),
// and the residuals of those matches about the model. A model whose residuals are larger than the matches'
// noise, or spatially structured, describes a motion the model lacks: the matches are reported instead.
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/tensor2.hpp"

namespace tirstrain::flow {

// What a track reports in a frame: its own match, or a model that a test on the frame accepted. Written
// per frame and track as /tracks/model (docs/formats.md).
enum class TrackModel : std::uint8_t {
  kOwnMatch = 0,        // the track's own subset match
  kFused = 1,           // the neighbour fusion's position, within the own match's noise (mahalanobis2)
  kRestFit = 2,         // the affine fit of a frame at rest (RestTest accepted it)
  kSmoothedInTime = 3,  // smoothed in time after tracking, within the own match's noise
  kLocalFit = 4,        // a local affine fit of the neighbours' matches (flow/local_fit.hpp accepted it)
  kAffineFit = 5,       // the affine fit of a moving frame (test_affine_model accepted it)
};
const char* to_string(TrackModel model);

// A track's own match: where its subset put it and how well.
struct OwnMatch {
  Vec2 reference_px;               // X
  Vec2 position_px;                // x from the match alone
  Eigen::Matrix2d covariance_px2;  // of position_px, predicted (predicted_match_covariance)
};

// The covariance of a translation match's position, px²: σ_d² H⁻¹, where H = Σ ∇f ∇fᵀ over the subset
// (`information` is H over the subset's energy Σ f², as Subset reports it) and σ_d² the variance of the
// matched pixels' difference, from the match's correlation: Σ (f − g)² ≈ 2 (1 − ZNCC) Σ f². Smoothing
// both frames by a Gaussian of σ_p correlates the residual over about 4π σ_p² pixels (`correlated_pixels`,
// counted on the subset's own lattice), which the sum over pixels would otherwise count as independent.
// A direction whose information is below 2e-3 of the other's, which the match leaves at its start, has
// kUnmeasuredVariance_px2 instead.
Eigen::Matrix2d predicted_match_covariance(double zncc, std::size_t pixel_count,
                                           const Eigen::Matrix2d& information, double correlated_pixels);

// The variance predicted_match_covariance gives a direction the texture does not determine (straight
// ridges along them, a frame without texture), px²: the match keeps its start there, which may be off by the
// tracker's reach; a position with such a direction is not measured along it.
inline constexpr double kUnmeasuredVariance_px2 = 100.0;
// Whether a predicted covariance has such a direction.
bool has_unmeasured_direction(const Eigen::Matrix2d& covariance_px2);

// How many matched pixels share one noise sample after a Gaussian prefilter of σ_p on a lattice of stride s.
double correlated_pixels(double prefilter_sigma_px, int stride);

// (shift)ᵀ C⁻¹ (shift): a shift from the own match in units of its noise; χ² with 2 degrees of freedom
// if the shift is noise alone (99.9 %: 13.8).
double mahalanobis2(Vec2 shift_px, const Eigen::Matrix2d& covariance_px2);

// The χ²(2) quantile a model's shift of one track must stay under to replace its own match.
constexpr double kModelShiftChi2 = 13.8;

struct RestTestOptions {
  // The residuals' χ² per degree of freedom must stay under this (1: the matches' predicted noise).
  double max_chi2_per_dof = 1.5;
  // Spatial structure: the correlation of neighbouring residuals is significant (z-score above
  // `max_correlation_z`) and large enough to matter (above `max_correlation`: a correlation ρ puts about ρ
  // of the residuals' variance into a shared pattern, of about sqrt(ρ) of the noise's amplitude).
  // Thousands of pairs make even ρ ≈ 0.1 significant, and that much appears at true rest under a slow
  // drift of the illumination (the noisy synthetic scenes' rest frames: 0.06-0.10).
  double max_correlation_z = 3.0;
  double max_correlation = 0.2;
  // Two tracks whose matches share no pixel and no neighbour lie at least this far apart (px); the
  // correlation is taken over the pairs between this distance and this plus `pair_band_px`.
  double independence_px = 30.0;
  double pair_band_px = 16.0;
  // Fewer pairs than this: the spatial test cannot speak, and the frame is not at rest.
  int min_pairs = 20;
  int min_tracks = 6;
  // The fitted motion is nil when its RMS over the tracks is within `tolerance_px`, or when its six
  // parameters are zero within their uncertainty (χ²(6) at most `max_motion_chi2`, 22.5: 99.9 %); tracks
  // share noise over `correlated_tracks` of them (overlapping subsets).
  double tolerance_px = 0.01;
  double max_motion_chi2 = 22.5;
  double correlated_tracks = 1.0;
};

// The affine model d = a + B (X − X0) of the own matches' displacements, and the test of it.
struct RestTest {
  int tracks = 0;
  int pairs = 0;
  double chi2_per_dof = std::numeric_limits<double>::quiet_NaN();
  double correlation = std::numeric_limits<double>::quiet_NaN();
  double correlation_z = std::numeric_limits<double>::quiet_NaN();
  bool affine = false;  // the affine model describes the matches (χ² and correlation within bounds)
  double motion_rms_px = std::numeric_limits<double>::quiet_NaN();  // the fitted motion over the tracks
  double motion_chi2 = std::numeric_limits<double>::quiet_NaN();    // the fit's parameters against zero
  bool accepted = false;                                            // affine and nil: at rest
  Vec2 origin_px;                                                   // X0
  Eigen::Matrix<double, 3, 2> coefficients = Eigen::Matrix<double, 3, 2>::Zero();  // rows a, B's columns
  Vec2 displacement_px(Vec2 reference_px) const;
  Gradient2 gradient() const;
};

// Fits the affine model to the matches and tests it: χ² of the residuals whitened by each match's
// covariance, the correlation of whitened residuals between independent neighbours, and the fitted
// motion against zero.
RestTest test_affine_model(const std::vector<OwnMatch>& matches, const RestTestOptions& options);

}  // namespace tirstrain::flow
