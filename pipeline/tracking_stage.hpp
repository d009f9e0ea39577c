#pragma once
// The tracking stage: skin features inside the contact and the plate's printed pattern (flow/), started on
// the first frame with contact (the reference frame), stored for /tracks and /plate in result.h5.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

std::unique_ptr<Stage> make_tracking_stage(const Scene& scene);

}  // namespace tirstrain::pipeline
