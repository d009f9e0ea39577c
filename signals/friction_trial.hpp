#pragma once
// Friction and loading events of a real recording: the phases (signals/phases.hpp) first, then the events
// of the first stroke's loading searched inside them, and the two checked against each other.
//
// The onset is searched between loaded and the first slide's end (so a drifting channel during the
// approach or the press cannot start it), t90 and full slip against the level the tangential force has
// when the first slide starts, and the dynamic μ is the mean over each whole slide. Every disagreement
// between the events and the phases is a named warning.
#include <cstddef>
#include <vector>

#include "signals/friction.hpp"
#include "signals/phases.hpp"

namespace tirstrain::signals {

struct FrictionTrialOptions {
  PhaseOptions phases;  // tare and segmentation
  EventOptions events;  // onset, t90 and full slip (its plateau settings are not used)
};

struct FrictionTrial {
  Phases phases;                       // tared channels, phase times, strokes with μ
  TrialEvents events;                  // of the first stroke's loading, on the tared tangential force
  std::vector<PhaseWarning> warnings;  // the phases' and the consistency checks'
};

// Throws Error when there is no stroke (the message carries the phases' warnings, which say why) or the
// events cannot be found inside the first stroke's loading.
FrictionTrial analyse_friction_trial(const std::vector<double>& time_s, const std::vector<double>& normal_N,
                                     const std::vector<double>& tangential_N,
                                     const std::vector<double>* position,
                                     const FrictionTrialOptions& options);

}  // namespace tirstrain::signals
