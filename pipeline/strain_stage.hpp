#pragma once
// The strain stage: a Delaunay mesh of the tracks that follows births and retirements, per-triangle
// Green–Lagrange strain (exact, or the paper's incremental sum), rates, principal strains, rotation, energy,
// stick ratio, and maps on the standard ellipse of the reference frame (strain/). Needs the tracking stage.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

std::unique_ptr<Stage> make_strain_stage(const Scene& scene);

}  // namespace tirstrain::pipeline
