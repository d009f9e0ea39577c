#pragma once
// The contact stage: segmentation, hull, ellipse and orientation field per frame (contact/), stored for
// /contact in result.h5 and the contact columns of frames.csv.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

std::unique_ptr<Stage> make_contact_stage(const Scene& scene);

// Segmenter settings that follow from a scene: calibration, fixed ridge period, reference band excluded.
contact::SegmenterOptions segmenter_options_for(const Scene& scene);

}  // namespace tirstrain::pipeline
