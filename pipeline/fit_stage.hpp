#pragma once
// The fit stage: the Hertz + Cattaneo–Mindlin field fitted to each frame's tracks (fit/cm_fit.hpp), the
// same fit `tirstrain fit` runs on a finished result, here inside `process` (`compute: [..., fit]`). It fits
// once the tracking stage has finished (after any revision of the tracks in time), reading the tracks back
// from result.h5 a block of frames at a time, so memory does not grow with the trial. Writes /fit of
// result.h5 (docs/formats.md "Model fit in result.h5"), fit columns of frames.csv and the "fit" part of
// summary.json. Not run in the live view.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

std::unique_ptr<Stage> make_fit_stage(const Scene& scene);

}  // namespace tirstrain::pipeline
