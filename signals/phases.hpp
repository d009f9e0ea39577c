#pragma once
// A real force recording segmented into its phases, and its force channels tared.
//
// A finger on a tribometer is recorded from before it touches the plate to after it lifts off: approach (no
// contact), press (the normal force W rises to its loaded level), loading (W held, the tangential force F_t
// builds up while the contact sticks), one or more slides (strokes, F_t ≈ μW, each in one direction) and
// release (W falls back to zero). The DAQ adds an offset to every channel, and the offset drifts.
//
// Tare: the quiet stretches without contact (found from W, or given) define each channel's zero; a straight
// line fitted over the stretches before and after the contact removes a linear drift, a constant fitted over
// one stretch removes the offset only. Phase times are then taken on the tared channels:
//   - contact start, loaded: the press is the line through the 20 % and 80 % crossings of the loaded level,
//     extrapolated to 0 % (contact start) and 100 % (loaded); release and contact end likewise on the way
//     down. A threshold crossing moves with the threshold and the noise, the extrapolated line does not, and
//     a ramp's ends are where it meets the two levels.
//   - strokes: stretches between loaded and release where |μ| (smoothed) exceeds half its typical level
//     (98th percentile, at least μ 0.02); each stroke's slide starts where the loading rise of μ ends (its
//     slope falls to a fraction of the rise's steepest: the Cattaneo–Mindlin curve meets μW with zero
//     slope) and ends where the fall begins, and never runs past the start of the release. A μ that wanders
//     along the slide changes far more slowly than the rise and the fall, so the slide is not cut short
//     where μ dips.
// All times are on the channel file's clock, in seconds.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace tirstrain::signals {

// A warning the user must see, with a stable code so scripts and tests can look for it.
struct PhaseWarning {
  std::string code;     // e.g. "normal_force_negative"
  std::string message;  // what was found and what to do
};

struct TimeStretch {
  double start_s = 0.0;
  double end_s = 0.0;
};

struct PhaseOptions {
  double smooth_s = 0.02;           // moving-mean window for the phase search (μ and W), s
  double head_s = 0.1;              // stretch at the record start giving the first no-contact level, s
  double min_contact_N = 0.02;      // smallest normal-force excursion that counts as contact, N
  double noise_sigmas = 10.0;       // ... and at least this many σ of the channel noise
  double tare_guard_s = 0.1;        // kept clear of the press and release ramps when taring, s
  double min_quiet_s = 0.2;         // shortest no-contact stretch used for the tare, s
  std::optional<TimeStretch> tare;  // a given quiet stretch (offsets only); empty: found from W
  bool tare_enabled = true;         // false: the channels are used as recorded
  double min_normal_N = 0.05;       // μ is undefined below this normal force, N
  double stroke_fraction = 0.5;     // a stroke is where |μ| exceeds this fraction of its typical level
  double min_stroke_mu = 0.02;      // ... and at least this: a hold's noise is never a stroke
  double knee_fraction = 0.2;  // a rise ends (a fall begins) where μ's slope is this fraction of its steepest
  double knee_window_s = 0.15;   // the steepest slope is searched this far around the stroke's edges, s
  double level_window_s = 0.25;  // the tangential force's level at a slide's start is its median over this, s
  double min_stroke_s = 0.1;     // shorter stretches above the stroke threshold are not strokes, s
};

// What was subtracted from one channel: baseline(t) = offset + drift_per_s · (t − reference_s).
struct ChannelTare {
  double offset = 0.0;        // baseline at reference_s (the contact start), channel units
  double drift_per_s = 0.0;   // slope of the fitted line; 0 for a constant
  double residual_rms = 0.0;  // scatter about the baseline over the quiet stretches (the channel's noise)
};

struct Tare {
  std::string model;   // "linear" (stretches before and after), "constant" (one stretch), "none"
  std::string source;  // "found from the normal force", "given", "disabled"
  std::vector<TimeStretch> quiet;
  double reference_s = 0.0;
  ChannelTare normal, tangential;
};

struct Stroke {
  double slide_start_s = 0.0;
  double slide_end_s = 0.0;
  double mu_mean = 0.0;  // F_t/W over the whole slide (samples with W ≥ min_normal_N), signed
  double mu_sd = 0.0;
  std::size_t mu_samples = 0;
  int direction = 1;             // +1 or −1: sign of the plate's travel (position given) or of F_t
  std::string direction_source;  // "position" or "tangential"
};

struct Phases {
  double record_start_s = 0.0, record_end_s = 0.0;
  double contact_start_s = 0.0;  // the press begins (end of the approach)
  double loaded_s = 0.0;         // W reaches its loaded level (end of the press)
  double release_s = 0.0;        // W starts to fall (end of the last slide at the latest)
  double contact_end_s = 0.0;    // W back at zero
  double normal_level_N = 0.0;   // loaded level of the tared W (median over the contact)
  int normal_sign = 1;           // sign of W's excursion from its no-contact level (−1: inverted channel)
  Tare tare;
  std::vector<Stroke> strokes;
  std::vector<double> normal_N, tangential_N;  // tared, on the input samples
  std::vector<PhaseWarning> warnings;
};

// Segments the recording. `normal_N` and `tangential_N` have the signs the channel config gives them;
// `position` (any unit, may be null) gives the strokes' directions. Throws Error when the lengths differ,
// the record is shorter than the head stretch, or W never leaves its starting level while that level is
// below min_contact_N (nothing touched the plate).
Phases detect_phases(const std::vector<double>& time_s, const std::vector<double>& normal_N,
                     const std::vector<double>& tangential_N, const std::vector<double>* position,
                     const PhaseOptions& options);

// First sample at or after t (size() when none).
std::size_t index_at_or_after(const std::vector<double>& time_s, double t);

// Centred moving mean over `window` samples (shrunk at the ends).
std::vector<double> moving_mean(const std::vector<double>& v, std::size_t window);

}  // namespace tirstrain::signals
