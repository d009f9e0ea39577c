#pragma once
// The channels stage: force, plate-position, accelerometer and trigger channels (signals/) fused with the
// frames. It reads the channel file named by the scene's `channels:` section, puts the channels on the
// camera clock (explicit offset, trigger edge, or cross-correlation of the plate position with the
// image-measured plate displacement), resamples them to the frame times, tares the force channels and
// segments the recording into its phases (signals/phases.hpp), and derives friction (μ at frames, μ over
// each slide), the first stroke's loading events inside the phases (onset, 90 % point, full slip), the
// external work U_ext and, with the strain stage, U/U_ext. Writes /channels, /friction, /events and /work of
// result.h5 (docs/formats.md) and the "channels" part of summary.json.
#include <memory>

#include "core/scene.hpp"
#include "pipeline/stage.hpp"

namespace tirstrain::pipeline {

// Parses the scene's `channels:` section strictly (unknown keys, missing file or columns, a mode without the
// channel it needs are errors naming the scene file and key). The channel file is read at start().
std::unique_ptr<Stage> make_channels_stage(const Scene& scene);

// Reads the channel file the scene's section names, as the stage's start() does: throws the Error start()
// would (a non-finite sample, a time axis going back, a missing column), before any frame is read.
void check_channel_file(const Scene& scene);

}  // namespace tirstrain::pipeline
