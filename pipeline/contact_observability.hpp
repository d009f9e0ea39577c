#pragma once
// How well can a synthetic trial's contact ellipse be located at all, from what its image shows?
//
// Inside the contact a TIR image shows ridges; a valley in contact reflects like the background. So where a
// valley lies along the border the image does not say where in that valley the border is, while where a ridge
// crosses the border its end marks it. This computes the range of truth-ellipse centres that agree with every
// pixel where the image shows a ridge in contact (must stay inside) and every pixel just outside where a
// ridge would show had the contact reached it (must stay outside). "Shows" means a ridge signal above k_sigma
// times the scene's pixel noise. Alternatives are the truth's border plus radial Fourier modes 0..5
// (modes 3..5 bounded by twice the generator's border irregularity); the constraints are linear in the mode
// amplitudes, so the extreme centres along each direction come from a linear programme (log-barrier Newton).
//
// The observer this describes knows the ridge flow just outside the contact (a ridge continues past its end),
// ignores the fade of ridge contrast towards the border (the generator's law, not the finger's), and detects
// a ridge pixel by pixel at k_sigma. Half the width of the feasible range is then the worst-case centre error
// such an observer must accept; a segmenter that integrates along a ridge sees fainter flanks (a lower
// k_sigma), and the range narrows. On the shipped scenes it is 0.04-0.13 px at 2 sigma, so the 1 px target is
// within what the frames show; with the fingerprint's core under a tiny contact, ridges run along the whole
// border and it is 1.6 px at 2 sigma, 0.2 px at 0.2 sigma (BENCHMARKS.md, contact/).
#include <opencv2/core/mat.hpp>

#include <optional>

#include "contact/ellipse.hpp"
#include "samples/trial.hpp"

namespace tirstrain::pipeline {

struct ObservabilityOptions {
  double k_sigma = 2.0;     // a ridge shows where its signal exceeds this many noise standard deviations
  double band_px = 25.0;    // pixels further than this from the truth's border do not constrain it
  int directions = 12;      // centre ranges are measured along this many directions over 180 degrees
  double mode_bound = 2.0;  // modes 3..5 bounded by this times the generator's irregularity prior
};

struct CentreBound {
  int inside_pixels = 0;       // ridge shows, inside the truth
  int outside_pixels = 0;      // a ridge would show, outside the truth
  int hidden_pixels = 0;       // within band_px of the border but no ridge signal either way
  double half_range_px = 0.0;  // half the widest feasible range of the truth ellipse's centre
  double direction_deg = 0.0;  // along which (from +x towards +y)
  double noise_sigma = 0.0;    // pixel noise used, fraction of full scale
};

// The truth's contact ellipse as `tirstrain validate` and the tests take it: the direct fit of the truth
// mask's outline (pixel centres; not those on the frame's edge, where a contact cut by the frame has no
// outline of its own), semi-axes + 0.5 px to the pixels' outer edges. `mask`: CV_8UC1, non-zero in.
std::optional<contact::Ellipse> truth_contact_ellipse(const cv::Mat& mask);

// Throws Error when the trial has no contact or the programme is infeasible at the truth (a bug).
CentreBound contact_centre_bound(const samples::Trial& trial, int frame,
                                 const ObservabilityOptions& options = {});

}  // namespace tirstrain::pipeline
