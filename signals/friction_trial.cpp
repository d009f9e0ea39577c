#include "signals/friction_trial.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/error.hpp"
#include "core/median.hpp"

namespace tirstrain::signals {
namespace {

std::string fmt(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.5g", v);
  return buf;
}

std::vector<double> slice(const std::vector<double>& v, std::size_t lo, std::size_t hi) {
  return {v.begin() + static_cast<std::ptrdiff_t>(lo), v.begin() + static_cast<std::ptrdiff_t>(hi)};
}

// The tangential force's level when the slide starts: its median over the first level window of the slide
// (indices relative to the event window starting at `lo`).
Plateau slide_plateau(const std::vector<double>& t, const std::vector<double>& ft, const Stroke& stroke,
                      std::size_t lo, std::size_t hi, const PhaseOptions& o) {
  Plateau p;
  p.start_index = index_at_or_after(t, stroke.slide_start_s) - lo;
  p.end_index = std::min(hi, index_at_or_after(t, stroke.slide_end_s)) - lo;
  p.start_s = stroke.slide_start_s;
  p.end_s = stroke.slide_end_s;
  const std::size_t level_end =
      std::min(hi, index_at_or_after(t, stroke.slide_start_s + o.level_window_s) + 1);
  std::vector<double> level(
      ft.begin() + static_cast<std::ptrdiff_t>(lo + p.start_index),
      ft.begin() + static_cast<std::ptrdiff_t>(std::max(level_end, lo + p.start_index + 1)));
  std::vector<double> sorted = level;
  p.mean = upper_median_in_place(sorted);
  double var = 0.0;
  for (double v : level) var += (v - p.mean) * (v - p.mean);
  p.stddev = std::sqrt(var / static_cast<double>(level.size()));
  return p;
}

// Events of the first stroke's loading: the window runs from loaded to the end of that slide.
TrialEvents first_stroke_events(const std::vector<double>& t, const Phases& phases,
                                const std::vector<double>* position, const FrictionTrialOptions& o) {
  const Stroke& stroke = phases.strokes.front();
  const std::size_t lo =
      std::min(index_at_or_after(t, phases.loaded_s), index_at_or_after(t, stroke.slide_start_s));
  const std::size_t hi = std::min(t.size(), index_at_or_after(t, stroke.slide_end_s) + 1);
  const auto tw = slice(t, lo, hi), ftw = slice(phases.tangential_N, lo, hi);
  std::vector<double> xw;
  if (position) xw = slice(*position, lo, hi);
  const Plateau plateau = slide_plateau(t, phases.tangential_N, stroke, lo, hi, o.phases);
  TrialEvents ev = detect_events_on_plateau(tw, ftw, position ? &xw : nullptr, plateau, o.events);
  ev.onset_index += lo;
  ev.fraction_index += lo;
  ev.full_slip_index += lo;
  ev.tangential_plateau.start_index += lo;
  ev.tangential_plateau.end_index += lo;
  return ev;
}

// The events must fall in order inside the phases: contact ≤ onset ≤ slide start, onset ≤ t90 ≤ slide end,
// t90 ≤ full slip ≤ slide end; U_ext ≥ 0.
void check_consistency(const Phases& p, const TrialEvents& ev, std::vector<PhaseWarning>& warnings) {
  const Stroke& s = p.strokes.front();
  const auto add = [&](const char* code, const std::string& what) { warnings.push_back({code, what}); };
  if (ev.onset_s < p.contact_start_s || ev.onset_s > s.slide_start_s)
    add("onset_outside_loading", "movement onset " + fmt(ev.onset_s) +
                                     " s lies outside the contact before the first slide (" +
                                     fmt(p.contact_start_s) + " to " + fmt(s.slide_start_s) + " s)");
  if (ev.fraction_s < ev.onset_s || ev.fraction_s > s.slide_end_s)
    add("t90_outside_loading", "t90 " + fmt(ev.fraction_s) +
                                   " s lies outside onset to the first slide's end (" + fmt(ev.onset_s) +
                                   " to " + fmt(s.slide_end_s) + " s)");
  if (ev.full_slip_s < ev.fraction_s || ev.full_slip_s > s.slide_end_s)
    add("full_slip_outside_slide", "full slip " + fmt(ev.full_slip_s) +
                                       " s lies outside t90 to the first slide's end (" + fmt(ev.fraction_s) +
                                       " to " + fmt(s.slide_end_s) + " s)");
  // While the plate drags the finger along, force and displacement point the same way.
  if (ev.external_work_J && *ev.external_work_J < 0.0)
    add("external_work_negative", "U_ext = " + fmt(*ev.external_work_J) +
                                      " J is negative: the tangential force and the position count positive "
                                      "in opposite directions; flip the sign of one of them");
}

}  // namespace

FrictionTrial analyse_friction_trial(const std::vector<double>& time_s, const std::vector<double>& normal_N,
                                     const std::vector<double>& tangential_N,
                                     const std::vector<double>* position,
                                     const FrictionTrialOptions& options) {
  FrictionTrial trial;
  trial.phases = detect_phases(time_s, normal_N, tangential_N, position, options.phases);
  trial.warnings = trial.phases.warnings;
  if (trial.phases.strokes.empty()) {
    std::string why;
    for (const auto& w : trial.phases.warnings) why += "; " + w.code + ": " + w.message;
    throw Error("no slide found between loaded (" + fmt(trial.phases.loaded_s) + " s) and release (" +
                fmt(trial.phases.release_s) + " s)" + why);
  }
  trial.events = first_stroke_events(time_s, trial.phases, position, options);
  check_consistency(trial.phases, trial.events, trial.warnings);
  return trial;
}

}  // namespace tirstrain::signals
