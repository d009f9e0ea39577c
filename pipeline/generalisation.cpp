#include "pipeline/generalisation.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/error.hpp"
#include "core/scene.hpp"
#include "flow/tracker.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Windows with fewer samples per wavelength than this along x (grid steps) are not fitted: the sine and
// cosine then alias onto each other.
constexpr double kMinSamplesPerWavelength = 2.5;
constexpr int kMinWindowTracks = 6;

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

// How far from the frame's edges `tirstrain track --grid` seeds: a subset radius (or half the LK window)
// plus 2 px.
double grid_margin_px(const flow::TrackerOptions& s) {
  return s.refine ? s.main_match.subset_radius_px + 2.0 : s.prediction.window_px / 2.0;
}

std::vector<Vec2> grid_points(const flow::TrackerOptions& s, cv::Size size, double step_px) {
  const double margin = grid_margin_px(s);
  std::vector<Vec2> points;
  for (double y = margin; y <= size.height - 1 - margin; y += step_px)
    for (double x = margin; x <= size.width - 1 - margin; x += step_px) points.push_back({x, y});
  return points;
}

struct ErrorSums {
  double sum2 = 0.0, max = 0.0;
  Vec2 sum;
  int n = 0, over_1px = 0;
  void add(Vec2 e) {
    const double length = std::hypot(e.x, e.y);
    over_1px += length > 1.0 ? 1 : 0;
    sum2 += e.x * e.x + e.y * e.y;
    sum.x += e.x;
    sum.y += e.y;
    max = std::max(max, length);
    ++n;
  }
  double rms() const { return n ? std::sqrt(sum2 / n) : kNaN; }
};

struct RunSums {
  ErrorSums all, edge, interior;
};

double edge_distance_px(const samples::GeneralisationCase& sequence, Vec2 p) {
  return std::min({p.x, p.y, sequence.width() - 1.0 - p.x, sequence.height() - 1.0 - p.y});
}

// The frame's errors at every live track; fills `frame` and adds to the run's totals.
void measure_frame(const samples::GeneralisationCase& sequence, const flow::FeatureTracker& tracker,
                   int index, double edge_band_px, GeneralisationFrame& frame, RunSums& totals) {
  ErrorSums sums;
  for (const flow::Track& t : tracker.tracks()) {
    if (!flow::is_alive(t.status)) continue;
    const Vec2 u = sequence.field(t.reference_px, index).displacement_px;
    const Vec2 e{t.position_px.x - t.reference_px.x - u.x, t.position_px.y - t.reference_px.y - u.y};
    sums.add(e);
    totals.all.add(e);
    (edge_distance_px(sequence, t.reference_px) < edge_band_px ? totals.edge : totals.interior).add(e);
  }
  frame.frame = index;
  frame.alive = sums.n;
  frame.rms_px = sums.rms();
  frame.max_px = sums.n ? sums.max : kNaN;
  frame.bias_px = sums.n ? Vec2{sums.sum.x / sums.n, sums.sum.y / sums.n} : Vec2{kNaN, kNaN};
}

// The chirp's measures on the last frame: the windowed gain and the RMS over long wavelengths.
void measure_chirp(const samples::GeneralisationCase& sequence, const flow::FeatureTracker& tracker,
                   const GeneralisationOptions& options, GeneralisationResult& result) {
  const int last = sequence.frames() - 1;
  std::vector<Vec2> X;
  std::vector<double> u_x;
  ErrorSums long_waves;
  double long_u2 = 0.0;
  for (const flow::Track& t : tracker.tracks()) {
    if (!flow::is_alive(t.status)) continue;
    X.push_back(t.reference_px);
    u_x.push_back(t.position_px.x - t.reference_px.x);
    if (sequence.chirp_wavelength_px(t.reference_px.x) >= options.long_wave_radii * result.radius_px) {
      const Vec2 u = sequence.field(t.reference_px, last).displacement_px;
      long_waves.add({t.position_px.x - t.reference_px.x - u.x, t.position_px.y - t.reference_px.y - u.y});
      long_u2 += std::pow(t.position_px.x - t.reference_px.x - u.x, 2);
    }
  }
  result.chirp = chirp_resolution(sequence, X, u_x, options.min_gain);
  result.resolution_px = result.chirp.resolved_wavelength_px;
  result.resolution_radii = result.resolution_px / result.radius_px;
  result.long_wave_rms_px = long_waves.rms();
  result.long_wave_u_rms_px = long_waves.n ? std::sqrt(long_u2 / long_waves.n) : kNaN;
  if (!result.chirp.windows.empty()) {
    result.longest_wavelength_px = result.chirp.windows.front().wavelength_px;
    result.longest_gain = result.chirp.windows.front().gain;
  }
}

// In-phase and quadrature amplitude of u_x ~ a sin(phi) + b cos(phi) + c over the window's tracks.
bool fit_window(const samples::GeneralisationCase& sequence, const std::vector<Vec2>& X_px,
                const std::vector<double>& u_x_px, ChirpWindow& window) {
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  const double half = 0.5 * window.wavelength_px;
  window.tracks = 0;
  for (std::size_t i = 0; i < X_px.size(); ++i) {
    if (std::abs(X_px[i].x - window.centre_px) > half) continue;
    const double phase = sequence.chirp_phase_rad(X_px[i].x);
    const Eigen::Vector3d basis(std::sin(phase), std::cos(phase), 1.0);
    normal += basis * basis.transpose();
    rhs += basis * u_x_px[i];
    ++window.tracks;
  }
  if (window.tracks < kMinWindowTracks) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal);
  if (eigen.eigenvalues()(0) < 1e-3 * eigen.eigenvalues()(2)) return false;
  const Eigen::Vector3d coefficients = normal.ldlt().solve(rhs);
  const double amplitude = sequence.config().chirp_amplitude_px;
  window.gain = coefficients(0) / amplitude;
  window.quadrature = coefficients(1) / amplitude;
  return true;
}

}  // namespace

const std::vector<std::string>& generalisation_presets() {
  static const std::vector<std::string> names = {"auto",
                                                 "delhaye2016",
                                                 "auto_no_rest",
                                                 "auto_no_affine_fit",
                                                 "auto_no_local_fit",
                                                 "auto_own_matches",
                                                 "auto_low_snr",
                                                 "auto_joint_windows"};
  return names;
}

flow::TrackerOptions generalisation_settings(const std::string& preset) {
  const bool no_rest = preset == "auto_no_rest", no_local_fit = preset == "auto_no_local_fit",
             no_affine = preset == "auto_no_affine_fit", low_snr = preset == "auto_low_snr",
             own_matches = preset == "auto_own_matches", joint_windows = preset == "auto_joint_windows";
  const bool variant = no_rest || no_local_fit || no_affine || low_snr || own_matches || joint_windows;
  if (!variant && preset != "auto" && preset != "delhaye2016")
    throw Error(
        "unknown generalisation configuration '" + preset +
        "' (known: auto, delhaye2016, auto_no_rest, auto_no_affine_fit, auto_no_local_fit, auto_own_matches, "
        "auto_low_snr, auto_joint_windows)");
  flow::TrackerOptions settings = flow::parse_tracking_options(Scene{}, variant ? "auto" : preset);
  settings.births.enabled = false;
  if (no_rest) settings.rest.average_frames = 1;
  if (no_affine || own_matches) settings.affine_fit.enabled = false;
  if (no_local_fit || own_matches) settings.local_fit.enabled = false;
  if (joint_windows) settings.local_fit.per_component = false;
  // Ridged texture of any SNR takes the low-SNR path (docs/flow.md, "Frame 0").
  if (low_snr) settings.texture.min_quadratic_snr = 1e6;
  return settings;
}

ChirpResolution chirp_resolution(const samples::GeneralisationCase& sequence, const std::vector<Vec2>& X_px,
                                 const std::vector<double>& u_x_px, double min_gain) {
  ChirpResolution out;
  if (X_px.empty()) return out;
  double lo = X_px.front().x, hi = lo;
  for (const Vec2& p : X_px) {
    lo = std::min(lo, p.x);
    hi = std::max(hi, p.x);
  }
  // The smallest spacing of the points along x, to know which wavelengths they sample.
  std::vector<double> xs;
  for (const Vec2& p : X_px) xs.push_back(p.x);
  std::sort(xs.begin(), xs.end());
  xs.erase(std::unique(xs.begin(), xs.end(), [](double a, double b) { return b - a < 1e-6; }), xs.end());
  const double spacing_px = xs.size() > 1 ? (xs.back() - xs.front()) / (xs.size() - 1.0) : 1.0;
  // Windows one local wavelength wide, wholly inside the tracked span, a quarter wavelength apart.
  double next_px = lo;
  for (double centre = lo; centre <= hi; centre += 1.0) {
    const double wavelength = sequence.chirp_wavelength_px(centre);
    if (centre < next_px || centre - 0.5 * wavelength < lo || centre + 0.5 * wavelength > hi) continue;
    if (wavelength < kMinSamplesPerWavelength * spacing_px) break;
    ChirpWindow window{centre, wavelength};
    if (fit_window(sequence, X_px, u_x_px, window)) out.windows.push_back(window);
    next_px = centre + 0.25 * wavelength;
  }
  for (std::size_t i = 0; i < out.windows.size(); ++i) {
    if (out.windows[i].gain >= min_gain) continue;
    if (i == 0) return out;  // not even the longest wavelength is reproduced
    const ChirpWindow& a = out.windows[i - 1];
    const ChirpWindow& b = out.windows[i];
    const double t = (a.gain - min_gain) / (a.gain - b.gain);
    out.resolved_wavelength_px = a.wavelength_px + t * (b.wavelength_px - a.wavelength_px);
    return out;
  }
  // Every window passes: the shortest one measured bounds the resolution.
  if (!out.windows.empty()) out.resolved_wavelength_px = out.windows.back().wavelength_px;
  return out;
}

GeneralisationResult run_generalisation(const samples::GeneralisationCase& sequence,
                                        const std::vector<cv::Mat>& frames, const std::string& preset,
                                        const GeneralisationOptions& options) {
  const samples::GeneralisationConfig& config = sequence.config();
  GeneralisationResult result;
  result.field = samples::to_string(config.field);
  result.texture = samples::to_string(config.texture);
  result.preset = preset;
  result.noise_fraction = config.noise_fraction;
  result.width_px = sequence.width();
  result.height_px = sequence.height();
  result.frames = static_cast<int>(frames.size());

  flow::FeatureTracker tracker(generalisation_settings(preset));
  const std::vector<Vec2> points =
      grid_points(tracker.settings(), frames.front().size(), options.grid_step_px);
  result.seeded = static_cast<int>(points.size());
  tracker.start(frames.front(), cv::Mat(), 0.0, points);
  const flow::TrackerOptions& s = tracker.settings();
  result.radius_px = s.refine ? s.main_match.subset_radius_px : 0.5 * s.prediction.window_px;

  result.edge_band_px = grid_margin_px(s) + 1.5 * options.grid_step_px;
  RunSums totals;
  double alive_sum = 0.0, ms_sum = 0.0;
  for (std::size_t k = 1; k < frames.size(); ++k) {
    const int index = static_cast<int>(k);
    const Clock::time_point begin = Clock::now();
    const flow::FrameStats& stats = tracker.track(frames[k], cv::Mat(), 0.01 * index);
    GeneralisationFrame frame;
    frame.track_ms = elapsed_ms(begin);
    frame.at_rest = stats.at_rest;
    frame.affine_fit = stats.affine_fit;
    frame.affine_hidden_px = stats.affine_hidden_px;
    measure_frame(sequence, tracker, index, result.edge_band_px, frame, totals);
    alive_sum += frame.alive;
    ms_sum += frame.track_ms;
    result.rest_frames += frame.at_rest ? 1 : 0;
    result.affine_fit_frames += frame.affine_fit ? 1 : 0;
    if (frame.alive) {
      const double bias = std::hypot(frame.bias_px.x, frame.bias_px.y);
      result.bias_px = std::isnan(result.bias_px) ? bias : std::max(result.bias_px, bias);
    }
    result.per_frame.push_back(frame);
  }
  const double tracked_frames = static_cast<double>(frames.size() - 1);
  result.alive_mean = alive_sum / tracked_frames;
  result.ms_per_frame = ms_sum / tracked_frames;
  result.rms_px = totals.all.rms();
  result.edge_rms_px = totals.edge.rms();
  result.interior_rms_px = totals.interior.rms();
  result.max_px = totals.all.n ? totals.all.max : kNaN;
  result.over_1px = totals.all.over_1px;
  if (config.field == samples::GeneralisationField::kChirp) measure_chirp(sequence, tracker, options, result);
  return result;
}

std::vector<GeneralisationResult> run_generalisation_suite(
    const GeneralisationSuite& suite, const std::function<void(const GeneralisationResult&)>& on_result) {
  std::vector<GeneralisationResult> results;
  for (const samples::GeneralisationField field : suite.fields) {
    for (const samples::GeneralisationTexture texture : suite.textures) {
      // The clean frames do not depend on the noise: render them once per field and texture.
      std::vector<cv::Mat> clean;
      for (const double noise : suite.noise_fractions) {
        const samples::GeneralisationCase sequence(
            samples::generalisation_config(field, texture, noise, suite.small));
        if (clean.empty())
          for (int k = 0; k < sequence.frames(); ++k) clean.push_back(sequence.render_clean(k));
        std::vector<cv::Mat> frames;
        for (int k = 0; k < sequence.frames(); ++k)
          frames.push_back(sequence.add_noise(clean[static_cast<std::size_t>(k)], k));
        if (suite.on_sequence) suite.on_sequence(sequence, frames);
        for (const std::string& preset : suite.presets) {
          results.push_back(run_generalisation(sequence, frames, preset, suite.options));
          if (on_result) on_result(results.back());
        }
      }
    }
  }
  return results;
}

}  // namespace tirstrain::pipeline
