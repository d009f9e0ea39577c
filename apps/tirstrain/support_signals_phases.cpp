// `tirstrain signals phases` and `tirstrain signals friction`: a real force recording tared and segmented
// (signals/phases.hpp), μ over each slide and the loading events inside the phases
// (signals/friction_trial.hpp).
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "signals/channels.hpp"
#include "signals/friction_trial.hpp"
#include "signals/phases.hpp"
#include "signals/phases_json.hpp"
#include "signals/phases_plot.hpp"
#include "tirstrain/signals_common.hpp"
#include "tirstrain/signals_verbs.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

namespace ts = tirstrain::signals;
using nlohmann::json;

// What both verbs read and how they tare.
struct RecordingOptions {
  std::string input;                                      // channel file
  std::string time_column = "t_s";                        // seconds
  double rate_tolerance = 0.01;                           // largest relative deviation of a sample interval
  std::string group = "/";                                // HDF5 group of the datasets
  std::optional<double> rate_Hz;                          // of a file without a time column, Hz
  std::string normal, tangential, position;               // columns
  std::string position_unit;                              // m, mm or um; empty: from the column's name
  bool invert_normal = false, invert_tangential = false;  // flip a channel's sign as read
  std::vector<double> tare_s;                             // a given quiet stretch T0,T1 (empty: found)
  bool no_tare = false;                                   // use the channels as recorded
  ts::PhaseOptions phases;
};

void add_recording_options(CLI::App* sub, RecordingOptions& o) {
  sub->add_option("IN", o.input,
                  "channel file: CSV with a header row and a time column, HDF5, or MATLAB .mat (v4 to v7.3; "
                  "NAME, NAME[:,k] or a.b.c)")
      ->required();
  sub->add_option("--normal", o.normal, "normal force channel W, N (mN when its name ends with _mN)")
      ->required();
  sub->add_option("--tangential", o.tangential, "tangential force channel F_t, N (or _mN)")->required();
  sub->add_option("--position", o.position,
                  "plate position channel: stroke directions, onset, U_ext (its unit from a name ending "
                  "with _m, _mm or _um, or --position-unit; without one, U_ext is left out)");
  sub->add_option("--position-unit", o.position_unit, "unit of the position channel: m, mm or um");
  sub->add_flag("--invert-normal", o.invert_normal,
                "flip the normal force's sign (pressing must be positive)");
  sub->add_flag("--invert-tangential", o.invert_tangential, "flip the tangential force's sign");
  sub->add_option("--tare-s", o.tare_s, "quiet stretch without contact T0,T1 in s (default: found from W)")
      ->delimiter(',');
  sub->add_flag("--no-tare", o.no_tare, "use the force channels as recorded (no offsets removed)");
  sub->add_option("--min-normal-N", o.phases.min_normal_N, "mu is undefined below this normal force, N")
      ->capture_default_str();
  sub->add_option("--smooth-s", o.phases.smooth_s, "moving-mean window of the phase search, s")
      ->capture_default_str();
  sub->add_option("--knee-fraction", o.phases.knee_fraction,
                  "a slide starts (ends) where mu's slope is this fraction of its rise's (fall's) steepest")
      ->capture_default_str();
  sub->add_option("--time-column", o.time_column, "name of the time column, seconds")->capture_default_str();
  sub->add_option("--rate-tolerance", o.rate_tolerance, "largest relative sample-interval deviation")
      ->capture_default_str();
  sub->add_option("--group", o.group, "HDF5 group holding the channel datasets")->capture_default_str();
  sub->add_option(
         "--rate-Hz", o.rate_Hz,
         "sample rate, Hz, of a file holding no time column (sample i at i / rate); an error when it has one")
      ->check(kPositive);
}

struct Recording {
  ts::ChannelTable table;
  std::vector<double> normal, tangential;       // N
  std::optional<std::vector<double>> position;  // m when position_in_m, else as recorded
  bool position_in_m = false;
  const std::vector<double>* position_or_null() const { return position ? &*position : nullptr; }
};

Recording read_recording(RecordingOptions& o) {
  if (!o.tare_s.empty() && o.tare_s.size() != 2) throw Error("expects T0,T1 in seconds", {.key = "--tare-s"});
  if (!o.tare_s.empty() && o.no_tare)
    throw Error("--tare-s and --no-tare exclude each other", {.key = "--tare-s"});
  if (o.tare_s.size() == 2) o.phases.tare = ts::TimeStretch{o.tare_s[0], o.tare_s[1]};
  o.phases.tare_enabled = !o.no_tare;
  ts::ChannelReadOptions read;
  read.time_column = o.time_column;
  read.rate_tolerance = o.rate_tolerance;
  read.hdf5_group = o.group;
  read.rate_Hz = o.rate_Hz;
  read.required = {o.normal, o.tangential};
  if (!o.position.empty()) read.required.push_back(o.position);
  Recording r;
  r.table = ts::read_channels(o.input, read);
  r.normal = force_in_N(r.table, o.normal);
  r.tangential = force_in_N(r.table, o.tangential);
  if (o.invert_normal)
    for (double& v : r.normal) v = -v;
  if (o.invert_tangential)
    for (double& v : r.tangential) v = -v;
  if (!o.position.empty()) {
    const auto m_per_unit =
        si_per_unit(o.position, o.position_unit, ts::Quantity::kPosition, "--position-unit");
    r.position = scaled(r.table.column(o.position), m_per_unit.value_or(1.0));
    r.position_in_m = m_per_unit.has_value();
  }
  return r;
}

// Library errors name the parameter; add the file and the option the user typed.
template <typename Fn>
auto in_recording_context(const RecordingOptions& o, Fn fn) -> decltype(fn()) {
  return with_error_context(fn, [&](ErrorContext& ctx) {
    ctx.file = o.input;
    if (ctx.column.empty()) ctx.column = o.normal;
    if (ctx.key == "tare_s") ctx.key = "--tare-s";
  });
}

void print_warnings(const std::vector<ts::PhaseWarning>& warnings) {
  for (const auto& w : warnings) std::cerr << "tirstrain: warning: " << w.code << ": " << w.message << "\n";
}

json signs_json(const RecordingOptions& o) {
  return {{"normal_inverted", o.invert_normal}, {"tangential_inverted", o.invert_tangential}};
}

std::string default_plot_path(const std::string& out) {
  return std::filesystem::path(out).replace_extension(".png").string();
}

// The friction summary: μ of the first slide under the names a single-trial summary always had, every
// slide's μ, the events, the phases and the warnings.
json friction_summary(const ts::FrictionTrial& trial, const RecordingOptions& o,
                      const ts::EventOptions& events, std::size_t rows_below_min_normal,
                      double sample_rate_Hz) {
  const ts::Stroke& first = trial.phases.strokes.front();
  const ts::TrialEvents& ev = trial.events;
  json j = {{"mu_dynamic", first.mu_mean},
            {"mu_plateau_start_s", first.slide_start_s},
            {"mu_plateau_end_s", first.slide_end_s},
            {"mu_plateau_stddev", first.mu_sd},
            {"mu_over", "the whole first slide (phases.strokes[0]); every slide in strokes"},
            {"onset_s", ev.onset_s},
            {"onset_index", ev.onset_index},
            {"onset_source", ev.onset_source},
            {"t90_s", ev.fraction_s},
            {"t90_index", ev.fraction_index},
            {"fraction", events.plateau_fraction},
            {"full_slip_s", ev.full_slip_s},
            {"full_slip_index", ev.full_slip_index},
            {"plateau_tangential_N", ev.tangential_plateau.mean},
            {"rows_below_min_normal", rows_below_min_normal},
            {"sample_rate_Hz", sample_rate_Hz},
            {"phases", ts::phases_json(trial.phases)},
            {"signs", signs_json(o)},
            {"warnings", ts::warnings_json(trial.warnings)}};
  j["strokes"] = j["phases"]["strokes"];
  j["tare"] = j["phases"]["tare"];
  if (ev.external_work_J) j["external_work_J"] = *ev.external_work_J;
  return j;
}

}  // namespace

void add_signals_phases_verb(CLI::App& signals) {
  struct Opts {
    RecordingOptions r;
    std::string out, plot;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = signals.add_subcommand(
      "phases", "Tare a real recording and segment it: approach, press, loading, slides (strokes), release");
  sub->footer(
      "A finger on a tribometer: no contact (approach), the normal force W rises (press) to its loaded "
      "level, "
      "the tangential force F_t builds up (loading), one or more slides (strokes, F_t ~ mu W, each in one "
      "direction), W falls (release).\n"
      "Tare: every force channel is zeroed over the quiet stretches without contact, found from W (or "
      "--tare-s); with a stretch before and one after the contact a straight line is fitted, so a drifting "
      "baseline is removed; the offsets and drifts are reported. Signs are as recorded unless --invert-*; a "
      "normal force that goes negative on contact is a warning.\n"
      "Times: contact start and loaded are the ends of the line through the 20 % and 80 % crossings of W's "
      "loaded level (release and contact end likewise); a stroke is where |mu| exceeds half its typical "
      "level, "
      "its slide starts where the loading rise of mu flattens (slope below --knee-fraction of the rise's "
      "steepest) and ends where the fall begins, never after the release starts.\n"
      "Output JSON: contact_start_s, loaded_s, release_s, contact_end_s, strokes [{slide_start_s, "
      "slide_end_s, mu_mean, mu_sd, mu_samples, direction (+1/-1), direction_source}], phases (named "
      "intervals), tare (model, quiet_stretches_s, normal/tangential offset_N, drift_N_per_s), warnings "
      "[{code, message}] (also on stderr). PNG (--plot, default OUT with .png): W, F_t and mu over time with "
      "the phases shaded.\n"
      "Example:\n"
      "  tirstrain signals phases trial.csv --normal normal_N --tangential lateral_N --position x_m "
      "--invert-normal --out phases.json");
  add_recording_options(sub, o->r);
  sub->add_option("--out", o->out, "output JSON (phase times, strokes, tare, warnings)")->required();
  sub->add_option("--plot", o->plot, "output PNG of the channels with the phases shaded (default: OUT.png)");
  sub->callback([o] {
    Recording rec = read_recording(o->r);
    const ts::Phases phases = in_recording_context(o->r, [&] {
      return ts::detect_phases(rec.table.time_s, rec.normal, rec.tangential, rec.position_or_null(),
                               o->r.phases);
    });
    const std::string plot = o->plot.empty() ? default_plot_path(o->out) : o->plot;
    ts::write_phases_png(plot, rec.table.time_s, phases,
                         {.title = std::filesystem::path(o->r.input).filename().string()});
    json j = ts::phases_json(phases);
    j["input"] = o->r.input;
    j["sample_rate_Hz"] = rec.table.sample_rate_Hz;
    j["signs"] = signs_json(o->r);
    j["plot"] = plot;
    write_text_file(o->out, j.dump(2) + "\n");
    print_warnings(phases.warnings);
  });
}

void add_signals_friction_verb(CLI::App& signals) {
  struct Opts {
    RecordingOptions r;
    std::string out, summary;
    ts::EventOptions events;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = signals.add_subcommand(
      "friction",
      "Friction coefficient mu(t), mu over each slide, loading events and U_ext inside the phases");
  sub->footer(
      "The recording is tared and segmented first, as `signals phases` does (see its --help). Then:\n"
      "Output CSV: t_s,mu with mu = F_t/W on the tared channels (rows with W < --min-normal-N left out and "
      "counted).\n"
      "--summary JSON: mu_dynamic (mean mu over the first slide, whole), mu_plateau_start_s/end_s/stddev "
      "(that slide), strokes (every slide's mu), onset_s (the position, else F_t, leaves its baseline: the "
      "first --baseline-s after loaded; by 5 % of its excursion, the onset being the last sample inside 5 "
      "sigma), t90_s (F_t at --fraction of its level when the slide starts), full_slip_s (F_t within 1 % of "
      "that level), plateau_tangential_N, external_work_J (integral of F_t dx from onset to t90, in J; needs "
      "--position with a known unit), phases, tare, warnings.\n"
      "The events must fall in order inside the phases (onset in the contact before the first slide, t90 "
      "and full slip before that slide's end); a disagreement is a named warning on stderr and in the "
      "summary. No slide is an error.\n"
      "Example:\n"
      "  tirstrain signals friction trial.csv --normal normal_N --tangential lateral_N --position x_m "
      "--summary friction.json --out mu.csv");
  add_recording_options(sub, o->r);
  sub->add_option("--out", o->out, "output CSV: t_s,mu")->required();
  sub->add_option("--summary", o->summary, "summary JSON (mu per slide, events, U_ext, phases)");
  sub->add_option("--baseline-s", o->events.baseline_s,
                  "quiet stretch after loaded used as the onset's baseline, s")
      ->capture_default_str();
  sub->add_option("--fraction", o->events.plateau_fraction, "the 't90' fraction of the slide's level")
      ->capture_default_str();
  sub->callback([o] {
    Recording rec = read_recording(o->r);
    auto trial = in_recording_context(o->r, [&] {
      return ts::analyse_friction_trial(rec.table.time_s, rec.normal, rec.tangential, rec.position_or_null(),
                                        {o->r.phases, o->events});
    });
    if (rec.position && !rec.position_in_m) {
      trial.events.external_work_J.reset();
      trial.warnings.push_back({"external_work_not_measured",
                                "U_ext is left out: the unit of position column '" + o->r.position +
                                    "' is not known (name it with _m, _mm or _um, or give --position-unit)"});
    }
    const ts::Phases& p = trial.phases;
    CsvWriter out(o->out, {signals::seconds_column_name(o->r.time_column), "mu"});
    std::size_t below = 0;
    for (std::size_t i = 0; i < p.normal_N.size(); ++i) {
      if (p.normal_N[i] < o->r.phases.min_normal_N) {
        ++below;
        continue;
      }
      out.row({rec.table.time_s[i], p.tangential_N[i] / p.normal_N[i]});
    }
    if (!o->summary.empty())
      write_text_file(
          o->summary,
          friction_summary(trial, o->r, o->events, below, rec.table.sample_rate_Hz).dump(2) + "\n");
    out.commit();
    print_warnings(trial.warnings);
  });
}

}  // namespace tirstrain::cli
