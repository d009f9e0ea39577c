#pragma once
// The contact ellipse's centre smoothed in time, after the trial.
//
// Each frame's centre is segmented on its own, and where the border runs along a ridge valley the centre is
// placed from what lies beside it (docs/contact.md), so it scatters from frame to frame by ~0.1 px even
// where the contact stands still (a hold, partial slip: the finger is held and the plate moves). The same
// intersection-of-confidence-intervals rule as the tracks' smoothing in time (flow/temporal_smoothing.hpp)
// averages that scatter over the frames where the centre holds still or moves steadily, and keeps a frame
// or two where it moves otherwise (the contact growing under the load's onset, a jump); no sample moves by
// more than 2 gamma sigma of its series' own noise. Runs of consecutive frames with a centre are smoothed
// apart, x and y each with its own noise; frame rows are the time axis (the contact's motion is smooth per
// frame whatever the timestamps' jitter). What stays is the centre's bias, which is the same on
// neighbouring frames.
#include <optional>
#include <span>
#include <vector>

#include "core/tensor2.hpp"
#include "flow/temporal_smoothing.hpp"

namespace tirstrain::pipeline {

struct CentreSmoothing {
  std::vector<std::optional<Vec2>> centre_px;  // per row; nothing where the input had none
  std::vector<bool> changed;                   // per row: the smoothed centre differs from the measured one
  int frames_changed = 0;
  // Median over the runs smoothed of each axis's noise level (one sample's sigma, px); 0 when none was.
  double noise_px = 0.0;
};

// `measured_px`: each row's measured centre, nothing where the frame has none. Runs shorter than
// options.min_samples are returned as they are.
CentreSmoothing smooth_centres_in_time(std::span<const std::optional<Vec2>> measured_px,
                                       const flow::TemporalSmoothing& options = {});

}  // namespace tirstrain::pipeline
