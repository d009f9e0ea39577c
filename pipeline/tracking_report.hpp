#pragma once
// What a tracking run used and what it measured of the texture, as JSON: written beside `tirstrain track`'s
// CSV and into result.h5 / summary.json by the tracking stage, so that a run can be reproduced and a reader
// sees which heuristics applied.
#include <nlohmann/json.hpp>

#include <string>

#include "flow/tracker.hpp"

namespace tirstrain::pipeline {

// The settings in effect (after the texture adapted them, once `tracker` has started; `fallback` otherwise).
nlohmann::json tracking_settings_json(const flow::TrackerOptions& settings);
// The frame-0 texture as the tracker judged it, and in words what followed from it (e.g. no ridges: the
// ridge heuristics are off and the subsets keep the preset's sizes).
nlohmann::json texture_json(const flow::FeatureTracker& tracker);
std::string texture_note(const flow::FeatureTracker& tracker);

}  // namespace tirstrain::pipeline
