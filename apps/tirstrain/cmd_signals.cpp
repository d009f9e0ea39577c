// `tirstrain signals <verb>`: the signals/ library on channel files. Every verb reads a CSV (header row, time
// column t_s, sample rate from it) or an HDF5/.mat file, validates it (see signals/channels.hpp) and writes
// a CSV with a header row or a JSON file, each through a temporary name.
#include <cmath>
#include <iostream>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "signals/channels.hpp"
#include "signals/filter.hpp"
#include "signals/friction.hpp"
#include "signals/friction_speed.hpp"
#include "signals/mechanics.hpp"
#include "signals/spatial.hpp"
#include "signals/spectral.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/signals_common.hpp"
#include "tirstrain/signals_verbs.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

namespace ts = tirstrain::signals;
using nlohmann::json;

constexpr const char* kWelchConventions =
    "Spectra follow scipy.signal.welch/csd (MATLAB pwelch/cpsd/tfestimate/mscohere): periodic Hann window of "
    "--segment samples, 50 % overlap, per-segment mean removal, one-sided density scaling (units^2/Hz), "
    "segments "
    "averaged; the last partial segment is dropped.";

ts::WelchOptions welch_options(long segment, long overlap) {
  if (segment < 2) throw Error("segment must be at least 2 samples", {.key = "--segment"});
  ts::WelchOptions w;
  w.segment = static_cast<std::size_t>(segment);
  if (overlap >= 0) w.overlap = static_cast<std::size_t>(overlap);
  return w;
}

void add_filter(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string column;
    int order = 4;
    double lowpass_Hz = 0.0, highpass_Hz = 0.0;
    std::vector<double> bandpass_Hz;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "filter",
      "Zero-phase Butterworth filter of one channel (scipy.signal.butter + filtfilt semantics)",
      "Output CSV: t_s,NAME_filtered. The filter runs forward and backward (zero phase, magnitude |H|^2, so "
      "the -3 dB cutoff of one pass becomes -6 dB); the signal is extended at both ends by odd reflection of "
      "padlen = 3*(filter order + 1) samples and each pass starts from the steady state of the first sample "
      "(lfilter_zi), as SciPy does by default. Band-pass order N gives a 2N-pole filter, as in SciPy. "
      "Designed "
      "as second-order sections for numerical stability.");
  add_common(sub, o->c, "output CSV: t_s,NAME_filtered");
  add_example(sub,
              "tirstrain signals filter trial.csv --column normal_N --lowpass-Hz 80 --out normal_80Hz.csv");
  sub->add_option("--column", o->column, "channel to filter")->required();
  sub->add_option("--order", o->order, "Butterworth order N")->capture_default_str();
  sub->add_option("--lowpass-Hz", o->lowpass_Hz, "low-pass -3 dB frequency, Hz (e.g. the paper's 80)")
      ->check(kPositiveHz);
  sub->add_option("--highpass-Hz", o->highpass_Hz, "high-pass -3 dB frequency, Hz")->check(kPositiveHz);
  sub->add_option("--bandpass-Hz", o->bandpass_Hz, "band-pass edges F1,F2 in Hz (e.g. 15,500)")
      ->delimiter(',');
  sub->callback([o] {
    const int given = (o->lowpass_Hz > 0.0) + (o->highpass_Hz > 0.0) + (!o->bandpass_Hz.empty());
    if (given != 1)
      throw Error("give exactly one of --lowpass-Hz, --highpass-Hz, --bandpass-Hz F1,F2",
                  {.key = "--lowpass-Hz"});
    if (!o->bandpass_Hz.empty() && o->bandpass_Hz.size() != 2)
      throw Error("expects two frequencies F1,F2", {.key = "--bandpass-Hz"});
    const auto table = load(o->c, o->c.input, {o->column});
    ts::ButterworthSpec spec;
    spec.order = o->order;
    spec.sample_rate_Hz = table.sample_rate_Hz;
    if (o->lowpass_Hz > 0.0) {
      spec.type = ts::FilterType::lowpass;
      spec.cutoff_Hz = o->lowpass_Hz;
    } else if (o->highpass_Hz > 0.0) {
      spec.type = ts::FilterType::highpass;
      spec.cutoff_Hz = o->highpass_Hz;
    } else {
      spec.type = ts::FilterType::bandpass;
      spec.cutoff_Hz = o->bandpass_Hz[0];
      spec.cutoff2_Hz = o->bandpass_Hz[1];
    }
    const std::string option = o->lowpass_Hz > 0.0    ? "--lowpass-Hz"
                               : o->highpass_Hz > 0.0 ? "--highpass-Hz"
                                                      : "--bandpass-Hz";
    const auto y = in_context(o->c.input, o->column, [&] {
      try {
        return ts::butterworth_filtfilt(table.column(o->column), spec);
      } catch (const Error& e) {
        // The design names its own parameters (cutoff_Hz, order); point at the option the user typed.
        if (e.context().key != "cutoff_Hz" && e.context().key != "cutoff2_Hz" && e.context().key != "order")
          throw;
        throw Error(e.message(), {.key = e.context().key == "order" ? "--order" : option});
      }
    });
    CsvWriter out(o->c.out, {signals::seconds_column_name(o->c.time_column), o->column + "_filtered"});
    for (std::size_t i = 0; i < y.size(); ++i) out.row({table.time_s[i], y[i]});
    out.commit();
  });
}

void add_psd(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string column;
    long segment = 0, overlap = -1;
    std::string peaks_out;
    double min_prominence = 0.0;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "psd", "Welch power spectral density of one channel (SciPy conventions)",
      std::string("Welch power spectral density of one channel. Output CSV: freq_Hz,psd (units^2/Hz).\n") +
          kWelchConventions);
  add_common(sub, o->c, "output CSV: freq_Hz,psd");
  add_example(sub, "tirstrain signals psd trial.csv --column accel_m_s2 --segment 1024 --out accel_psd.csv");
  sub->add_option("--column", o->column, "channel")->required();
  sub->add_option("--segment", o->segment, "segment length nperseg, samples (= nfft)")->required();
  sub->add_option("--overlap", o->overlap, "overlap, samples (default segment/2)")
      ->check(kSamplesAtLeastZero);
  sub->add_option(
      "--peaks-out", o->peaks_out,
      "also write spectral peaks (scipy.signal.find_peaks semantics) as CSV: freq_Hz,psd,prominence");
  sub->add_option("--min-prominence", o->min_prominence, "smallest peak prominence kept, units^2/Hz")
      ->capture_default_str();
  sub->callback([o] {
    const auto table = load(o->c, o->c.input, {o->column});
    const auto p = in_context(o->c.input, o->column, [&] {
      return ts::welch(table.column(o->column), table.sample_rate_Hz, welch_options(o->segment, o->overlap));
    });
    CsvWriter out(o->c.out, {"freq_Hz", "psd"});
    for (std::size_t k = 0; k < p.psd.size(); ++k) out.row({p.freq_Hz[k], p.psd[k]});
    out.commit();
    if (!o->peaks_out.empty()) {
      CsvWriter peaks(o->peaks_out, {"freq_Hz", "psd", "prominence"});
      for (const auto& pk : ts::find_peaks(p.psd, {.min_prominence = o->min_prominence}))
        peaks.row({p.freq_Hz[pk.index], pk.value, pk.prominence});
      peaks.commit();
    }
  });
}

void add_tf(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string input_column, output_column;
    long segment = 0, overlap = -1;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "tf", "H1 transfer function and coherence from channel A to channel B",
      std::string(
          "H1 transfer-function estimate and magnitude-squared coherence from channel A to channel B.\n"
          "Output CSV: freq_Hz,gain,phase_rad,coherence with H1 = Pxy/Pxx (Pxy = conj(X)*Y, SciPy's "
          "order), gain = |H1| in units_B/units_A, phase = arg(H1) in (-pi, pi], coherence = "
          "|Pxy|^2/(Pxx*Pyy).\n") +
          kWelchConventions);
  add_common(sub, o->c, "output CSV: freq_Hz,gain,phase_rad,coherence");
  add_example(
      sub,
      "tirstrain signals tf trial.csv --input tangential_N --output accel_m_s2 --segment 1024 --out tf.csv");
  sub->add_option("--input", o->input_column, "input channel A (e.g. force)")->required();
  sub->add_option("--output", o->output_column, "output channel B (e.g. acceleration)")->required();
  sub->add_option("--segment", o->segment, "segment length nperseg, samples")->required();
  sub->add_option("--overlap", o->overlap, "overlap, samples (default segment/2)")
      ->check(kSamplesAtLeastZero);
  sub->callback([o] {
    const auto table = load(o->c, o->c.input, {o->input_column, o->output_column});
    const auto t = in_context(o->c.input, o->input_column, [&] {
      return ts::transfer_estimate(table.column(o->input_column), table.column(o->output_column),
                                   table.sample_rate_Hz, welch_options(o->segment, o->overlap));
    });
    CsvWriter out(o->c.out, {"freq_Hz", "gain", "phase_rad", "coherence"});
    for (std::size_t k = 0; k < t.freq_Hz.size(); ++k)
      out.row({t.freq_Hz[k], std::abs(t.h1[k]), std::arg(t.h1[k]), t.coherence[k]});
    out.commit();
  });
}

json fit_json(const ts::MckFit& fit) {
  json j = {{"m_kg", fit.mck.m_kg},
            {"c_Ns_m", fit.mck.c_Ns_m},
            {"k_N_m", fit.mck.k_N_m},
            {"m_sd_kg", fit.m_sd_kg},
            {"c_sd_Ns_m", fit.c_sd_Ns_m},
            {"k_sd_N_m", fit.k_sd_N_m},
            {"m_k_correlation", fit.m_k_correlation},
            {"stiffness_fixed", fit.stiffness_fixed},
            {"natural_frequency_Hz", fit.mck.natural_frequency_Hz()},
            {"damping_ratio", fit.mck.damping_ratio()},
            {"frequencies_used", fit.frequencies_used},
            {"band_low_Hz", fit.band_low_Hz},
            {"band_high_Hz", fit.band_high_Hz},
            {"relative_residual", fit.relative_residual},
            {"warnings", json::array()}};
  if (std::abs(fit.m_k_correlation) > ts::kMassStiffnessCorrelationLimit) {
    const std::string warning =
        "m and k are correlated at " + std::to_string(fit.m_k_correlation) +
        ": the band does not separate the stiffness from the mass; widen --band-Hz or "
        "fix k with --fix-stiffness";
    j["warnings"].push_back(warning);
    std::cerr << "tirstrain signals impedance: warning: " << warning << "\n";
  }
  return j;
}

struct ImpedanceOpts {
  Common c;
  std::string force, accel, velocity, unloaded;
  std::optional<double> fix_stiffness_N_m;
  long segment = 0, overlap = -1;
  std::vector<double> band_Hz;
  double min_coherence = 0.9;
  std::string fit_out;
};

// The finger's impedance: the loaded recording's, less the unloaded plate's when one is given.
ts::FingerImpedance finger_impedance_of(const ImpedanceOpts& o) {
  const auto w = welch_options(o.segment, o.overlap);
  const std::string motion = o.accel.empty() ? o.velocity : o.accel;
  const auto kind = o.accel.empty() ? ts::MotionKind::velocity_m_s : ts::MotionKind::acceleration_m_s2;
  auto impedance_of = [&](const std::string& path) {
    const auto table = load(o.c, path, {o.force, motion});
    return std::make_pair(in_context(path, o.force,
                                     [&] {
                                       return ts::mechanical_impedance(table.column(o.force),
                                                                       table.column(motion),
                                                                       table.sample_rate_Hz, w, kind);
                                     }),
                          table.sample_rate_Hz);
  };
  const auto [loaded, fs] = impedance_of(o.c.input);
  std::optional<ts::ImpedanceSpectrum> unloaded;
  if (!o.unloaded.empty()) {
    const auto [u, fs_u] = impedance_of(o.unloaded);
    if (std::abs(fs_u - fs) > 1e-6 * fs)
      throw Error("sample rate " + std::to_string(fs_u) + " Hz differs from the loaded recording's " +
                      std::to_string(fs) + " Hz",
                  {.file = o.unloaded});
    unloaded = u;
  }
  return in_context(o.c.input, "",
                    [&] { return ts::finger_impedance(loaded, unloaded ? &*unloaded : nullptr); });
}

void run_impedance(const ImpedanceOpts& o) {
  if (!o.band_Hz.empty() && o.band_Hz.size() != 2)
    throw Error("expects LOW,HIGH in Hz", {.key = "--band-Hz"});
  if (o.accel.empty() == o.velocity.empty())
    throw Error("give exactly one motion channel: --accel or --velocity-column", {.key = "--accel"});
  const ts::FingerImpedance finger = finger_impedance_of(o);
  CsvWriter out(o.c.out, {"freq_Hz", "z_real_Ns_m", "z_imag_Ns_m", "mass_kg", "damping_Ns_m", "damping_ratio",
                          "coherence"});
  for (std::size_t k = 0; k < finger.freq_Hz.size(); ++k)
    out.row({finger.freq_Hz[k], finger.z_Ns_m[k].real(), finger.z_Ns_m[k].imag(), finger.mass_kg[k],
             finger.damping_Ns_m[k], finger.damping_ratio[k], finger.coherence[k]});
  if (!o.fit_out.empty()) {
    ts::MckFitOptions fo;
    fo.min_coherence = o.min_coherence;
    fo.fixed_stiffness_N_m = o.fix_stiffness_N_m;
    if (o.band_Hz.size() == 2) {
      fo.band_low_Hz = o.band_Hz[0];
      fo.band_high_Hz = o.band_Hz[1];
    }
    const auto fit = in_context(o.c.input, "", [&] { return ts::fit_mass_spring_damper(finger, fo); });
    write_json(o.fit_out, fit_json(fit));
  }
  out.commit();
}

void add_impedance(CLI::App& signals) {
  auto o = std::make_shared<ImpedanceOpts>();
  CLI::App* sub = add_verb(
      signals, "impedance", "Mechanical impedance of a finger on a vibrating plate; spring-mass-damper fit",
      std::string(
          "Mechanical impedance of a finger on a vibrating plate from force (N) and plate acceleration "
          "(m/s^2, --accel) or velocity (m/s, --velocity-column, e.g. a laser vibrometer).\nZ = F/V = "
          "j*omega*F/A from the H1 estimate of A given F (Z = F/V from H1 of V given F); with --unloaded, "
          "the "
          "finger's share Z_f = Z_loaded - Z_unloaded (same channel names, sample rate and segment). Per "
          "frequency: m = Im(Z_f)/omega (kg), b = Re(Z_f) (N*s/m), damping ratio b/(2*m*omega).\n"
          "Output CSV: freq_Hz,z_real_Ns_m,z_imag_Ns_m,mass_kg,damping_Ns_m,damping_ratio,coherence. "
          "--fit-out fits a spring-mass-damper F/X = (k - m*omega^2) + j*omega*c by weighted linear least "
          "squares over the bins with coherence >= --min-coherence in --band-Hz, written as JSON: m_kg, "
          "c_Ns_m, k_N_m, natural_frequency_Hz, damping_ratio, their standard deviations (m_sd_kg, "
          "c_sd_Ns_m, k_sd_N_m) and the m-k correlation; --fix-stiffness K holds k at K N/m (0: mass and "
          "damper only). When |m-k correlation| > 0.95 the band cannot separate the stiffness from the mass: "
          "the JSON carries a warning (also printed) to widen the band or fix k.\n"
          "Example: tirstrain signals impedance plate.csv --force F_N --accel a_m_s2 --segment 4096 "
          "--band-Hz 20,400 --fit-out fit.json --out z.csv\n") +
          kWelchConventions);
  add_common(sub, o->c, "output CSV (see above)");
  sub->add_option("--force", o->force, "force channel, N")->required();
  sub->add_option("--accel", o->accel, "acceleration channel, m/s^2");
  sub->add_option("--velocity-column", o->velocity, "velocity channel, m/s (instead of --accel)");
  sub->add_option("--fix-stiffness", o->fix_stiffness_N_m, "hold the fitted stiffness k at this value, N/m");
  sub->add_option("--segment", o->segment, "segment length nperseg, samples")->required();
  sub->add_option("--overlap", o->overlap, "overlap, samples (default segment/2)")
      ->check(kSamplesAtLeastZero);
  sub->add_option("--unloaded", o->unloaded, "recording of the plate without the finger");
  sub->add_option("--band-Hz", o->band_Hz, "fit band LOW,HIGH in Hz (default: all bins)")->delimiter(',');
  sub->add_option("--min-coherence", o->min_coherence, "bins below are not fitted")->capture_default_str();
  sub->add_option("--fit-out", o->fit_out, "spring-mass-damper fit, JSON");
  sub->callback([o] { run_impedance(*o); });
}

json power_law_json(const ts::PowerLawFit& fit) {
  return {{"a", fit.a},
          {"b", fit.b},
          {"a_low", fit.a_low},
          {"a_high", fit.a_high},
          {"b_low", fit.b_low},
          {"b_high", fit.b_high},
          {"a_stderr", fit.a_stderr},
          {"b_stderr", fit.b_stderr},
          {"covariance_ab", fit.covariance_ab},
          {"confidence", fit.confidence},
          {"residual_rms", fit.residual_rms},
          {"samples", fit.samples}};
}

void add_power_law(CLI::App& signals) {
  struct Opts {
    std::string input, out, normal = "normal_N", mu = "mu";
    double confidence = 0.95;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "power-law", "Fit mu = a * W^b across trials with confidence intervals",
      "One row per trial (no time column needed); nonlinear least squares (Ceres), with confidence intervals "
      "estimate +/- t(n-2) * sigma * sqrt(diag((J^T J)^-1)).\n"
      "Output JSON: a, b, a_low, a_high, b_low, b_high, a_stderr, b_stderr, covariance_ab, confidence, "
      "residual_rms, samples.");
  sub->add_option("IN", o->input, "CSV with one row per trial")->required();
  sub->add_option("--out", o->out, "output JSON")->required();
  sub->add_option("--normal", o->normal, "normal force column W, N")->capture_default_str();
  add_example(sub, "tirstrain signals power-law trials.csv --normal normal_N --mu mu --out power_law.json");
  sub->add_option("--mu", o->mu, "friction coefficient column")->capture_default_str();
  sub->add_option("--confidence", o->confidence, "confidence level of the intervals")->capture_default_str();
  sub->callback([o] {
    const auto table = read_numeric_csv(o->input);
    const auto fit = in_context(o->input, o->mu, [&] {
      return ts::fit_power_law(table.column(o->normal), table.column(o->mu), o->confidence);
    });
    write_json(o->out, power_law_json(fit));
  });
}

void add_friction_speed(CLI::App& signals) {
  struct Opts {
    std::string input, out, speed = "speed_m_s", mu = "mu";
    double reference_speed_m_s = 0.01, confidence = 0.95;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "friction-speed", "Fit mu against sliding speed: power law and logarithmic law, compared",
      "One row per trial or stroke (no time column needed). Two laws, each with confidence intervals "
      "(estimate +/- t(n-2) * standard error): the power law mu = a * v^b (nonlinear least squares, Ceres, "
      "as `signals power-law`) and the logarithmic law mu = mu_ref + beta * ln(v / v_ref) (linear least "
      "squares). Both have two parameters, so their AIC = n ln(RSS/n) + 4 compares them directly; "
      "`preferred` names the lower, `delta_aic` says by how much (below 2: the data do not prefer either).\n"
      "Output JSON: power{a, b, intervals, residual_rms, aic}, log{mu_ref, beta, intervals, "
      "reference_speed_m_s, residual_rms, aic}, preferred, delta_aic.\n"
      "Example: tirstrain signals friction-speed strokes.csv --speed speed_m_s --mu mu --out speed_law.json");
  sub->add_option("IN", o->input, "CSV with one row per trial or stroke")->required();
  sub->add_option("--out", o->out, "output JSON")->required();
  sub->add_option("--speed", o->speed, "sliding speed column, m/s")->capture_default_str();
  sub->add_option("--mu", o->mu, "friction coefficient column")->capture_default_str();
  sub->add_option("--reference-speed-m-s", o->reference_speed_m_s, "v_ref of the logarithmic law, m/s")
      ->capture_default_str();
  sub->add_option("--confidence", o->confidence, "confidence level of the intervals")->capture_default_str();
  sub->callback([o] {
    const auto table = read_numeric_csv(o->input);
    const auto& speed = table.column(o->speed);
    const auto& mu = table.column(o->mu);
    const auto power =
        in_context(o->input, o->speed, [&] { return ts::fit_power_law(speed, mu, o->confidence); });
    const auto log_law = in_context(o->input, o->speed, [&] {
      return ts::fit_log_speed_law(speed, mu, o->reference_speed_m_s, o->confidence);
    });
    json pj = power_law_json(power);
    pj["aic"] = ts::least_squares_aic(power.residual_rms, power.samples, 2);
    json lj = {{"mu_ref", log_law.mu_ref},
               {"beta", log_law.beta},
               {"mu_ref_low", log_law.mu_ref_low},
               {"mu_ref_high", log_law.mu_ref_high},
               {"beta_low", log_law.beta_low},
               {"beta_high", log_law.beta_high},
               {"mu_ref_stderr", log_law.mu_ref_stderr},
               {"beta_stderr", log_law.beta_stderr},
               {"reference_speed_m_s", log_law.reference_speed_m_s},
               {"confidence", log_law.confidence},
               {"residual_rms", log_law.residual_rms},
               {"samples", log_law.samples},
               {"aic", ts::least_squares_aic(log_law.residual_rms, log_law.samples, 2)}};
    const double delta = pj["aic"].get<double>() - lj["aic"].get<double>();
    write_json(o->out, {{"power", pj},
                        {"log", lj},
                        {"preferred", delta <= 0.0 ? "power" : "log"},
                        {"delta_aic", std::abs(delta)}});
  });
}

void add_spatial(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string force, position, position_unit;
    long segment = 0, overlap = -1;
    double dx_m = 0.0, from_s = -1.0, to_s = -1.0, speed_window_s = 0.02;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "spatial", "Spatial spectrum of a force over plate position; predicted frequency v/lambda",
      std::string(
          "Spatial spectrum of a force recorded while the plate slides: the force is resampled uniformly "
          "in plate position (linear interpolation; the stroke must move one way) and Welch-averaged "
          "with 'sample rate' 1/dx.\nOutput CSV (DC row omitted): "
          "spatial_freq_per_m,wavelength_m,psd,predicted_freq_Hz,predicted_freq_peak_speed_Hz, with psd in "
          "N^2*m, predicted_freq_Hz = mean speed / wavelength (v/lambda) and predicted_freq_peak_speed_Hz "
          "= peak speed / wavelength, the peak speed over windows of --speed-window-s.\n") +
          kWelchConventions);
  add_common(sub, o->c, "output CSV (see above)");
  sub->add_option("--force", o->force, "force channel, N (mN when its name ends with _mN)")->required();
  add_example(sub,
              "tirstrain signals spatial stroke.csv --force tangential_N --position plate_x_mm --segment 512 "
              "--out spatial.csv");
  sub->add_option(
         "--position", o->position,
         "plate position channel; its unit from a name ending with _m, _mm or _um, or --position-unit")
      ->required();
  sub->add_option("--position-unit", o->position_unit, "unit of the position channel: m, mm or um");
  sub->add_option("--segment", o->segment, "segment length, spatial samples")->required();
  sub->add_option("--overlap", o->overlap, "overlap, samples (default segment/2)")
      ->check(kSamplesAtLeastZero);
  sub->add_option("--dx-m", o->dx_m, "spatial step, m (default: median |dx| of the stroke)");
  sub->add_option("--from-s", o->from_s, "start of the stroke, s (default: record start)");
  sub->add_option("--to-s", o->to_s, "end of the stroke, s (default: record end)");
  sub->add_option("--speed-window-s", o->speed_window_s, "window of the peak speed, s")
      ->capture_default_str();
  sub->callback([o] {
    const auto table = load(o->c, o->c.input, {o->force, o->position});
    std::size_t begin = 0, end = table.samples();
    if (o->from_s >= 0.0)
      begin = static_cast<std::size_t>(std::lower_bound(table.time_s.begin(), table.time_s.end(), o->from_s) -
                                       table.time_s.begin());
    if (o->to_s >= 0.0)
      end = static_cast<std::size_t>(std::upper_bound(table.time_s.begin(), table.time_s.end(), o->to_s) -
                                     table.time_s.begin());
    const auto m_per_unit =
        si_per_unit(o->position, o->position_unit, ts::Quantity::kPosition, "--position-unit");
    if (!m_per_unit)
      throw Error("cannot tell the unit of position column '" + o->position +
                      "': name it with _m, _mm or _um, or give --position-unit",
                  {.file = o->c.input, .key = "--position"});
    const auto position_m = scaled(table.column(o->position), *m_per_unit);
    const auto force_N =
        scaled(table.column(o->force), si_per_unit(o->force, "", ts::Quantity::kForce, "").value_or(1.0));
    const auto spec = in_context(o->c.input, o->position, [&] {
      const auto s =
          ts::to_spatial_domain(table.time_s, position_m, force_N, o->dx_m, begin, end, o->speed_window_s);
      return ts::spatial_spectrum(s, welch_options(o->segment, o->overlap));
    });
    CsvWriter out(o->c.out, {"spatial_freq_per_m", "wavelength_m", "psd", "predicted_freq_Hz",
                             "predicted_freq_peak_speed_Hz"});
    for (std::size_t k = 1; k < spec.psd.size(); ++k)
      out.row({spec.spatial_freq_per_m[k], 1.0 / spec.spatial_freq_per_m[k], spec.psd[k],
               spec.mean_speed_m_s * spec.spatial_freq_per_m[k],
               spec.peak_speed_m_s * spec.spatial_freq_per_m[k]});
    out.commit();
  });
}

struct PadDeformationOpts {
  Common c;
  std::string calibration, cal_pad, cal_side, side, force, bands_out;
  long segment = 0, overlap = -1;
  double min_coherence = 0.9, m_kg = 0.0, c_Ns_m = 0.0, k_N_m = 0.0;
  std::vector<double> bands_Hz;
};

// The pad displacement PSD from the side accelerometer through the calibrated G1, and from the force
// through G2 when a force channel is given.
struct PadDisplacement {
  ts::PadTransfer calibration;
  std::vector<double> psd_side_m2_Hz, psd_force_m2_Hz;
};

PadDisplacement pad_displacement(const PadDeformationOpts& o) {
  const bool with_force = !o.force.empty();
  const auto w = welch_options(o.segment, o.overlap);
  const auto cal_table = load(o.c, o.calibration, {o.cal_pad, o.cal_side});
  std::vector<std::string> required{o.side};
  if (with_force) required.push_back(o.force);
  const auto table = load(o.c, o.c.input, required);
  if (std::abs(cal_table.sample_rate_Hz - table.sample_rate_Hz) > 1e-6 * table.sample_rate_Hz)
    throw Error("calibration sample rate " + std::to_string(cal_table.sample_rate_Hz) + " Hz differs from " +
                    std::to_string(table.sample_rate_Hz) + " Hz of the trial",
                {.file = o.calibration});
  PadDisplacement out;
  out.calibration = in_context(o.calibration, o.cal_side, [&] {
    return ts::calibrate_pad_transfer(cal_table.column(o.cal_pad), cal_table.column(o.cal_side),
                                      cal_table.sample_rate_Hz, w, o.min_coherence);
  });
  const auto side_psd =
      in_context(o.c.input, o.side, [&] { return ts::welch(table.column(o.side), table.sample_rate_Hz, w); });
  out.psd_side_m2_Hz = ts::pad_displacement_psd_from_side(out.calibration, side_psd.psd);
  if (with_force) {
    const auto fp = in_context(o.c.input, o.force,
                               [&] { return ts::welch(table.column(o.force), table.sample_rate_Hz, w); });
    out.psd_force_m2_Hz = ts::pad_displacement_psd_from_force(
        fp.freq_Hz, fp.psd, ts::MassSpringDamper{o.m_kg, o.c_Ns_m, o.k_N_m});
  }
  return out;
}

void write_pad_bands(const PadDeformationOpts& o, const PadDisplacement& xp) {
  if (o.bands_Hz.size() < 2)
    throw Error("--bands-out needs at least two edges in --bands-Hz", {.key = "--bands-Hz"});
  const std::vector<double>& freq_Hz = xp.calibration.freq_Hz;
  CsvWriter bands(o.bands_out, {"low_Hz", "high_Hz", "rms_side_m", "rms_force_m", "ratio"});
  for (std::size_t b = 0; b + 1 < o.bands_Hz.size(); ++b) {
    const double lo = o.bands_Hz[b], hi = o.bands_Hz[b + 1];
    const double rs = ts::band_rms(freq_Hz, xp.psd_side_m2_Hz, lo, hi);
    const double rf = xp.psd_force_m2_Hz.empty() ? 0.0 : ts::band_rms(freq_Hz, xp.psd_force_m2_Hz, lo, hi);
    bands.row({lo, hi, rs, rf, rf > 0.0 ? rs / rf : 0.0});
  }
  bands.commit();
}

void run_pad_deformation(const PadDeformationOpts& o) {
  const bool with_force = !o.force.empty();
  if (with_force && !(o.m_kg > 0.0 && o.k_N_m > 0.0 && o.c_Ns_m >= 0.0))
    throw Error("--force needs --m-kg > 0, --c-Ns-m >= 0 and --k-N-m > 0", {.key = "--force"});
  const PadDisplacement xp = pad_displacement(o);
  const ts::PadTransfer& cal = xp.calibration;
  std::vector<std::string> names{"freq_Hz", "g1_gain",          "g1_phase_rad", "calibration_coherence",
                                 "valid",   "xp_psd_side_m2_Hz"};
  if (with_force) names.push_back("xp_psd_force_m2_Hz");
  CsvWriter out(o.c.out, names);
  for (std::size_t k = 0; k < cal.freq_Hz.size(); ++k) {
    std::vector<double> row{cal.freq_Hz[k],   std::abs(cal.g1[k]),      std::arg(cal.g1[k]),
                            cal.coherence[k], cal.valid[k] ? 1.0 : 0.0, xp.psd_side_m2_Hz[k]};
    if (with_force) row.push_back(xp.psd_force_m2_Hz[k]);
    out.row(row);
  }
  if (!o.bands_out.empty()) write_pad_bands(o, xp);
  out.commit();
}

void add_pad_deformation(CLI::App& signals) {
  auto o = std::make_shared<PadDeformationOpts>();
  CLI::App* sub = add_verb(
      signals, "pad-deformation",
      "Pad displacement from a finger-side accelerometer (and from force through G2)",
      std::string(
          "The pad-to-side transfer G1 = A_side/A_pad is "
          "calibrated (H1) from a two-accelerometer sweep (--calibration with --cal-pad and --cal-side); "
          "bins "
          "with coherence >= --min-coherence are valid. Then X_p(omega) = A_side(omega)/(-omega^2 "
          "G1(omega)), "
          "reported as a PSD (m^2/Hz). With --force and --m-kg --c-Ns-m --k-N-m, also X_p = G2 F with "
          "G2 = 1/(m s^2 + c s + k).\nOutput CSV: freq_Hz,g1_gain,g1_phase_rad,calibration_coherence,valid,"
          "xp_psd_side_m2_Hz[,xp_psd_force_m2_Hz]. --bands-out: low_Hz,high_Hz,rms_side_m,rms_force_m,ratio "
          "for consecutive edges in --bands-Hz.\n") +
          kWelchConventions);
  add_common(sub, o->c, "output CSV (see above)");
  sub->add_option("--calibration", o->calibration, "two-accelerometer calibration recording")->required();
  add_example(sub,
              "tirstrain signals pad-deformation trial.csv --side accel_side_m_s2 --calibration sweep.csv "
              "--cal-pad accel_pad_m_s2 --cal-side accel_side_m_s2 --segment 2048 --out pad.csv");
  sub->add_option("--cal-pad", o->cal_pad, "pad accelerometer channel in the calibration, m/s^2")->required();
  sub->add_option("--cal-side", o->cal_side, "side accelerometer channel in the calibration, m/s^2")
      ->required();
  sub->add_option("--side", o->side, "side accelerometer channel in IN, m/s^2")->required();
  sub->add_option("--force", o->force, "tangential force channel in IN, N");
  sub->add_option("--m-kg", o->m_kg, "G2 mass, kg");
  sub->add_option("--c-Ns-m", o->c_Ns_m, "G2 damping, N*s/m");
  sub->add_option("--k-N-m", o->k_N_m, "G2 stiffness, N/m");
  sub->add_option("--segment", o->segment, "segment length nperseg, samples (same for both files)")
      ->required();
  sub->add_option("--overlap", o->overlap, "overlap, samples (default segment/2)")
      ->check(kSamplesAtLeastZero);
  sub->add_option("--min-coherence", o->min_coherence, "calibration bins below are invalid")
      ->capture_default_str();
  sub->add_option("--bands-Hz", o->bands_Hz, "band edges F0,F1,...,Fn in Hz")->delimiter(',');
  sub->add_option("--bands-out", o->bands_out, "per-band RMS comparison CSV");
  sub->callback([o] { run_pad_deformation(*o); });
}

void add_resample(CLI::App& signals) {
  struct Opts {
    Common c;
    std::string times, times_column = "t_s";
    std::vector<std::string> columns;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = add_verb(
      signals, "resample", "Resample channels to given times (e.g. frame timestamps)",
      "Linear interpolation. Times outside the "
      "channel record are an error (nothing is extrapolated).\nOutput CSV: t_s followed by the channels.");
  add_common(sub, o->c, "output CSV: t_s,COLUMNS...");
  add_example(
      sub,
      "tirstrain signals resample channels.csv --times REC/frames.csv --columns normal_N,tangential_N "
      "--out at_frames.csv");
  sub->add_option("--times", o->times, "CSV holding the target times")->required();
  sub->add_option("--times-column", o->times_column, "column of --times, s")->capture_default_str();
  sub->add_option("--columns", o->columns,
                  "channels to resample, NAME,NAME (default: all; a .mat matrix column as dataQ[:,2])");
  sub->callback([o] {
    o->columns = split_channel_names(o->columns);
    const auto table = load(o->c, o->c.input, o->columns);
    const auto times = read_numeric_csv(o->times);
    std::vector<double> query = times.column(o->times_column);
    for (double& t : query) t *= signals::time_column_seconds_per_unit(o->times_column);
    const auto columns = o->columns.empty() ? table.names : o->columns;
    std::vector<std::vector<double>> values;
    for (const auto& name : columns)
      values.push_back(in_context(o->times, o->times_column, [&] {
        return ts::resample_linear(table.time_s, table.column(name), query);
      }));
    std::vector<std::string> names{signals::seconds_column_name(o->c.time_column)};
    names.insert(names.end(), columns.begin(), columns.end());
    CsvWriter out(o->c.out, names);
    for (std::size_t i = 0; i < query.size(); ++i) {
      std::vector<double> row{query[i]};
      for (const auto& v : values) row.push_back(v[i]);
      out.row(row);
    }
    out.commit();
  });
}

// Options of `signals align`.
struct AlignOptions {
  Common c;                              // the channel file, its reading options and the JSON output
  std::optional<double> offset_s;        // a known offset, s (t_camera = t_channel + offset)
  std::string trigger, edge = "rising";  // trigger channel and the edge the camera saw
  std::optional<double> threshold;       // trigger level, channel units (unset: 50 % of its range)
  std::optional<double> camera_edge_s;   // camera time of the trigger edge, s
  std::string position, camera, camera_column, camera_time_column = "t_s";  // cross-correlation inputs
  double max_lag_s = 0.2;                                                   // largest offset searched, s
  std::string shifted_out;  // the channel file moved to the camera clock (optional)
};

// The offset by the one method the options name, and that method's own fields for the JSON.
ts::ClockAlignment compute_alignment(const AlignOptions& o, const ts::ChannelTable& table, json& j) {
  ts::ClockAlignment a;
  if (o.offset_s) {
    a = in_context(o.c.input, "", [&] { return ts::align_explicit(*o.offset_s); });
  } else if (!o.trigger.empty()) {
    if (!o.camera_edge_s)
      throw Error("--trigger needs --camera-edge-s (the camera time of the same edge)",
                  {.key = "--camera-edge-s"});
    a = in_context(o.c.input, o.trigger, [&] {
      return ts::align_by_trigger_channel(table.time_s, table.column(o.trigger), *o.camera_edge_s,
                                          o.threshold, o.edge == "rising");
    });
    j["channel_edge_s"] = a.channel_edge_s;
    j["camera_edge_s"] = a.camera_edge_s;
    if (o.threshold) j["threshold"] = *o.threshold;
  } else {
    if (o.camera.empty() || o.camera_column.empty())
      throw Error("--position needs --camera and --camera-column", {.key = "--camera"});
    const auto camera =
        load(Common{o.camera, "", o.camera_time_column, o.c.rate_tolerance, o.c.group, std::nullopt},
             o.camera, {o.camera_column});
    a = in_context(o.c.input, o.position, [&] {
      return ts::align_by_cross_correlation(
          table.time_s, ts::oriented_along_motion(table.column(o.position)), camera.time_s,
          ts::oriented_along_motion(camera.column(o.camera_column)), o.max_lag_s);
    });
    j["max_lag_s"] = o.max_lag_s;
    j["camera_samples_compared"] = a.samples_compared;
  }
  return a;
}

void run_align(const AlignOptions& o) {
  const int modes = (o.offset_s ? 1 : 0) + (o.trigger.empty() ? 0 : 1) + (o.position.empty() ? 0 : 1);
  if (modes != 1)
    throw Error("give exactly one of --offset-s, --trigger or --position", {.key = "--offset-s"});
  std::vector<std::string> required;
  if (!o.trigger.empty()) required.push_back(o.trigger);
  if (!o.position.empty()) required.push_back(o.position);
  const auto table = load(o.c, o.c.input, required);
  json j;
  const ts::ClockAlignment a = compute_alignment(o, table, j);
  j["method"] = a.method;
  j["offset_s"] = a.offset_s;
  j["correlation"] = a.correlation;
  j["convention"] = "t_camera = t_channel + offset_s";
  j["input"] = o.c.input;
  if (!o.shifted_out.empty()) {
    std::vector<std::string> names{signals::seconds_column_name(o.c.time_column)};
    names.insert(names.end(), table.names.begin(), table.names.end());
    CsvWriter out(o.shifted_out, names);
    std::vector<double> row(names.size());
    for (std::size_t i = 0; i < table.samples(); ++i) {
      row[0] = table.time_s[i] + a.offset_s;
      for (std::size_t c = 0; c < table.columns.size(); ++c) row[c + 1] = table.columns[c][i];
      out.row(row);
    }
    out.commit();
  }
  write_json(o.c.out, j);
}

void add_align(CLI::App& signals) {
  auto o = std::make_shared<AlignOptions>();
  CLI::App* sub = add_verb(
      signals, "align",
      "Clock offset between a channel file and the camera (explicit, trigger, cross-correlation)",
      "Clock offset between the channel clock and the camera clock, t_camera = t_channel + offset_s, by one "
      "of:\n"
      "  --offset-s S                 a known offset;\n"
      "  --trigger COL --camera-edge-s T [--threshold V] [--edge rising|falling]\n"
      "                               the first crossing of the threshold (default: the 50 % level between "
      "the\n"
      "                               channel's minimum and maximum), linearly interpolated between samples, "
      "is\n"
      "                               the edge the camera saw at T;\n"
      "  --position COL --camera CAM.csv --camera-column C [--camera-time-column t_s] [--max-lag-s 0.2]\n"
      "                               cross-correlation of the plate position channel with the "
      "image-measured\n"
      "                               plate displacement (any units): for each trial offset within +-max-lag "
      "the\n"
      "                               channel is interpolated at the camera times minus the offset and the "
      "Pearson\n"
      "                               correlation taken; steps of one channel sample, refined by a parabola "
      "and a\n"
      "                               golden-section search (sub-sample resolution). Both series are first\n"
      "                               oriented so that their largest excursion from the first sample is "
      "positive.\n"
      "Output JSON: method, offset_s, correlation (1 for explicit and trigger), convention, and "
      "channel_edge_s,\n"
      "camera_edge_s, threshold (trigger) or max_lag_s, camera_samples_compared (cross-correlation).\n"
      "--shifted-out writes IN with its time column moved to the camera clock (all columns, same names).");
  add_common(sub, o->c, "output JSON: method, offset_s, correlation, ...");
  add_example(
      sub, "tirstrain signals align channels.csv --trigger trigger_V --camera-edge-s 0.1 --out align.json");
  auto* offset =
      sub->add_option("--offset-s", o->offset_s, "explicit offset, s (t_camera = t_channel + offset)");
  auto* trigger = sub->add_option("--trigger", o->trigger, "trigger channel (any unit)");
  sub->add_option("--threshold", o->threshold, "trigger level, channel units (default: 50 % of its range)")
      ->needs(trigger);
  sub->add_option("--edge", o->edge, "trigger edge: rising or falling")
      ->check(CLI::IsMember({"rising", "falling"}))
      ->capture_default_str()
      ->needs(trigger);
  sub->add_option("--camera-edge-s", o->camera_edge_s, "camera time of the trigger edge, s")->needs(trigger);
  auto* position = sub->add_option("--position", o->position, "plate position channel (any unit)");
  sub->add_option("--camera", o->camera, "CSV of the image-measured plate displacement")->needs(position);
  sub->add_option("--camera-column", o->camera_column, "displacement column of --camera (any unit)")
      ->needs(position);
  sub->add_option("--camera-time-column", o->camera_time_column, "time column of --camera, s")
      ->capture_default_str();
  sub->add_option("--max-lag-s", o->max_lag_s, "largest offset searched, s")->capture_default_str();
  sub->add_option("--shifted-out", o->shifted_out, "IN on the camera clock (CSV)");
  offset->excludes(trigger)->excludes(position);
  trigger->excludes(position);
  sub->callback([o] { run_align(*o); });
}

}  // namespace

void add_signals_command(CLI::App& app) {
  CLI::App* signals = app.add_subcommand("signals",
                                         "Force, accelerometer and position channels: filter, spectra, "
                                         "phases, friction, impedance, recurrence analysis");
  signals->require_subcommand(1);
  add_filter(*signals);
  add_psd(*signals);
  add_tf(*signals);
  add_signals_recurrence_verbs(*signals);
  add_impedance(*signals);
  add_signals_friction_verb(*signals);
  add_signals_phases_verb(*signals);
  add_power_law(*signals);
  add_friction_speed(*signals);
  add_spatial(*signals);
  add_pad_deformation(*signals);
  add_resample(*signals);
  add_align(*signals);
}

}  // namespace tirstrain::cli
