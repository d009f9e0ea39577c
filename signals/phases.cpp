#include "signals/phases.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/median.hpp"

namespace tirstrain::signals {
namespace {

std::string fmt(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

double median_of(std::vector<double> v) {
  return v.empty() ? 0.0 : upper_median_in_place(v);
}

double median_range(const std::vector<double>& v, std::size_t lo, std::size_t hi) {
  hi = std::min(hi, v.size());
  if (lo >= hi) return 0.0;
  return median_of(std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(lo),
                                       v.begin() + static_cast<std::ptrdiff_t>(hi)));
}

// Noise σ from successive differences (median absolute deviation, ÷√2): a slow trend or a ramp does not
// inflate it the way the spread about the mean would.
double noise_sigma(const std::vector<double>& v, std::size_t lo, std::size_t hi) {
  hi = std::min(hi, v.size());
  if (hi < lo + 3) return 0.0;
  std::vector<double> d;
  d.reserve(hi - lo);
  for (std::size_t i = lo + 1; i < hi; ++i) d.push_back(v[i] - v[i - 1]);
  const double m = median_of(d);
  for (double& x : d) x = std::abs(x - m);
  return 1.4826 * median_of(d) / std::sqrt(2.0);
}

std::size_t samples_in(double seconds, double dt) {
  return std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(seconds / dt)));
}

// Time the signal first rises through `level` in [from, to), interpolated between samples.
std::optional<double> rising_through(const std::vector<double>& t, const std::vector<double>& v, double level,
                                     std::size_t from, std::size_t to) {
  for (std::size_t i = std::max<std::size_t>(from, 1); i < std::min(to, v.size()); ++i)
    if (v[i - 1] < level && v[i] >= level)
      return t[i - 1] + (level - v[i - 1]) / (v[i] - v[i - 1]) * (t[i] - t[i - 1]);
  return std::nullopt;
}

// Time the signal first falls through `level` in [from, to), interpolated between samples.
std::optional<double> falling_through(const std::vector<double>& t, const std::vector<double>& v,
                                      double level, std::size_t from, std::size_t to) {
  for (std::size_t i = std::max<std::size_t>(from, 1); i < std::min(to, v.size()); ++i)
    if (v[i - 1] >= level && v[i] < level)
      return t[i - 1] + (v[i - 1] - level) / (v[i - 1] - v[i]) * (t[i] - t[i - 1]);
  return std::nullopt;
}

// The press and the release, as the ends of the lines through the 20 % and 80 % crossings.
struct ContactTimes {
  double contact_start_s, loaded_s, release_s, contact_end_s;
  bool from_start = false, until_end = false;
  double press_s = 0.0, unload_s = 0.0;  // 20 → 80 % durations (0 when absent)
};

// `load`: W's excursion from its no-contact level, positive in contact; `level`: its loaded level.
ContactTimes contact_times(const std::vector<double>& t, const std::vector<double>& load, double level) {
  const std::size_t n = t.size();
  ContactTimes c{t.front(), t.front(), t.back(), t.back()};
  const auto up20 = rising_through(t, load, 0.2 * level, 0, n);
  const auto up80 =
      up20 ? rising_through(t, load, 0.8 * level, index_at_or_after(t, *up20), n) : std::nullopt;
  if (up20 && up80) {
    c.press_s = *up80 - *up20;
    c.contact_start_s = std::max(t.front(), *up20 - c.press_s / 3.0);
    c.loaded_s = *up80 + c.press_s / 3.0;
  } else {
    c.from_start = true;
  }
  std::size_t last80 = n;
  for (std::size_t i = n; i-- > 0;)
    if (load[i] >= 0.8 * level) {
      last80 = i;
      break;
    }
  const auto down80 = last80 < n ? falling_through(t, load, 0.8 * level, last80, n) : std::nullopt;
  const auto down20 = down80 ? falling_through(t, load, 0.2 * level, last80, n) : std::nullopt;
  if (down80 && down20) {
    c.unload_s = *down20 - *down80;
    c.release_s = std::max(c.loaded_s, *down80 - c.unload_s / 3.0);
    c.contact_end_s = std::min(t.back(), *down20 + c.unload_s / 3.0);
  } else {
    c.until_end = true;
  }
  return c;
}

// Loaded level: the median excursion over the samples above half the largest one.
double loaded_level(const std::vector<double>& load) {
  const double peak = *std::max_element(load.begin(), load.end());
  std::vector<double> high;
  for (double v : load)
    if (v > 0.5 * peak) high.push_back(v);
  return median_of(high);
}

void warn(Phases& p, const std::string& code, const std::string& message) {
  p.warnings.push_back({code, message});
}

// Least-squares line (or constant) through one channel's quiet samples.
ChannelTare fit_baseline(const std::vector<double>& t, const std::vector<double>& v,
                         const std::vector<TimeStretch>& quiet, double reference_s, bool linear) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  const auto each = [&](auto fn) {
    for (const TimeStretch& q : quiet)
      for (std::size_t i = index_at_or_after(t, q.start_s); i < t.size() && t[i] <= q.end_s; ++i)
        fn(t[i] - reference_s, v[i]);
  };
  each([&](double x, double y) {
    n += 1;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  });
  ChannelTare c;
  if (n < 2) return c;
  const double denom = n * sxx - sx * sx;
  c.drift_per_s = linear && denom > 0.0 ? (n * sxy - sx * sy) / denom : 0.0;
  c.offset = (sy - c.drift_per_s * sx) / n;
  double ss = 0.0;
  each([&](double x, double y) { ss += std::pow(y - c.offset - c.drift_per_s * x, 2); });
  c.residual_rms = std::sqrt(ss / n);
  return c;
}

std::vector<double> subtract(const std::vector<double>& t, const std::vector<double>& v, const ChannelTare& c,
                             double reference_s) {
  std::vector<double> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = v[i] - c.offset - c.drift_per_s * (t[i] - reference_s);
  return out;
}

// First look at the contact, on W less its level at the record start: the sign of W's excursion and the
// no-contact stretches before and after the contact, kept clear of the ramps.
struct RoughContact {
  bool contact_everywhere = false;
  int sign = 1;
  ContactTimes times{};
  std::vector<TimeStretch> quiet;
};

RoughContact rough_contact(const std::vector<double>& t, const std::vector<double>& w_smooth,
                           const std::vector<double>& w, const PhaseOptions& o) {
  const double dt = (t.back() - t.front()) / static_cast<double>(t.size() - 1);
  const std::size_t head = samples_in(o.head_s, dt);
  const double start_level = median_range(w_smooth, 0, head);
  const double sigma = noise_sigma(w, 0, head);
  double peak = 0.0;
  for (double v : w_smooth)
    if (std::abs(v - start_level) > std::abs(peak)) peak = v - start_level;
  RoughContact r;
  if (std::abs(peak) < std::max(o.min_contact_N, o.noise_sigmas * sigma)) {
    if (start_level < o.min_contact_N)
      throw Error("no contact: the normal force never leaves its level at the record start (" +
                  fmt(start_level) + " N) by more than " +
                  fmt(std::max(o.min_contact_N, o.noise_sigmas * sigma)) + " N");
    r.contact_everywhere = true;
    return r;
  }
  r.sign = peak < 0.0 ? -1 : 1;
  std::vector<double> load(w_smooth.size());
  for (std::size_t i = 0; i < load.size(); ++i) load[i] = r.sign * (w_smooth[i] - start_level);
  r.times = contact_times(t, load, loaded_level(load));
  const double guard_in = o.tare_guard_s + r.times.press_s, guard_out = o.tare_guard_s + r.times.unload_s;
  if (!r.times.from_start && r.times.contact_start_s - guard_in - t.front() >= o.min_quiet_s)
    r.quiet.push_back({t.front(), r.times.contact_start_s - guard_in});
  if (!r.times.until_end && t.back() - (r.times.contact_end_s + guard_out) >= o.min_quiet_s)
    r.quiet.push_back({r.times.contact_end_s + guard_out, t.back()});
  return r;
}

// Chooses the quiet stretches and fits each force channel's baseline over them.
Tare tare_channels(const std::vector<double>& t, const std::vector<double>& w, const std::vector<double>& ft,
                   const RoughContact& rough, const PhaseOptions& o, Phases& p) {
  Tare tare;
  tare.reference_s = rough.times.contact_start_s;
  if (!o.tare_enabled) {
    tare.model = "none";
    tare.source = "disabled";
    return tare;
  }
  if (o.tare) {
    if (!(o.tare->end_s > o.tare->start_s) || o.tare->start_s < t.front() || o.tare->end_s > t.back())
      throw Error("the tare stretch " + fmt(o.tare->start_s) + " to " + fmt(o.tare->end_s) +
                      " s must be an interval inside the record (" + fmt(t.front()) + " to " + fmt(t.back()) +
                      " s)",
                  {.key = "tare_s"});
    tare.quiet = {*o.tare};
    tare.source = "given";
  } else {
    tare.quiet = rough.quiet;
    tare.source = "found from the normal force";
  }
  const bool linear = tare.quiet.size() == 2;
  tare.model = tare.quiet.empty() ? "none" : linear ? "linear" : "constant";
  if (tare.quiet.empty()) {
    warn(p, "not_tared",
         "no quiet stretch of at least " + fmt(o.min_quiet_s) +
             " s without contact before or after the contact: the force channels are used as recorded "
             "(offsets included); give one with the tare stretch option");
    return tare;
  }
  if (!linear && !o.tare)
    warn(p, "drift_not_observable",
         "only one quiet stretch without contact (" + fmt(tare.quiet[0].start_s) + " to " +
             fmt(tare.quiet[0].end_s) +
             " s): offsets removed, a drift of the baseline cannot be seen and is not removed");
  tare.normal = fit_baseline(t, w, tare.quiet, tare.reference_s, linear);
  tare.tangential = fit_baseline(t, ft, tare.quiet, tare.reference_s, linear);
  return tare;
}

// Contact times on the tared W; fills the Phases fields and the warnings about the record's ends.
void locate_contact(const std::vector<double>& t, const std::vector<double>& w_tared_smooth, int sign,
                    Phases& p) {
  std::vector<double> load(w_tared_smooth.size());
  for (std::size_t i = 0; i < load.size(); ++i) load[i] = sign * w_tared_smooth[i];
  p.normal_level_N = sign * loaded_level(load);
  const ContactTimes c = contact_times(t, load, std::abs(p.normal_level_N));
  p.contact_start_s = c.contact_start_s;
  p.loaded_s = c.loaded_s;
  p.release_s = c.release_s;
  p.contact_end_s = c.contact_end_s;
  if (c.from_start)
    warn(p, "contact_from_record_start",
         "the record starts in contact (no press seen): contact start and loaded are the record's start");
  if (c.until_end)
    warn(p, "contact_until_record_end",
         "the record ends in contact (no release seen): release and contact end are the record's end");
}

struct StrokeSearch {
  const std::vector<double>& t;
  const std::vector<double>& mu;         // raw F_t/W, 0 where invalid
  const std::vector<char>& valid;        // W ≥ min_normal_N
  const std::vector<double>& mu_smooth;  // ratio of the smoothed channels, 0 where invalid
  const std::vector<double>& slope;      // of mu_smooth, per second
  const std::vector<double>* position;
};

// Runs of one sign where |μ| (smoothed) exceeds the threshold, within [lo, hi).
std::vector<std::pair<std::size_t, std::size_t>> stroke_runs(const StrokeSearch& s, double threshold,
                                                             std::size_t lo, std::size_t hi,
                                                             std::size_t min_samples) {
  std::vector<std::pair<std::size_t, std::size_t>> runs;
  for (std::size_t i = lo; i < hi;) {
    if (!s.valid[i] || std::abs(s.mu_smooth[i]) <= threshold) {
      ++i;
      continue;
    }
    const bool positive = s.mu_smooth[i] > 0.0;
    std::size_t j = i;
    while (j + 1 < hi && s.valid[j + 1] && std::abs(s.mu_smooth[j + 1]) > threshold &&
           (s.mu_smooth[j + 1] > 0.0) == positive)
      ++j;
    if (j + 1 - i >= min_samples) runs.emplace_back(i, j);
    i = j + 1;
  }
  return runs;
}

// Slope of the smoothed μ, central differences over one smoothing window.
std::vector<double> slope_of(const std::vector<double>& t, const std::vector<double>& v, std::size_t half) {
  const std::size_t n = v.size();
  std::vector<double> d(n, 0.0);
  half = std::max<std::size_t>(1, half);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= half ? i - half : 0, hi = std::min(n - 1, i + half);
    if (hi > lo) d[i] = (v[hi] - v[lo]) / (t[hi] - t[lo]);
  }
  return d;
}

// Where a rise ends: the steepest sample of `rising` (slope in the stroke's direction) is searched in
// [from, to], then the walk goes on from it (forward up to `limit`, or backward down to it for the end of a
// slide) to the first sample whose slope is below `fraction` of the steepest.
std::size_t knee(const std::vector<double>& rising, std::size_t from, std::size_t to, std::size_t limit,
                 double fraction, bool forward) {
  std::size_t steepest = from;
  for (std::size_t i = from; i <= to; ++i)
    if (rising[i] > rising[steepest]) steepest = i;
  const double floor = fraction * rising[steepest];
  std::size_t i = steepest;
  if (forward)
    while (i < limit && rising[i] >= floor) ++i;
  else
    while (i > limit && rising[i] >= floor) --i;
  return i;
}

// One run's slide. The loading rise ends where μ's slope falls to a fraction of the rise's steepest slope
// (the Cattaneo–Mindlin curve meets μW with zero slope), the slide ends where the fall begins in the same
// way; a run that begins at loaded or ends at the release has no rise or fall of its own and keeps that end.
// A level-and-band test would cut a slide whose μ wanders; the slope of the slow wander stays far below
// that of the rise and the fall.
std::optional<Stroke> slide_of(const StrokeSearch& s, std::size_t a, std::size_t b, std::size_t lo,
                               std::size_t hi, const PhaseOptions& o, double dt) {
  const double sign = s.mu_smooth[(a + b) / 2] >= 0.0 ? 1.0 : -1.0;
  const std::size_t w = samples_in(o.knee_window_s, dt), n = s.t.size();
  std::vector<double> rising(s.slope.size()), falling(s.slope.size());
  for (std::size_t i = 0; i < rising.size(); ++i) {
    rising[i] = sign * s.slope[i];
    falling[i] = -rising[i];
  }
  // The rise and the fall are searched only where μ has the stroke's sign: a neighbouring stroke in the
  // other direction rises and falls too.
  std::size_t rise_from = a, fall_to = b;
  while (rise_from > lo && rise_from + w > a && sign * s.mu_smooth[rise_from - 1] > 0.0) --rise_from;
  while (fall_to + 1 < n && fall_to < b + w && sign * s.mu_smooth[fall_to + 1] > 0.0) ++fall_to;
  std::size_t first = a, last = b;
  if (a > lo) first = knee(rising, rise_from, std::min(b, a + w), b, o.knee_fraction, true);
  if (b + 1 < hi)
    last = knee(falling, std::max(first, b >= w ? b - w : 0), fall_to, first, o.knee_fraction, false);
  last = std::min(last, b);
  if (last <= first) return std::nullopt;
  Stroke k;
  k.slide_start_s = s.t[first];
  k.slide_end_s = s.t[last];
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t i = first; i <= last; ++i)
    if (s.valid[i]) {
      sum += s.mu[i];
      sum2 += s.mu[i] * s.mu[i];
      ++k.mu_samples;
    }
  if (k.mu_samples > 0) {
    const double m = static_cast<double>(k.mu_samples);
    k.mu_mean = sum / m;
    k.mu_sd =
        k.mu_samples > 1 ? std::sqrt(std::max(0.0, (sum2 - m * k.mu_mean * k.mu_mean) / (m - 1.0))) : 0.0;
  }
  if (s.position && (*s.position)[last] != (*s.position)[first]) {
    k.direction = (*s.position)[last] > (*s.position)[first] ? 1 : -1;
    k.direction_source = "position";
  } else {
    k.direction = sign > 0.0 ? 1 : -1;
    k.direction_source = "tangential";
  }
  return k;
}

void find_strokes(const std::vector<double>& t, const std::vector<double>* position, const PhaseOptions& o,
                  double dt, Phases& p) {
  const std::size_t n = t.size(), smooth = samples_in(o.smooth_s, dt);
  std::vector<double> mu(n, 0.0), mu_smooth(n, 0.0);
  std::vector<char> valid(n, 0);
  const auto w_smooth = moving_mean(p.normal_N, smooth), ft_smooth = moving_mean(p.tangential_N, smooth);
  for (std::size_t i = 0; i < n; ++i)
    if (p.normal_N[i] >= o.min_normal_N && w_smooth[i] >= o.min_normal_N) {
      valid[i] = 1;
      mu[i] = p.tangential_N[i] / p.normal_N[i];
      mu_smooth[i] = ft_smooth[i] / w_smooth[i];
    }
  const std::size_t lo = index_at_or_after(t, p.loaded_s),
                    hi = std::min(n, index_at_or_after(t, p.release_s) + 1);
  std::vector<double> magnitudes;
  for (std::size_t i = lo; i < hi; ++i)
    if (valid[i]) magnitudes.push_back(std::abs(mu_smooth[i]));
  if (magnitudes.empty()) {
    warn(p, "no_slide",
         "μ is undefined everywhere between loaded and release (W below " + fmt(o.min_normal_N) +
             " N): no stroke found");
    return;
  }
  std::sort(magnitudes.begin(), magnitudes.end());
  // The 98th percentile: a stroke that fills only a few percent of the contact still sets the level.
  const double typical =
      magnitudes[static_cast<std::size_t>(0.98 * static_cast<double>(magnitudes.size() - 1))];
  const double threshold = std::max(o.stroke_fraction * typical, o.min_stroke_mu);
  const auto slope = slope_of(t, mu_smooth, smooth / 2);
  const StrokeSearch s{t, mu, valid, mu_smooth, slope, position};
  for (const auto& [a, b] : stroke_runs(s, threshold, lo, hi, samples_in(o.min_stroke_s, dt)))
    if (auto k = slide_of(s, a, b, lo, hi, o, dt)) p.strokes.push_back(*k);
  if (p.strokes.empty())
    warn(p, "no_slide",
         "no stretch of at least " + fmt(o.min_stroke_s) + " s where |μ| exceeds " + fmt(threshold) + " (" +
             fmt(o.stroke_fraction) + " of its typical level " + fmt(typical) + ", at least " +
             fmt(o.min_stroke_mu) + ")");
}

}  // namespace

std::size_t index_at_or_after(const std::vector<double>& time_s, double t) {
  return static_cast<std::size_t>(std::lower_bound(time_s.begin(), time_s.end(), t) - time_s.begin());
}

std::vector<double> moving_mean(const std::vector<double>& v, std::size_t window) {
  const std::size_t n = v.size(), half = window / 2;
  std::vector<double> prefix(n + 1, 0.0), out(n);
  for (std::size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + v[i];
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= half ? i - half : 0, hi = std::min(n, i + half + 1);
    out[i] = (prefix[hi] - prefix[lo]) / static_cast<double>(hi - lo);
  }
  return out;
}

Phases detect_phases(const std::vector<double>& time_s, const std::vector<double>& normal_N,
                     const std::vector<double>& tangential_N, const std::vector<double>* position,
                     const PhaseOptions& options) {
  const std::size_t n = time_s.size();
  if (normal_N.size() != n || tangential_N.size() != n || (position && position->size() != n))
    throw Error("phases: the time, normal, tangential (and position) channels differ in length");
  if (n < 8 || time_s.back() - time_s.front() <= options.head_s)
    throw Error("phases: the record (" + std::to_string(n) +
                    " samples) is shorter than the head stretch of " + fmt(options.head_s) + " s",
                {.key = "head_s"});
  const double dt = (time_s.back() - time_s.front()) / static_cast<double>(n - 1);
  const std::size_t smooth = samples_in(options.smooth_s, dt);
  Phases p;
  p.record_start_s = time_s.front();
  p.record_end_s = time_s.back();
  const RoughContact rough = rough_contact(time_s, moving_mean(normal_N, smooth), normal_N, options);
  p.normal_sign = rough.sign;
  p.tare = tare_channels(time_s, normal_N, tangential_N, rough, options, p);
  p.normal_N = subtract(time_s, normal_N, p.tare.normal, p.tare.reference_s);
  p.tangential_N = subtract(time_s, tangential_N, p.tare.tangential, p.tare.reference_s);
  if (rough.contact_everywhere) {
    p.contact_start_s = p.loaded_s = time_s.front();
    p.release_s = p.contact_end_s = time_s.back();
    p.normal_level_N = median_of(p.normal_N);
    warn(p, "contact_from_record_start",
         "the normal force never leaves its level at the record start: the whole record is taken as contact");
  } else {
    locate_contact(time_s, moving_mean(p.normal_N, smooth), rough.sign, p);
  }
  if (rough.sign < 0)
    warn(p, "normal_force_negative",
         "the normal force is mostly negative (loaded level " + fmt(p.normal_level_N) +
             " N after the tare): set the channel's sign (invert) so that pressing is positive; μ is "
             "undefined "
             "where W < " +
             fmt(options.min_normal_N) + " N");
  find_strokes(time_s, position, options, dt, p);
  return p;
}

}  // namespace tirstrain::signals
