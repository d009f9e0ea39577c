#pragma once
// The phases of a recording as JSON, the same object in `tirstrain signals phases`, the friction summary
// and the channels stage's summary.json.
#include <nlohmann/json.hpp>

#include "signals/phases.hpp"

namespace tirstrain::signals {

// contact_start_s, loaded_s, release_s, contact_end_s, normal_level_N, phases (named intervals in order),
// strokes, tare (model, source, quiet stretches, per-channel offset and drift) and warnings ({code,
// message}).
nlohmann::json phases_json(const Phases& phases);

nlohmann::json warnings_json(const std::vector<PhaseWarning>& warnings);

}  // namespace tirstrain::signals
