#pragma once
// Friction and loading events from force (and plate position) channels, as the seed studies compute them:
// μ(t) = F_t / W, the dynamic μ on the full-slip plateau (detected, not hand-picked), movement onset, the
// time the tangential force reaches 90 % of its plateau, full slip, the external work U_ext = ∫ F dx from
// onset to the 90 % point, and the power law μ = a·W^b across trials with confidence intervals.
// All functions take plain vectors sampled on one time axis so the pipeline can call them on channels
// resampled to frame times as well as on raw channels.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace tirstrain::signals {

struct FrictionSeries {
  std::vector<double> mu;   // F_t / W where valid, 0 elsewhere (check `valid`)
  std::vector<char> valid;  // W >= min_normal_N
  std::size_t invalid_count = 0;
};

// μ is undefined while the finger is (nearly) off the plate; samples with W < min_normal_N are marked
// invalid instead of producing huge or infinite ratios.
FrictionSeries friction_coefficient(const std::vector<double>& tangential_N,
                                    const std::vector<double>& normal_N, double min_normal_N);

struct PlateauOptions {
  double window_s = 0.1;              // sliding-window length for the local slope
  double max_relative_change = 0.05;  // |slope|·window allowed, relative to the local mean
  double min_duration_s = 0.2;        // shorter flat stretches are not plateaus
};

struct Plateau {
  std::size_t start_index = 0;
  std::size_t end_index = 0;  // inclusive
  double start_s = 0.0;
  double end_s = 0.0;
  double mean = 0.0;
  double stddev = 0.0;
};

// The plateau is the flat stretch (local linear trend over `window_s` changing the value by at most
// max_relative_change of the local mean) lasting at least min_duration_s with the largest |mean|: the
// full-slip plateau of μ or F_t is the highest flat part of a loading trial, and the rest before loading
// (μ ≈ 0) is flat too but never the highest. `valid` (empty = all valid) masks samples out; the search
// starts at start_index. nullopt when nothing qualifies.
std::optional<Plateau> detect_plateau(const std::vector<double>& time_s, const std::vector<double>& values,
                                      const std::vector<char>& valid, const PlateauOptions& options,
                                      std::size_t start_index = 0);

struct EventOptions {
  double baseline_s = 0.1;        // quiet start used for the baseline level and noise σ
  double onset_sigma = 5.0;       // noise band half-width, in baseline σ
  double onset_fraction = 0.05;   // detection threshold, as a fraction of the total excursion
  double plateau_fraction = 0.9;  // the "90 %" point
  double slip_band = 0.01;        // full slip: |F_t − plateau| within this fraction of the plateau rise
  PlateauOptions plateau;
};

struct TrialEvents {
  std::string onset_source;  // "position" or "tangential"
  double onset_s = 0.0;
  std::size_t onset_index = 0;  // first sample at or after the event
  double fraction_s = 0.0;      // tangential force at plateau_fraction of its plateau
  std::size_t fraction_index = 0;
  double full_slip_s = 0.0;
  std::size_t full_slip_index = 0;
  double baseline_tangential_N = 0.0;
  // The baseline's last sample time; before baseline_s when the movement starts inside that window
  // (baseline_shortened), which a caller reports.
  double baseline_end_s = 0.0;
  bool baseline_shortened = false;
  Plateau tangential_plateau;
  std::optional<double> external_work_J;  // ∫ F_t dx from onset to the fraction point (needs position)
};

// Onset: the signal (position if given, else tangential force) first leaves its baseline by
// onset_fraction of its total excursion; the onset is the last sample before that still inside the
// baseline noise band (onset_sigma·σ), so a clean ramp's onset is its first moving sample.
// Throws Error when the baseline is longer than the record, nothing moves, or no plateau is found.
TrialEvents detect_events(const std::vector<double>& time_s, const std::vector<double>& tangential_N,
                          const std::vector<double>* position_m, const EventOptions& options);

// The same events with the plateau given instead of searched (e.g. the start of a slide found by
// detect_phases): `plateau` in the tangential force's own units and sample indices; full slip is searched
// from t90 up to plateau.end_index.
TrialEvents detect_events_on_plateau(const std::vector<double>& time_s,
                                     const std::vector<double>& tangential_N,
                                     const std::vector<double>* position_m, const Plateau& plateau,
                                     const EventOptions& options);

// ∫ F dx between t0 and t1 (trapezoid on the samples, the end points linearly interpolated). Sign as
// given: F and x measured along the same axis.
double external_work_J(const std::vector<double>& time_s, const std::vector<double>& force_N,
                       const std::vector<double>& position_m, double t0_s, double t1_s);

struct PowerLawFit {
  double a = 0.0, b = 0.0;
  double a_stderr = 0.0, b_stderr = 0.0;
  double a_low = 0.0, a_high = 0.0;  // confidence interval
  double b_low = 0.0, b_high = 0.0;
  double covariance_ab = 0.0;
  double confidence = 0.95;
  double residual_rms = 0.0;
  std::size_t samples = 0;
};

// Least squares on μ − a·W^b (Ceres, Levenberg–Marquardt, started from a log–log line). Intervals:
// estimate ± t(1−(1−confidence)/2, n−2)·σ̂·sqrt(diag((JᵀJ)⁻¹)), σ̂² = SSR/(n−2), JᵀJ at the optimum.
// Needs W > 0 and at least 3 samples; throws Error naming the offending sample otherwise.
PowerLawFit fit_power_law(const std::vector<double>& normal_N, const std::vector<double>& mu,
                          double confidence = 0.95);

// Student t quantile, p in (0, 1), dof > 0.
double student_t_quantile(double p, double dof);

}  // namespace tirstrain::signals
