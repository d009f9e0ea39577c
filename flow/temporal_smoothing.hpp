#pragma once
// Smoothing of a track's position series in time, with a window chosen frame by frame by the intersection
// of confidence intervals (ICI; Katkovnik's rule). At each frame, local linear fits over 1..32 frames to the
// left, to the right and centred are lengthened while each new estimate's interval (±gamma standard
// deviations) still overlaps those of the shorter windows; the longest consistent window of each side is
// kept and the three are fused by inverse variance. Where the skin holds still or moves steadily the
// windows grow and average the noise; where the motion changes (the load's onset, the slip front passing)
// they shrink to a frame or two, so the change is not smeared. The noise level is each series' own, from
// its second and third differences (robust: median absolute deviation).
//
// Why it exists: on noisy texture (ridge SNR below 4) each frame's match is at its Cramér–Rao bound and the
// error is white in time, so only time can average it (bench/studies/temporal_smoothing.py). On clean texture
// there is little to average and a window one frame too long costs more than it removes, so the pipeline
// applies it only to noisy texture (pipeline/tracking_stage.cpp).
#include <span>
#include <vector>

namespace tirstrain::flow {

struct TemporalSmoothing {
  double gamma = 1.5;        // interval half-width in standard deviations of each window's estimate
  int max_half_window = 32;  // frames on each side
  int min_samples = 10;      // shorter series are returned as they are (too few to know their noise)
};

// Robust noise level of a series (σ of one sample, same unit as x) from its second and third differences.
double series_noise(std::span<const double> x);

// The smoothed series of samples x at times t_s (increasing), noise level sigma (<= 0: x returned as is).
std::vector<double> smooth_in_time(std::span<const double> t_s, std::span<const double> x, double sigma,
                                   const TemporalSmoothing& options = {});

}  // namespace tirstrain::flow
