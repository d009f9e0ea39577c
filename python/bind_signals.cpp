// The `tirstrain signals` verbs filter, psd, tf and rqa (signals/) as functions on NumPy arrays, with the
// CLI's conventions and checks; errors name the keyword argument where the CLI names its option.
#include <pybind11/complex.h>
#include <pybind11/stl.h>

#include <complex>
#include <optional>
#include <string>

#include "core/error.hpp"
#include "python/arrays.hpp"
#include "python/bindings.hpp"
#include "signals/filter.hpp"
#include "signals/rqa.hpp"
#include "signals/spectral.hpp"

namespace tirstrain::python {

namespace {

namespace ts = tirstrain::signals;

ts::WelchOptions welch_options(long segment, std::optional<long> overlap) {
  if (segment < 2) throw Error("segment must be at least 2 samples", {.key = "segment"});
  if (overlap && *overlap < 0) throw Error("must be at least 0 samples", {.key = "overlap"});
  ts::WelchOptions w;
  w.segment = static_cast<std::size_t>(segment);
  if (overlap) w.overlap = static_cast<std::size_t>(*overlap);
  return w;
}

ts::ButterworthSpec filter_spec(double sample_rate_Hz, int order, std::optional<double> lowpass_Hz,
                                std::optional<double> highpass_Hz,
                                const std::optional<std::vector<double>>& bandpass_Hz) {
  if (lowpass_Hz.has_value() + highpass_Hz.has_value() + bandpass_Hz.has_value() != 1)
    throw Error("give exactly one of lowpass_Hz, highpass_Hz, bandpass_Hz=(F1, F2)", {.key = "lowpass_Hz"});
  ts::ButterworthSpec spec;
  spec.order = order;
  spec.sample_rate_Hz = sample_rate_Hz;
  if (lowpass_Hz) {
    spec.type = ts::FilterType::lowpass;
    spec.cutoff_Hz = *lowpass_Hz;
  } else if (highpass_Hz) {
    spec.type = ts::FilterType::highpass;
    spec.cutoff_Hz = *highpass_Hz;
  } else {
    if (bandpass_Hz->size() != 2) throw Error("expects two frequencies F1,F2", {.key = "bandpass_Hz"});
    spec.type = ts::FilterType::bandpass;
    spec.cutoff_Hz = (*bandpass_Hz)[0];
    spec.cutoff2_Hz = (*bandpass_Hz)[1];
  }
  return spec;
}

py::array_t<double> filter(const DoubleArray& x, double sample_rate_Hz, int order,
                           std::optional<double> lowpass_Hz, std::optional<double> highpass_Hz,
                           const std::optional<std::vector<double>>& bandpass_Hz) {
  const ts::ButterworthSpec spec = filter_spec(sample_rate_Hz, order, lowpass_Hz, highpass_Hz, bandpass_Hz);
  const std::string option = lowpass_Hz ? "lowpass_Hz" : highpass_Hz ? "highpass_Hz" : "bandpass_Hz";
  const std::vector<double> in = to_vector(x, "x");
  std::vector<double> y;
  try {
    py::gil_scoped_release release;
    y = ts::butterworth_filtfilt(in, spec);
  } catch (const Error& e) {
    // The design names its own parameters (cutoff_Hz, order); point at the argument the caller gave.
    if (e.context().key != "cutoff_Hz" && e.context().key != "cutoff2_Hz") throw;
    throw Error(e.message(), {.key = option});
  }
  return to_array(y);
}

py::tuple psd(const DoubleArray& x, double sample_rate_Hz, long segment, std::optional<long> overlap) {
  const ts::WelchOptions options = welch_options(segment, overlap);
  const std::vector<double> in = to_vector(x, "x");
  ts::PowerSpectrum p;
  {
    py::gil_scoped_release release;
    p = ts::welch(in, sample_rate_Hz, options);
  }
  return py::make_tuple(to_array(p.freq_Hz), to_array(p.psd));
}

py::dict tf(const DoubleArray& x, const DoubleArray& y, double sample_rate_Hz, long segment,
            std::optional<long> overlap) {
  const ts::WelchOptions options = welch_options(segment, overlap);
  const std::vector<double> in = to_vector(x, "x");
  const std::vector<double> out = to_vector(y, "y");
  ts::TransferEstimate t;
  {
    py::gil_scoped_release release;
    t = ts::transfer_estimate(in, out, sample_rate_Hz, options);
  }
  std::vector<double> gain, phase;
  for (const std::complex<double>& h : t.h1) {
    gain.push_back(std::abs(h));
    phase.push_back(std::arg(h));
  }
  py::dict d;
  d["freq_Hz"] = to_array(t.freq_Hz);
  d["gain"] = to_array(gain);
  d["phase_rad"] = to_array(phase);
  d["coherence"] = to_array(t.coherence);
  return d;
}

ts::RecurrenceNorm parse_norm(const std::string& name) {
  if (name == "euclidean") return ts::RecurrenceNorm::euclidean;
  if (name == "supremum" || name == "max") return ts::RecurrenceNorm::supremum;
  throw Error("unknown norm '" + name + "' (use euclidean or supremum)", {.key = "norm"});
}

// What `signals rqa` checks before embedding.
void check_rqa_arguments(long dim, long delay, long min_line, std::optional<double> threshold,
                         std::optional<double> rate) {
  if (threshold.has_value() == rate.has_value())
    throw Error("give exactly one of threshold=EPS or recurrence_rate=R", {.key = "threshold"});
  if (threshold && !(*threshold >= 0.0)) throw Error("must be at least 0", {.key = "threshold"});
  if (rate && !(*rate > 0.0 && *rate <= 1.0)) throw Error("must be in (0, 1]", {.key = "recurrence_rate"});
  if (dim < 1) throw Error("must be at least 1", {.key = "dim"});
  if (delay < 1) throw Error("must be at least 1 sample", {.key = "delay"});
  if (min_line < 1) throw Error("must be at least 1", {.key = "min_line"});
}

// `fixed` < 0: the threshold that gives the recurrence rate `rate`.
ts::RecurrenceMatrix recurrence(const std::vector<double>& x, long dim, long delay, double fixed, double rate,
                                ts::RecurrenceNorm norm, double& threshold) {
  const auto e = ts::delay_embed(x, static_cast<std::size_t>(dim), static_cast<std::size_t>(delay));
  if (e.points > 40000)
    throw Error(std::to_string(e.points) + " embedded points need a " +
                std::to_string(e.points * e.points / 8 / 1000000) +
                " MB recurrence bitset; decimate or split the series (limit 40000)");
  threshold = fixed >= 0.0 ? fixed : ts::threshold_for_recurrence_rate(e, rate, norm);
  return ts::recurrence_matrix(e, threshold, norm);
}

py::dict rqa(const DoubleArray& x, long dim, long delay, std::optional<double> threshold,
             std::optional<double> recurrence_rate, long min_line, const std::string& norm_name,
             const std::optional<DoubleArray>& joint, std::optional<double> joint_threshold) {
  check_rqa_arguments(dim, delay, min_line, threshold, recurrence_rate);
  const ts::RecurrenceNorm norm = parse_norm(norm_name);
  const std::vector<double> xs = to_vector(x, "x");
  const std::vector<double> js = joint ? to_vector(*joint, "joint") : std::vector<double>{};
  const double rate = recurrence_rate.value_or(-1.0);
  const double fixed = threshold.value_or(-1.0);
  // The joint series takes joint_threshold, else the same threshold, or its own for the same rate.
  const double fixed_joint = recurrence_rate ? -1.0 : joint_threshold.value_or(fixed);
  double eps = 0.0, eps_joint = 0.0;
  ts::RqaMeasures m;
  std::size_t points = 0;
  {
    py::gil_scoped_release release;
    ts::RecurrenceMatrix r = recurrence(xs, dim, delay, fixed, rate, norm, eps);
    if (joint) {
      r = r & recurrence(js, dim, delay, fixed_joint, rate, norm, eps_joint);
    }
    points = r.size();
    m = ts::rqa_measures(ts::line_histograms(r), static_cast<std::size_t>(min_line));
  }
  py::dict d;
  d["recurrence_rate"] = m.recurrence_rate;
  d["determinism"] = m.determinism;
  d["mean_diagonal_length"] = m.mean_diagonal_length;
  d["laminarity"] = m.laminarity;
  d["trapping_time"] = m.trapping_time;
  d["max_diagonal_length"] = m.max_diagonal_length;
  d["threshold"] = eps;
  if (joint) d["joint_threshold"] = eps_joint;
  d["embedded_points"] = points;
  return d;
}

}  // namespace

void bind_signals(py::module_& m) {
  using namespace py::literals;
  m.def("filter", &filter, "x"_a, py::kw_only(), "sample_rate_Hz"_a, "order"_a = 4,
        "lowpass_Hz"_a = py::none(), "highpass_Hz"_a = py::none(), "bandpass_Hz"_a = py::none(),
        "Zero-phase Butterworth filter (scipy.signal.butter + filtfilt semantics), as `tirstrain signals\n"
        "filter`: give exactly one of lowpass_Hz, highpass_Hz or bandpass_Hz=(F1, F2). Returns the filtered\n"
        "1-D array.");
  m.def("psd", &psd, "x"_a, py::kw_only(), "sample_rate_Hz"_a, "segment"_a, "overlap"_a = py::none(),
        "Welch power spectral density (SciPy conventions: periodic Hann, nfft = segment, overlap default\n"
        "segment/2, constant detrend, one-sided density), as `tirstrain signals psd`. Returns (freq_Hz,\n"
        "psd) with psd in units^2/Hz.");
  m.def("tf", &tf, "x"_a, "y"_a, py::kw_only(), "sample_rate_Hz"_a, "segment"_a, "overlap"_a = py::none(),
        "H1 transfer function from x to y and coherence, as `tirstrain signals tf`. Returns a dict:\n"
        "freq_Hz, gain (units_y/units_x), phase_rad in (-pi, pi], coherence in [0, 1].");
  m.def("rqa", &rqa, "x"_a, py::kw_only(), "dim"_a, "delay"_a, "threshold"_a = py::none(),
        "recurrence_rate"_a = py::none(), "min_line"_a = 2, "norm"_a = "euclidean", "joint"_a = py::none(),
        "joint_threshold"_a = py::none(),
        "Recurrence quantification analysis, as `tirstrain signals rqa` (one series; joint: a second\n"
        "series for joint recurrence). Give exactly one of threshold (channel units) or recurrence_rate in\n"
        "(0, 1]. Returns a dict: recurrence_rate, determinism, mean_diagonal_length, laminarity,\n"
        "trapping_time, max_diagonal_length, threshold (and joint_threshold), embedded_points.");
}

}  // namespace tirstrain::python
