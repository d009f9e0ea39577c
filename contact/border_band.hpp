#pragma once
// The contact ellipse from the intensities of the band around its border
// (SegmenterOptions::border_band_centre).
//
// The ridge labels (contact/ridge_labels.hpp) threshold each pixel and place each sector's border between its
// labels; where a valley runs along the border, that placement is a guess within the valley, and the guess is
// the same on every frame of a fingerprint. Here every pixel of the band is compared with a model of the
// ridges cut by the border, and the ellipse is the one whose model explains the band best:
//
//   signal(x) = A(d) (c0 + c1_k cos(k_k . x) + c2_k sin(k_k . x)),
//   A(d)      = logistic(-d / edge_px) (floor + (1 - floor) smoothstep5(-d / fade_px)),
//
// with d the signed distance from the ellipse (> 0 outside), k_k sector k's ridge wave vector (from the
// window inside the border, refined against the band), c0 the ridges' mean level (common to all sectors:
// without it, a sector with one ridge in the band could trade its own gain against the border's place), c1_k
// and c2_k each sector's phase and amplitude (solved exactly for each trial ellipse: variable projection),
// and A the border: a soft step of width edge_px, with the ridges' contrast rising from `floor` at the border
// to full fade_px inside, as the contact pressure does (both fitted). A valley along the border still hides
// the border, but the contrast of the last ridge inside, against the common level, says how far in it lies; a
// ridge that ends at the border pins it.
//
// On synthetic trials with exact truth (BENCHMARKS.md, contact/): alone, the centre is
// no better than the labels' on average; the mean of the two is (their errors are partly independent), and on
// frames too noisy for labels it replaces the level edge's centre. The profile's form is the synthetic
// generator's (a quintic rise), with its floor and length fitted; where the contrast fades little towards
// the border the valley arcs carry little, and the fit can cost more than it gives.
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <optional>
#include <vector>

#include "contact/ellipse.hpp"

namespace tirstrain::contact {

struct BorderBandSample {
  int sector = 0;
  float x_px = 0.0f, y_px = 0.0f;
  float signal = 0.0f;  // ridge signal: ridges positive, the background's level 0
  // From the sector wave's origin (the phase k . x is taken from there).
  float dx_px = 0.0f, dy_px = 0.0f;
};

struct BorderBandOptions {
  // Levenberg-Marquardt iterations per fit. With the analytic Jacobian 3 give the centres 5 do (within
  // 0.01 px over 13 fingerprints: the start is near) at ~20 % less time for the whole segmentation.
  int iterations = 3;
  int wave_rounds = 2;  // refinements of the sectors' wave vectors, each followed by a refit
  double initial_edge_px = 1.0;
  double initial_floor = 0.4;
  double initial_fade_periods = 0.8;
};

struct BorderBandFit {
  Ellipse ellipse;
  double edge_px = 0.0, fade_floor = 0.0, fade_px = 0.0;  // the fitted border profile A(d)
  double rms_residual = 0.0;                              // signal units
};

// The model's eight parameters: the ellipse (cx_px, cy_px, semi-axes a and b in px, angle in rad), then the
// profile (edge_px, floor, fade_px).
using BorderBandParams = Eigen::Matrix<double, 8, 1>;
using BorderBandGradient = Eigen::Matrix<double, Eigen::Dynamic, 8>;

// The border profile A(d) at each sample and (optional) its derivatives with respect to the parameters, one
// column each: the fit's Jacobian is built from them in one pass. d is approximated by r (1 - 1/q), r the
// distance from the centre and q the normalised radius, as in the ridge labels' logistic fit.
Eigen::VectorXd border_profile(const std::vector<BorderBandSample>& samples, const BorderBandParams& p,
                               BorderBandGradient* gradient = nullptr);

// `samples`: the band's pixels (ridge signal, sector), `wave_vectors`: per sector its ridges' wave vector
// (rad/px; a zero vector for a sector without a wave), `start`: the ellipse to start from (frame px).
// Nothing when too few samples, no ridges in the band, or values that are not finite.
std::optional<BorderBandFit> fit_border_band(std::vector<BorderBandSample> samples,
                                             std::vector<cv::Vec2d> wave_vectors, const Ellipse& start,
                                             double period_px, const BorderBandOptions& options = {});

}  // namespace tirstrain::contact
