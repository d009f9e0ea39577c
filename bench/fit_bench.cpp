// Accuracy and speed of `tirstrain fit` on a synthesised Cattaneo–Mindlin trial processed by `tirstrain
// process`: the fitted c, Q and direction against the generator's truth, and frames fitted per second.
//   fit_bench TRIAL_DIR RESULT_DIR [--threads N] [--frames]
// TRIAL_DIR holds truth.h5 (tirstrain synth); RESULT_DIR result.h5 (tirstrain process with tracking).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <numbers>
#include <string>
#include <vector>

#include "core/h5_file.hpp"
#include "fit/fit_result.hpp"

namespace {

using tirstrain::fit::FieldModel;
using tirstrain::fit::FitStatus;
using tirstrain::fit::FrameFit;

struct Truth {
  std::vector<double> q_N, p_N, c_m;
  double mu = 0.0, direction_deg = 0.0, a_m = 0.0;
};

Truth read_truth(const std::string& trial) {
  const tirstrain::H5Reader h5(trial + "/truth.h5");
  Truth t;
  t.q_N = h5.read_doubles("/load/tangential_N");
  t.p_N = h5.read_doubles("/load/normal_N");
  t.c_m = h5.read_doubles("/load/stick_radius_m");
  t.mu = h5.attribute_number("/", "friction");
  t.direction_deg = h5.attribute_number("/", "direction_rad") * 180.0 / std::numbers::pi;
  t.a_m = h5.attribute_number("/", "contact_radius_m");
  return t;
}

bool fitted(const FrameFit& f) {
  return f.status == FitStatus::ok || f.status == FitStatus::no_covariance;
}

struct Errors {
  double c_sum2 = 0.0, q_sum2 = 0.0, dir_max = 0.0, rest_max = 0.0;
  int loaded = 0, loaded_unfitted = 0, rest = 0;
  int models[tirstrain::fit::kFieldModels] = {};
};

void add_loaded(Errors& e, const FrameFit& f, const Truth& t, std::size_t i, double limit) {
  if (!fitted(f)) {
    ++e.loaded_unfitted;
    return;
  }
  ++e.loaded;
  const double a_mm = t.a_m * 1e3;
  const double c_fit = f.model == FieldModel::rest ? a_mm : f.c_mm.value;
  e.c_sum2 += std::pow((c_fit - t.c_m[i] * 1e3) / a_mm, 2);
  e.q_sum2 += std::pow((f.tangential_N.value - t.q_N[i]) / limit, 2);
  if (f.model != FieldModel::rest)
    e.dir_max = std::max(e.dir_max, std::abs(std::remainder(f.direction_deg.value - t.direction_deg, 360.0)));
}

Errors compare(const std::vector<FrameFit>& fits, const Truth& t) {
  Errors e;
  for (std::size_t i = 0; i < fits.size() && i < t.q_N.size(); ++i) {
    const FrameFit& f = fits[i];
    if (fitted(f)) ++e.models[static_cast<int>(f.model)];
    const double limit = t.mu * t.p_N[i];
    const double ratio = t.q_N[i] / limit;
    if (ratio > 0.2 && ratio < 0.95) add_loaded(e, f, t, i, limit);
    if (t.q_N[i] == 0.0 && fitted(f)) {
      ++e.rest;
      e.rest_max = std::max(e.rest_max, std::abs(f.tangential_N.value) / limit);
    }
  }
  return e;
}

// One line per frame: the truth next to the fit, in units of a and μP.
void print_frames(const std::vector<FrameFit>& fits, const Truth& t) {
  const double a_mm = t.a_m * 1e3;
  for (std::size_t i = 0; i < fits.size() && i < t.q_N.size(); ++i) {
    const FrameFit& f = fits[i];
    const double limit = t.mu * t.p_N[i];
    std::printf(
        "%3zu %-12s Q/muP %.3f fit %.3f  c/a %.3f fit %.3f  a %.3f  muP_fit/muP %.3f  dir %.2f  rms %.3f%s\n",
        i, fitted(f) ? tirstrain::fit::field_model_name(f.model) : tirstrain::fit::fit_status_name(f.status),
        t.q_N[i] / limit, f.tangential_N.value / limit, t.c_m[i] * 1e3 / a_mm, f.c_mm.value / a_mm,
        f.a_mm.value / a_mm, f.limit_N.value / limit, f.direction_deg.value, f.residual_rms_px,
        f.limit_from_trial ? "  (trial's muP)" : "");
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: fit_bench TRIAL_DIR RESULT_DIR [--threads N] [--frames] [--frame-limit]\n");
    return 2;
  }
  try {
    tirstrain::fit::RunOptions options;
    bool verbose = false;
    for (int i = 3; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--threads" && i + 1 < argc) options.frame_threads = std::stoi(argv[++i]);
      if (arg == "--frames") verbose = true;
      if (arg == "--frame-limit") options.trial_limit = false;
    }
    const Truth truth = read_truth(argv[1]);
    const tirstrain::fit::ResultForFit result = tirstrain::fit::read_result_for_fit(argv[2]);
    const auto start = std::chrono::steady_clock::now();
    const tirstrain::fit::FitRun run = tirstrain::fit::fit_result(result, options);
    const std::vector<FrameFit>& fits = run.frames;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    double tracks = 0.0;
    int fitted_frames = 0;
    for (const FrameFit& f : fits)
      if (fitted(f)) {
        tracks += f.tracks_used;
        ++fitted_frames;
      }
    const Errors e = compare(fits, truth);
    std::printf("frames %zu fitted %d tracks_mean %.0f threads %d frames_per_s %.1f\n", fits.size(),
                fitted_frames, fitted_frames ? tracks / fitted_frames : 0.0, options.frame_threads,
                static_cast<double>(fits.size()) / s);
    std::printf("models rest %d full_stick %d partial_slip %d full_slip %d\n", e.models[0], e.models[1],
                e.models[2], e.models[3]);
    std::printf(
        "0.2<Q/muP<0.95: frames %d (unfitted %d) c_rms_of_a %.4f Q_rms_of_muP %.4f direction_max_deg %.2f\n",
        e.loaded, e.loaded_unfitted, e.loaded ? std::sqrt(e.c_sum2 / e.loaded) : NAN,
        e.loaded ? std::sqrt(e.q_sum2 / e.loaded) : NAN, e.dir_max);
    std::printf("rest frames %d max |Q_fit|/muP %.4f\n", e.rest, e.rest_max);
    int from_trial = 0;
    for (const FrameFit& f : fits) from_trial += f.limit_from_trial ? 1 : 0;
    if (run.trial_limit)
      std::printf("trial limit %.5f N (sd %.5f, %d frames; true muP at frame 0 %.5f), held in %d frames\n",
                  run.trial_limit->limit_N, run.trial_limit->sd_N, run.trial_limit->frames,
                  truth.mu * (truth.p_N.empty() ? NAN : truth.p_N[0]), from_trial);
    else
      std::printf("trial limit: none\n");
    if (verbose) print_frames(fits, truth);
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "fit_bench: %s\n", ex.what());
    return 1;
  }
  return 0;
}
