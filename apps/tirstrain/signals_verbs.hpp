#pragma once
// `tirstrain signals` verbs defined outside cmd_signals.cpp (support_signals_*.cpp), registered by it.
#include <CLI/CLI.hpp>

namespace tirstrain::cli {

// `signals phases` and `signals friction`: tare, phases and strokes of a real recording; μ and events.
void add_signals_phases_verb(CLI::App& signals);
void add_signals_friction_verb(CLI::App& signals);
// `signals rqa`, `signals recurrence-plot` and `signals embedding`.
void add_signals_recurrence_verbs(CLI::App& signals);

}  // namespace tirstrain::cli
