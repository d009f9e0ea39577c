#pragma once
// How well a frame's ridge texture can be matched: the ridges' contrast against the sensor noise, measured
// inside the contact. The automatic preset uses it to decide how much model the subsets can afford (a
// second-order shape function's six curvature terms follow the noise when the ridges are faint).
#include <opencv2/core.hpp>

namespace tirstrain::flow {

struct TextureQuality {
  double noise_sigma = 0.0;  // pixel noise, standard deviation (image full scale 1)
  double ridge_rms = 0.0;    // RMS of the ridge band (periods P/2..2P, roughly) over the contact interior
  double snr = 0.0;          // ridge_rms / noise_sigma
  int pixels = 0;            // interior pixels measured; 0 = nothing to measure (snr is then 0)
  // How one-dimensional the texture is at the ridge scale: the structure tensor's coherence
  // (λ1 − λ2) / (λ1 + λ2), integrated over P/2 and averaged over the interior weighted by its energy.
  // Fingerprint ridges 0.5–0.95; isotropic texture (speckle) well under 0.3.
  double coherence = 0.0;
  // The texture has ridges (coherence ≥ kMinRidgeCoherence): the ridge period and the SNR above describe
  // it. Without ridges the heuristics sized from the period (smoothing, the low-SNR subsets) do not apply.
  bool ridges = false;
  // Mean squared intensity gradient per pixel and direction, (⟨g_x²⟩ + ⟨g_y²⟩) / 2 (full scale 1 per px):
  // with the noise, what a subset of n pixels pins its translation to, σ ≈ sqrt(2 σ_n² / (n ⟨g²⟩)).
  double gradient_energy = 0.0;
};

constexpr double kMinRidgeCoherence = 0.35;

// `image` CV_32F (full scale 1), `mask` CV_8U (non-zero = contact) of the same size or empty. The noise is
// Immerkær's estimator (the mean absolute response to a kernel that cancels any locally linear, and very
// nearly any ridge-like, signal), the ridge level the RMS of a difference of Gaussians at σ = P/8 and P/2.
// Pixels within P/2 of the contact border are left out: the border's step is neither ridge nor noise.
TextureQuality measure_texture(const cv::Mat& image, const cv::Mat& mask, double ridge_period_px);

}  // namespace tirstrain::flow
