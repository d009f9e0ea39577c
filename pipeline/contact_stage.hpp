#pragma once
// The contact stage: segmentation, hull, ellipse and orientation field per frame (contact/), stored for
// /contact in result.h5 and the contact columns of frames.csv.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

std::unique_ptr<Stage> make_contact_stage(const Scene& scene);

struct ContactStageOptions {
  contact::SegmenterOptions segmenter;  // each frame's segmentation
  // After the trial, the ellipse's centre (and the outline with it) smoothed in time where it holds still or
  // moves steadily (pipeline/contact_centre_smoothing.hpp); the measured centre stays in result.h5.
  bool smooth_centre_in_time = true;
};

// The contact stage's settings that follow from a scene: calibration, fixed ridge period, reference band
// excluded, the `segmentation:` section.
ContactStageOptions contact_stage_options_for(const Scene& scene);

// Segmenter settings that follow from a scene (contact_stage_options_for(scene).segmenter).
contact::SegmenterOptions segmenter_options_for(const Scene& scene);

}  // namespace tirstrain::pipeline
