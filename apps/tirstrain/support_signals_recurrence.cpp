// `tirstrain signals rqa`, `signals recurrence-plot` and `signals embedding`: recurrence analysis of one
// channel, of two channels jointly, or of an ensemble of trials (signals/rqa.hpp), its picture
// (signals/recurrence_plot.hpp), and help to choose the embedding (signals/embedding.hpp).
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/png_file.hpp"
#include "signals/channels.hpp"
#include "signals/embedding.hpp"
#include "signals/recurrence_plot.hpp"
#include "signals/rqa.hpp"
#include "tirstrain/signals_common.hpp"
#include "tirstrain/signals_verbs.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

namespace ts = tirstrain::signals;
using nlohmann::json;

constexpr std::size_t kMaxEmbeddedPoints = 40000;

// What decides the recurrence matrix of each input: shared by `rqa` and `recurrence-plot`.
struct RecurrenceRequest {
  Common c;
  std::vector<std::string> inputs;                  // one file per trial
  std::string column, joint_column;                 // channel, and the second channel of a joint analysis
  std::string norm = "euclidean";                   // euclidean or supremum
  long dim = 0, delay = 0;                          // embedding dimension and delay (samples)
  double threshold = -1.0, joint_threshold = -1.0;  // fixed ε of each channel, in its units
  double rate = -1.0;                               // fixed recurrence rate of each series
  double joint_rate = -1.0;                         // fixed recurrence rate of the joint plot
  std::string ensemble = "pool";                    // several inputs: pool line histograms or sum matrices
  long ensemble_min_trials = 0;                     // --ensemble sum: trials a cell must recur in (0: half)
  bool spatial = false;                             // the index column is a distance: lengths in its unit
};

// One trial's matrix with what chose it.
struct TrialRecurrence {
  std::string file;
  ts::RecurrenceMatrix matrix;
  json thresholds;
  double spacing = 1.0;  // index units per sample
};

const char* const kRecurrenceConventions =
    "Conventions: delay embedding y_i = (x_i, x_{i+tau}, ..., x_{i+(D-1)tau}); Euclidean distance (--norm "
    "supremum for the max norm); recurrent when distance <= epsilon; the line of identity is excluded from "
    "every measure (not a recurrence, not a diagonal line, and it splits vertical lines); rates over the "
    "M(M-1) off-diagonal cells; minimum diagonal and vertical line length 2 (--min-line); DET = points on "
    "diagonal lines / recurrent points, L = mean diagonal line length, LAM = points on vertical lines / "
    "recurrent points; an empty ratio is reported as 0.\n"
    "Threshold: --threshold EPS fixes epsilon; --recurrence-rate R fixes each series' rate: at least "
    "ceil(R * M(M-1)/2) pairs recur (more only on tied distances); --joint-recurrence-rate R (with "
    "--joint-column) fixes the joint plot's rate instead: each series keeps its k closest pairs, with the "
    "smallest k for which at least ceil(R * M(M-1)/2) pairs recur in both (at most one more).\n"
    "Ensembles (several IN): --ensemble pool (default) pools the trials' line histograms; --ensemble sum "
    "sums the trials' recurrence matrices and analyses the cells that recur in at least "
    "--ensemble-min-trials trials (default: half of them, rounded up).\n"
    "--spatial: the index column (--time-column, e.g. x_mm) is a distance; line lengths are also reported in "
    "its unit (the column name's last _suffix).\n"
    "Memory: an M x M bitset per trial (12.5 MB for 10^4 points; limit 40000 points).";

void add_request_options(CLI::App* sub, RecurrenceRequest& o) {
  sub->add_option("IN", o.inputs, kChannelInputHelp)->required();
  add_reading_options(sub, o.c);
  sub->add_option("--column", o.column, "channel")->required();
  sub->add_option("--dim", o.dim, "embedding dimension D")->required();
  sub->add_option("--delay", o.delay, "embedding delay tau, samples")->required();
  sub->add_option("--threshold", o.threshold, "fixed recurrence threshold epsilon, in the channel's units")
      ->check(kAtLeastZero);
  sub->add_option("--recurrence-rate", o.rate, "fixed recurrence rate R in (0, 1] of each series")
      ->check(kPositive);
  sub->add_option("--joint-recurrence-rate", o.joint_rate,
                  "fixed recurrence rate R in (0, 1] of the joint plot (needs --joint-column)");
  sub->add_option("--norm", o.norm, "euclidean or supremum")->capture_default_str();
  sub->add_option("--joint-column", o.joint_column, "second channel for joint recurrence");
  sub->add_option("--joint-threshold", o.joint_threshold,
                  "threshold for the joint channel (default --threshold)");
  sub->add_option("--ensemble", o.ensemble, "several IN: pool (line histograms) or sum (matrices)")
      ->capture_default_str();
  sub->add_option(
      "--ensemble-min-trials", o.ensemble_min_trials,
      "--ensemble sum: a cell recurs when it recurs in at least this many trials (default: half)");
  sub->add_flag("--spatial", o.spatial, "the index column is a distance: line lengths also in its unit");
}

void check_request(const RecurrenceRequest& o) {
  const int chosen = (o.threshold >= 0.0) + (o.rate > 0.0) + (o.joint_rate > 0.0);
  if (chosen != 1)
    throw Error("give exactly one of --threshold EPS, --recurrence-rate R or --joint-recurrence-rate R",
                {.key = "--threshold"});
  if (o.joint_rate > 0.0 && o.joint_column.empty())
    throw Error("a joint recurrence rate needs --joint-column", {.key = "--joint-recurrence-rate"});
  if (o.dim < 1) throw Error("must be at least 1", {.key = "--dim"});
  if (o.delay < 1) throw Error("must be at least 1 sample", {.key = "--delay"});
  if (o.ensemble != "pool" && o.ensemble != "sum")
    throw Error("unknown ensemble '" + o.ensemble + "' (use pool or sum)", {.key = "--ensemble"});
  if (o.ensemble_min_trials < 0 || o.ensemble_min_trials > static_cast<long>(o.inputs.size()))
    throw Error("must lie between 1 and the number of inputs (" + std::to_string(o.inputs.size()) + ")",
                {.key = "--ensemble-min-trials"});
}

ts::RecurrenceNorm parse_norm(const std::string& name) {
  if (name == "euclidean") return ts::RecurrenceNorm::euclidean;
  if (name == "supremum" || name == "max") return ts::RecurrenceNorm::supremum;
  throw Error("unknown norm '" + name + "' (use euclidean or supremum)", {.key = "--norm"});
}

ts::Embedding embed(const RecurrenceRequest& o, const ts::ChannelTable& table, const std::string& column) {
  auto e = ts::delay_embed(table.column(column), static_cast<std::size_t>(o.dim),
                           static_cast<std::size_t>(o.delay));
  if (e.points > kMaxEmbeddedPoints)
    throw Error(std::to_string(e.points) + " embedded points need a " +
                std::to_string(e.points * e.points / 8 / 1000000) +
                " MB recurrence bitset; decimate or split the series (limit 40000)");
  return e;
}

TrialRecurrence trial_recurrence(const RecurrenceRequest& o, const std::string& path) {
  std::vector<std::string> required{o.column};
  if (!o.joint_column.empty()) required.push_back(o.joint_column);
  const auto table = load(o.c, path, required);
  const auto norm = parse_norm(o.norm);
  TrialRecurrence t{path, {}, json::object(), 1.0 / table.sample_rate_Hz};
  const auto x = in_context(path, o.column, [&] { return embed(o, table, o.column); });
  if (o.joint_rate > 0.0) {
    const auto y = in_context(path, o.joint_column, [&] { return embed(o, table, o.joint_column); });
    auto joint = in_context(path, o.joint_column,
                            [&] { return ts::joint_recurrence_at_rate(x, y, o.joint_rate, norm); });
    t.matrix = std::move(joint.matrix);
    t.thresholds = {{"threshold", joint.threshold_x},
                    {"joint_threshold", joint.threshold_y},
                    {"recurrence_rate_each_series", joint.rate_each}};
    return t;
  }
  auto matrix_of = [&](const ts::Embedding& e, const std::string& column, double fixed, double& eps) {
    return in_context(path, column, [&] {
      if (fixed >= 0.0) {
        eps = fixed;
        return ts::recurrence_matrix(e, fixed, norm);
      }
      auto r = ts::recurrence_at_rate(e, o.rate, norm);
      eps = r.threshold;
      return std::move(r.matrix);
    });
  };
  double eps = 0.0;
  t.matrix = matrix_of(x, o.column, o.threshold, eps);
  t.thresholds["threshold"] = eps;
  if (!o.joint_column.empty()) {
    const auto y = in_context(path, o.joint_column, [&] { return embed(o, table, o.joint_column); });
    const double fixed = o.rate > 0.0 ? -1.0 : (o.joint_threshold >= 0.0 ? o.joint_threshold : o.threshold);
    double eps_joint = 0.0;
    t.matrix = in_context(path, o.joint_column,
                          [&] { return t.matrix & matrix_of(y, o.joint_column, fixed, eps_joint); });
    t.thresholds["joint_threshold"] = eps_joint;
  }
  return t;
}

std::vector<TrialRecurrence> trial_recurrences(const RecurrenceRequest& o) {
  std::vector<TrialRecurrence> trials;
  for (const std::string& path : o.inputs) trials.push_back(trial_recurrence(o, path));
  for (const auto& t : trials)
    if (std::abs(t.spacing - trials.front().spacing) > 1e-9 * trials.front().spacing)
      throw Error("trials of an ensemble must share the sample interval", {.file = t.file, .key = "IN"});
  return trials;
}

std::size_t min_trials(const RecurrenceRequest& o, std::size_t trials) {
  return o.ensemble_min_trials > 0 ? static_cast<std::size_t>(o.ensemble_min_trials) : (trials + 1) / 2;
}

std::string index_unit(const RecurrenceRequest& o) {
  // The index is read in seconds when its name carries a time unit (t_ms), else as it is (x_mm).
  const std::string name = signals::seconds_column_name(o.c.time_column);
  const auto cut = name.rfind('_');
  return cut == std::string::npos ? "units" : name.substr(cut + 1);
}

json measures_json(const ts::RqaMeasures& m, const RecurrenceRequest& o, double spacing) {
  json j = {{"recurrence_rate", m.recurrence_rate},
            {"determinism", m.determinism},
            {"mean_diagonal_length", m.mean_diagonal_length},
            {"laminarity", m.laminarity},
            {"trapping_time", m.trapping_time},
            {"max_diagonal_length", m.max_diagonal_length}};
  if (o.spatial) {
    const std::string unit = "_" + index_unit(o);
    j["mean_diagonal_length" + unit] = m.mean_diagonal_length * spacing;
    j["trapping_time" + unit] = m.trapping_time * spacing;
    j["max_diagonal_length" + unit] = static_cast<double>(m.max_diagonal_length) * spacing;
  }
  return j;
}

json conventions_json(const RecurrenceRequest& o, long min_line) {
  json j = {{"norm", o.norm},
            {"recurrent_when", "distance <= threshold"},
            {"line_of_identity", "excluded"},
            {"min_line", min_line},
            {"dim", o.dim},
            {"delay_samples", o.delay}};
  if (o.spatial) j["length_unit"] = index_unit(o);
  return j;
}

json analyse(const RecurrenceRequest& o, long min_line) {
  const auto trials = trial_recurrences(o);
  const auto lmin = static_cast<std::size_t>(min_line);
  const double spacing = trials.front().spacing;
  ts::LineHistograms pooled;
  json per_trial = json::array();
  for (const auto& t : trials) {
    const auto h = ts::line_histograms(t.matrix);
    pooled += h;
    json j = {{"file", t.file}, {"embedded_points", t.matrix.size()}};
    j.update(t.thresholds);
    j.update(measures_json(ts::rqa_measures(h, lmin), o, spacing));
    per_trial.push_back(j);
  }
  if (trials.size() == 1) return per_trial[0];
  json out;
  if (o.ensemble == "sum") {
    std::vector<ts::RecurrenceMatrix> matrices;
    for (const auto& t : trials) matrices.push_back(t.matrix);
    const std::size_t quorum = min_trials(o, trials.size());
    out = measures_json(ts::rqa_measures(ts::line_histograms(ts::ensemble_matrix(matrices, quorum)), lmin), o,
                        spacing);
    out["ensemble"] = "summed recurrence matrices; a cell recurs when it recurs in at least " +
                      std::to_string(quorum) + " of " + std::to_string(trials.size()) + " trials";
    out["ensemble_min_trials"] = quorum;
  } else {
    out = measures_json(ts::rqa_measures(pooled, lmin), o, spacing);
    out["ensemble"] = "measures pooled over the trials' line histograms";
  }
  out["trials"] = per_trial;
  return out;
}

void add_rqa(CLI::App& signals) {
  struct Opts {
    RecurrenceRequest r;
    std::string out;
    long min_line = 2;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "rqa", "Recurrence quantification analysis (RR, DET, L, LAM), joint or ensemble",
      std::string("Recurrence quantification analysis of one channel (several IN files: an ensemble over "
                  "trials, plus each trial's measures).\n"
                  "Output JSON: recurrence_rate, determinism, mean_diagonal_length, laminarity (+ "
                  "trapping_time, max_diagonal_length, threshold, embedded_points).\n") +
          kRecurrenceConventions +
          "\nExample: tirstrain signals rqa force.csv --column F_t_N --dim 3 --delay 5 --recurrence-rate "
          "0.05 "
          "--out rqa.json");
  add_request_options(sub, o->r);
  sub->add_option("--out", o->out, "output JSON")->required();
  sub->add_option("--min-line", o->min_line, "minimum diagonal/vertical line length")->capture_default_str();
  sub->callback([o] {
    check_request(o->r);
    if (o->min_line < 1) throw Error("must be at least 1", {.key = "--min-line"});
    json out = analyse(o->r, o->min_line);
    out["conventions"] = conventions_json(o->r, o->min_line);
    if (o->r.rate > 0.0) out["target_recurrence_rate"] = o->r.rate;
    if (o->r.joint_rate > 0.0) out["target_joint_recurrence_rate"] = o->r.joint_rate;
    write_json(o->out, out);
  });
}

void add_recurrence_plot(CLI::App& signals) {
  struct Opts {
    RecurrenceRequest r;
    std::string out;
    int side_px = 800;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "recurrence-plot", "Recurrence or joint-recurrence plot as a PNG (same options as rqa)",
      std::string("The recurrence plot of one channel (with --joint-column: the joint plot) as a PNG, i to "
                  "the right, j upwards, axes in the index column's unit. Several IN: the summed matrix, "
                  "each cell as dark as the fraction of trials in which it recurs. Matrices larger than "
                  "--side-px are shown in square blocks, each as dark as the fraction of its cells that "
                  "recur.\n") +
          kRecurrenceConventions +
          "\nExample: tirstrain signals recurrence-plot force.csv --column F_t_N --dim 3 --delay 5 "
          "--recurrence-rate 0.05 --out rp.png");
  add_request_options(sub, o->r);
  sub->add_option("--out", o->out, "output PNG")->required();
  sub->add_option("--side-px", o->side_px, "largest side of the plot area, pixels")->capture_default_str();
  sub->callback([o] {
    check_request(o->r);
    const auto trials = trial_recurrences(o->r);
    ts::RecurrencePlotOptions plot;
    plot.max_side_px = o->side_px;
    plot.spacing = trials.front().spacing;
    plot.axis_label = signals::seconds_column_name(o->r.c.time_column);
    plot.title = o->r.column + (o->r.joint_column.empty() ? "" : " & " + o->r.joint_column) +
                 ", D = " + std::to_string(o->r.dim) + ", tau = " + std::to_string(o->r.delay);
    if (trials.size() == 1) {
      write_png_file(o->out, ts::render_recurrence_plot(trials.front().matrix, plot));
      return;
    }
    std::vector<ts::RecurrenceMatrix> matrices;
    for (const auto& t : trials) matrices.push_back(t.matrix);
    plot.title += ", " + std::to_string(trials.size()) + " trials summed";
    write_png_file(o->out, ts::render_ensemble_plot(ts::ensemble_sum(matrices), matrices.front().size(),
                                                    matrices.size(), plot));
  });
}

void add_embedding(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string column;
    ts::MutualInformationOptions mi;
    ts::FalseNeighbourOptions fnn;
    long delay = 0;
    double fnn_fraction = 0.01;
    std::size_t minimum_window = 2;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "embedding", "Suggested embedding delay (mutual information) and dimension (false neighbours)",
      "Average mutual information I(tau) between x(t) and x(t+tau), in nats, from a 2-D histogram of --bins "
      "equal-width bins (bias about (bins-1)^2/(2N) nats); the suggested delay is its first local minimum, "
      "taken as the first tau whose I is the lowest within +-(--minimum-window) delays so that the "
      "estimate's own scatter does not make one. "
      "False nearest neighbours (Kennel et al.) for D = 1 ... --max-dim at that delay (or --delay): a "
      "nearest neighbour is false when the added coordinate grows the distance by more than "
      "--distance-ratio times, or the grown distance exceeds --size-ratio standard deviations of the series; "
      "the suggested dimension is the smallest D whose fraction is at most --fnn-fraction. The neighbour "
      "search is O(N^2): at most 20000 samples.\n"
      "Output JSON: mutual_information_nats[], suggested_delay, false_neighbour_fraction[], suggested_dim.\n"
      "Example: tirstrain signals embedding force.csv --column F_t_N --out embedding.json");
  add_common(sub, o->c, "output JSON");
  sub->add_option("--column", o->column, "channel")->required();
  sub->add_option("--bins", o->mi.bins, "histogram bins per axis")->capture_default_str();
  sub->add_option("--max-delay", o->mi.max_delay, "largest delay evaluated, samples")->capture_default_str();
  sub->add_option("--minimum-window", o->minimum_window, "a minimum is the lowest within +- this many delays")
      ->capture_default_str();
  sub->add_option("--delay", o->delay, "delay of the false-neighbour test, samples (default: suggested)");
  sub->add_option("--max-dim", o->fnn.max_dim, "largest dimension evaluated")->capture_default_str();
  sub->add_option("--distance-ratio", o->fnn.distance_ratio, "R_tol")->capture_default_str();
  sub->add_option("--size-ratio", o->fnn.size_ratio, "A_tol")->capture_default_str();
  sub->add_option("--theiler-window", o->fnn.theiler_window, "neighbours at least this many samples apart")
      ->capture_default_str();
  sub->add_option("--fnn-fraction", o->fnn_fraction, "false-neighbour fraction taken as zero")
      ->capture_default_str();
  sub->callback([o] {
    const auto table = load(o->c, o->c.input, {o->column});
    const auto& x = table.column(o->column);
    const auto mi =
        in_context(o->c.input, o->column, [&] { return ts::delayed_mutual_information(x, o->mi); });
    const std::size_t suggested_delay = ts::first_local_minimum(mi, o->minimum_window);
    if (o->delay < 0) throw Error("must be at least 1 sample", {.key = "--delay"});
    o->fnn.delay =
        o->delay > 0 ? static_cast<std::size_t>(o->delay) : std::max<std::size_t>(1, suggested_delay);
    const auto fnn =
        in_context(o->c.input, o->column, [&] { return ts::false_nearest_neighbours(x, o->fnn); });
    std::size_t suggested_dim = 0;
    for (std::size_t d = 0; d < fnn.size() && suggested_dim == 0; ++d)
      if (fnn[d] <= o->fnn_fraction) suggested_dim = d + 1;
    json out = {{"file", o->c.input},
                {"column", o->column},
                {"sample_rate_Hz", table.sample_rate_Hz},
                {"mutual_information_nats", mi},
                {"suggested_delay", suggested_delay},
                {"minimum_window", o->minimum_window},
                {"fnn_delay", o->fnn.delay},
                {"false_neighbour_fraction", fnn},
                {"suggested_dim", suggested_dim}};
    if (suggested_delay == 0)
      out["note"] = "I(tau) has no local minimum up to --max-delay; the false-neighbour test used delay 1";
    if (suggested_dim == 0)
      out["note_dim"] = "no dimension up to --max-dim reaches --fnn-fraction (noise?): suggested_dim is 0";
    write_json(o->c.out, out);
  });
}

}  // namespace

void add_signals_recurrence_verbs(CLI::App& signals) {
  add_rqa(signals);
  add_recurrence_plot(signals);
  add_embedding(signals);
}

}  // namespace tirstrain::cli
