// Speed against error of the feature tracker on one synthetic Cattaneo–Mindlin trial (640×512, elliptical
// contact, pattern band on top, sensor noise): both presets and a sweep of LK window, pyramid levels, grid
// spacing and refinement subset, one table in one run. Frames are rendered before timing starts; the time
// is tracking only (pyramids, LK, refinement, checks, births, plate). Error is against the exact field.
//
//   flow_bench [--frames N] [--width W --height H | --scene FILE] [--only NAME] [--threads T]
//              [--yaml TRACKING]... [--mesh E,S,B,SIGMA,INSET,UPDATE,CONV]... [--crb] [--frame-times]
// --frame-times adds, per configuration, where the time goes across the trial: seeding (frame 0), frame 1,
// and the later frames' median and largest, in ms.
// --scene renders that scene's `synthesis:` section instead (e.g. samples/scenes/default.yaml).
// --yaml adds a configuration given as a scene `tracking:` section, e.g. --yaml "{subset_radius_px: 18}".
// --crb prints the Cramér–Rao bound of the automatic preset's subsets on this trial's frame 0 instead.
// --mesh E,S,B,SIGMA,INSET,UPDATE,CONV runs the global (mesh) correlation experiment instead (flow/
// mesh_correlation.hpp; not used by the tracker): element E px, smoothness S, brightness fields B (0/1),
// prefilter SIGMA px, region inset INSET px, full Gauss–Newton UPDATE (0/1), convergence CONV px; trailing
// fields may be left out. MESH_VERBOSE=1 prints each frame's error (all, and deeper than 26 px).
#include <yaml-cpp/yaml.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include "../tests/flow/flow_support.hpp"

#include "bench/studies/mesh_correlation.hpp"
#include "flow/settings.hpp"
#include "flow/subset.hpp"

namespace {

using tirstrain::flow::ShapeFunction;
using tirstrain::flow::TrackerOptions;

struct Config {
  std::string name;
  TrackerOptions settings;
};

YAML::Node bench_scene(int width, int height, int frames) {
  YAML::Node root = YAML::Load(R"(
calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
reference_pattern: {roi_px: [0, 0, 640, 48]}
synthesis:
  seed: 5
  image: {bit_depth: 8}
  timing: {frame_rate_hz: 50}
  contact: {shape: ellipse, normal_N: 2.0, semi_axes_mm: [4.2, 3.5], angle_deg: 10}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 15, plate_speed_mm_s: 1.0}
  fingerprint: {core_offset_mm: [0.3, -0.5]}
  sensor: {full_well_electrons: 20000, read_noise: 0.004, blur_sigma_px: 0.6}
  channels: {}
)");
  root["reference_pattern"]["roi_px"][2] = width;
  root["synthesis"]["image"]["width_px"] = width;
  root["synthesis"]["image"]["height_px"] = height;
  root["synthesis"]["timing"]["frames"] = frames;
  const double scale = std::min(width / 640.0, (height - 48) / 464.0);
  root["synthesis"]["contact"]["semi_axes_mm"][0] = 4.2 * scale;
  root["synthesis"]["contact"]["semi_axes_mm"][1] = 3.5 * scale;
  return root;
}

// Global (mesh) correlation of the frame-0 material against frame 0, frame after frame, each frame started
// from the last two frames' fields extrapolated; scored on a grid of reference points.
void run_mesh(const tirstrain::samples::Trial& trial, const tirstrain::flow::testing::RenderedTrial& rendered,
              const tirstrain::studies::MeshCorrelationOptions& options, double sigma_px, int inset_px,
              double grid_px) {
  using namespace tirstrain;
  const auto to_float = [&](const cv::Mat& m) {
    cv::Mat f;
    m.convertTo(f, CV_32F, m.depth() == CV_16U ? 1.0 / 65535.0 : 1.0 / 255.0);
    if (sigma_px > 0) cv::GaussianBlur(f, f, cv::Size(), sigma_px);
    return f;
  };
  cv::Mat region, current_mask;
  cv::erode(rendered.mask, region,
            cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * inset_px + 1, 2 * inset_px + 1)));
  flow::erode_for_matching(region, current_mask);
  cv::Mat depth;
  cv::distanceTransform(rendered.mask, depth, cv::DIST_L2, 3);
  const auto t0 = std::chrono::steady_clock::now();
  studies::MeshCorrelation mesh(to_float(rendered.frames[0]), region, options);
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::vector<Vec2> u(static_cast<std::size_t>(mesh.node_count())), last = u, before = u;
  std::vector<Vec2> points;
  for (double y = 0; y < region.rows; y += grid_px)
    for (double x = 0; x < region.cols; x += grid_px)
      if (region.at<std::uint8_t>(static_cast<int>(y), static_cast<int>(x))) points.push_back({x, y});
  double sum2 = 0.0, max_e = 0.0;
  long scored = 0, iterations = 0, wrong = 0;
  for (int f = 1; f < trial.frames(); ++f) {
    const cv::Mat current = to_float(rendered.frames[static_cast<std::size_t>(f)]);
    const auto t1 = std::chrono::steady_clock::now();
    for (std::size_t n = 0; n < u.size(); ++n)
      u[n] = {2.0 * last[n].x - before[n].x, 2.0 * last[n].y - before[n].y};
    const studies::MeshCorrelationResult r = mesh.solve(current, current_mask, u);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    iterations += r.iterations;
    const bool verbose = std::getenv("MESH_VERBOSE") != nullptr;
    double frame2 = 0.0, inner2 = 0.0;
    long frame_n = 0, inner_n = 0;
    before = last;
    last = u;
    const samples::FrameField field = trial.field(f);
    for (const Vec2& X : points) {
      Vec2 d;
      if (!mesh.displacement_at(u, X, d)) continue;
      const int cx = static_cast<int>(X.x + d.x + 0.5), cy = static_cast<int>(X.y + d.y + 0.5);
      if (cx < 0 || cy < 0 || cx >= region.cols || cy >= region.rows || !region.at<std::uint8_t>(cy, cx))
        continue;
      const Vec2 t = field.displacement_px(X);
      const double e = std::hypot(d.x - t.x, d.y - t.y);
      sum2 += e * e;
      max_e = std::max(max_e, e);
      if (e > 1.0) ++wrong;
      ++scored;
      frame2 += e * e;
      ++frame_n;
      if (depth.at<float>(static_cast<int>(X.y), static_cast<int>(X.x)) > 26.0f) {
        inner2 += e * e;
        ++inner_n;
      }
    }
    if (verbose)
      std::fprintf(stderr,
                   "frame %d: %d iterations (%s), %d refactorisations, residual %.4f, %d px, rms %.4f, >26px "
                   "deep %.4f\n",
                   f, r.iterations, r.converged ? "converged" : "not converged", r.refactorisations,
                   r.rms_residual, r.pixels_used, std::sqrt(frame2 / std::max(1L, frame_n)),
                   std::sqrt(inner2 / std::max(1L, inner_n)));
  }
  std::printf("%-24s %7s %8s %10s %8s %9s %9s %7s\n", "mesh config", "points", "scored", "points/s",
              "frames/s", "rms_px", "max_px", ">1px");
  std::printf("mesh h=%d s=%.3g b=%d  %7zu %8ld %10.0f %8.2f %9.4f %9.3f %7ld  iter %.1f nodes %d\n",
              options.element_px, options.smoothness, options.brightness ? 1 : 0, points.size(),
              scored / (trial.frames() - 1), scored / seconds, (trial.frames() - 1) / seconds,
              std::sqrt(sum2 / std::max(1L, scored)), max_e, wrong,
              static_cast<double>(iterations) / (trial.frames() - 1), mesh.node_count());
  std::fflush(stdout);
}

// Cramér–Rao bound of a translation-only match (shape known) on frame 0's noise-free image, with the
// sensor's exact per-pixel noise (shot, read, 8/16-bit quantisation) in the current frame and 1/averaged of
// it in the anchor: the smallest displacement noise any unbiased estimator from those pixels can reach. Per
// seed on the tracker's grid, square subsets of the given radius restricted to the contact eroded by
// `exclusion_px` (what the tracker's subsets may use), RMS by depth inside the true border.
void run_crb(const tirstrain::samples::Trial& trial, double grid_px, double exclusion_px,
             const std::vector<int>& radii, int anchor_frames_averaged) {
  using namespace tirstrain;
  const samples::SensorConfig& sensor = trial.config().sensor;
  cv::Mat f = trial.render_clean(0);
  if (sensor.blur_sigma_px > 0)
    cv::GaussianBlur(f, f, cv::Size(0, 0), sensor.blur_sigma_px, sensor.blur_sigma_px, cv::BORDER_REFLECT);
  f *= sensor.gain;
  const double full_scale = trial.config().image.bit_depth == 16 ? 65535.0 : 255.0;
  cv::Mat gx, gy;
  cv::Sobel(f, gx, CV_32F, 1, 0, 1, 0.5);  // central differences
  cv::Sobel(f, gy, CV_32F, 0, 1, 1, 0.5);
  const auto variance = [&](double v) {
    double var = 1.0 / (12.0 * full_scale * full_scale);
    if (sensor.full_well_electrons > 0) var += std::max(0.0, v) / sensor.full_well_electrons;
    return var + sensor.read_noise * sensor.read_noise;
  };
  const double both = 1.0 + 1.0 / std::max(1, anchor_frames_averaged);
  std::printf(
      "Cramér–Rao bound, translation with known shape, frame 0, exclusion %.0f px, anchor averaged over %d\n",
      exclusion_px, anchor_frames_averaged);
  std::printf("%8s %12s %8s %10s %10s %10s\n", "radius", "depth_px", "seeds", "total_px", "along_px",
              "across_px");
  const double bins[4] = {13.0, 26.0, 52.0, 1e9};
  for (int r : radii) {
    double sum_t[3] = {}, sum_a[3] = {}, sum_c[3] = {};
    int count[3] = {};
    for (double y = 0; y < trial.height(); y += grid_px)
      for (double x = 0; x < trial.width(); x += grid_px) {
        const double depth = -trial.contact_signed_distance_px({x, y});
        if (depth < bins[0]) continue;
        int b = 0;
        while (depth >= bins[b + 1]) ++b;
        Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            const int px = static_cast<int>(x) + dx, py = static_cast<int>(y) + dy;
            if (px < 1 || py < 1 || px >= trial.width() - 1 || py >= trial.height() - 1) continue;
            if (-trial.contact_signed_distance_px({double(px), double(py)}) < exclusion_px) continue;
            const double ax = gx.at<float>(py, px), ay = gy.at<float>(py, px);
            const double w = 1.0 / (both * variance(f.at<float>(py, px)));
            info(0, 0) += w * ax * ax;
            info(0, 1) += w * ax * ay;
            info(1, 1) += w * ay * ay;
          }
        info(1, 0) = info(0, 1);
        if (info.determinant() <= 0) continue;
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(info.inverse());
        sum_a[b] += eig.eigenvalues()(1);
        sum_c[b] += eig.eigenvalues()(0);
        sum_t[b] += eig.eigenvalues().sum();
        ++count[b];
      }
    const char* names[3] = {"13-26", "26-52", ">52"};
    for (int b = 0; b < 3; ++b)
      std::printf("%8d %12s %8d %10.4f %10.4f %10.4f\n", r, names[b], count[b],
                  std::sqrt(sum_t[b] / std::max(1, count[b])), std::sqrt(sum_a[b] / std::max(1, count[b])),
                  std::sqrt(sum_c[b] / std::max(1, count[b])));
    const int all = count[0] + count[1] + count[2];
    std::printf("%8d %12s %8d %10.4f %10.4f %10.4f\n", r, "all >=13", all,
                std::sqrt((sum_t[0] + sum_t[1] + sum_t[2]) / std::max(1, all)),
                std::sqrt((sum_a[0] + sum_a[1] + sum_a[2]) / std::max(1, all)),
                std::sqrt((sum_c[0] + sum_c[1] + sum_c[2]) / std::max(1, all)));
  }
}

// Seeding and frame 1 pay for first-touch memory (subsets, anchor, field operators, second pyramid) that the
// later frames reuse; the steady state is what a long trial converges to.
void print_frame_times(const std::vector<double>& frame_seconds) {
  std::vector<double> later(frame_seconds.begin() + 2, frame_seconds.end());
  std::sort(later.begin(), later.end());
  std::printf("  ms: seeding %.1f, frame 1 %.1f, frames 2-%zu median %.1f max %.1f\n", 1e3 * frame_seconds[0],
              1e3 * frame_seconds[1], frame_seconds.size() - 1, 1e3 * later[later.size() / 2],
              1e3 * later.back());
}

// The command line.
struct Args {
  int frames = 30, width = 640, height = 512, threads = -1;
  bool frames_given = false;
  std::string only, scene_file;
  std::vector<std::string> custom;        // extra configurations: a scene `tracking:` section each
  bool frame_times = false;               // print the per-frame time breakdown under each row
  bool crb = false;                       // print the Cramér–Rao bound of the tracker's subsets instead
  std::vector<std::string> mesh_configs;  // "element_px,smoothness,brightness,sigma_px,inset_px"
};

void usage_and_exit() {
  std::fprintf(stderr,
               "usage: flow_bench [--frames N] [--width W --height H | --scene FILE] [--only NAME] "
               "[--threads T] [--yaml TRACKING]... [--mesh E,S,B,SIGMA,INSET,UPDATE,CONV]... [--crb] "
               "[--frame-times]\n");
  std::exit(2);
}

Args parse_args(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&] {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "flow_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::string(argv[++i]);
    };
    if (a == "--frames") {
      args.frames = std::stoi(next());
      args.frames_given = true;
    } else if (a == "--width")
      args.width = std::stoi(next());
    else if (a == "--height")
      args.height = std::stoi(next());
    else if (a == "--only")
      args.only = next();
    else if (a == "--threads")
      args.threads = std::stoi(next());
    else if (a == "--yaml")
      args.custom.push_back(next());
    else if (a == "--scene")
      args.scene_file = next();
    else if (a == "--crb")
      args.crb = true;
    else if (a == "--frame-times")
      args.frame_times = true;
    else if (a == "--mesh")
      args.mesh_configs.push_back(next());
    else
      usage_and_exit();
  }
  return args;
}

void run_mesh_configs(const std::vector<std::string>& mesh_configs, const tirstrain::samples::Trial& trial,
                      const tirstrain::flow::testing::RenderedTrial& rendered) {
  for (const std::string& m : mesh_configs) {
    tirstrain::studies::MeshCorrelationOptions o;
    int brightness = 1, inset = 3, update = 0;
    double sigma = 1.0;
    std::sscanf(m.c_str(), "%d,%lf,%d,%lf,%d,%d,%lf", &o.element_px, &o.smoothness, &brightness, &sigma,
                &inset, &update, &o.convergence_px);
    o.update_gradient = update != 0;
    o.brightness = brightness != 0;
    run_mesh(trial, rendered, o, sigma, inset, 9.0);
  }
}

// The configurations compared by default: the paper's preset, the automatic one, and one change at a time.
std::vector<Config> standard_configs(const TrackerOptions& automatic, const TrackerOptions& paper) {
  std::vector<Config> configs = {{"delhaye2016", paper}, {"auto", automatic}};
  const auto variant = [&](const std::string& name, auto change) {
    TrackerOptions s = automatic;
    change(s);
    configs.push_back({name, s});
  };
  // The paper's method with drift control, and the paper's window with our refinement.
  {
    TrackerOptions s = paper;
    s.reanchor.interval_frames = 5;
    configs.push_back({"delhaye2016+reanchor5", s});
  }
  for (int w : {11, 41})
    variant("auto window=" + std::to_string(w), [w](TrackerOptions& s) { s.prediction.window_px = w; });
  for (int l : {0, 1, 3})
    variant("auto levels=" + std::to_string(l), [l](TrackerOptions& s) { s.prediction.pyramid_levels = l; });
  for (double g : {6.0, 12.0})
    variant("auto grid=" + std::to_string(static_cast<int>(g)),
            [g](TrackerOptions& s) { s.seeding.grid_step_px = g; });
  for (int r : {8, 18})
    variant("auto subset_r=" + std::to_string(r),
            [r](TrackerOptions& s) { s.main_match.subset_radius_px = r; });
  variant("auto stride=1", [](TrackerOptions& s) {
    s.main_match.subset_stride = 1;
    s.pinned.subset_stride = true;
  });
  variant("auto quadratic", [](TrackerOptions& s) {
    s.main_match.shape = ShapeFunction::kQuadratic;
    s.pinned.shape = true;
  });
  for (int r : {2, 4})
    variant("auto rounds=" + std::to_string(r), [r](TrackerOptions& s) { s.rounds.resampled_rounds = r; });
  variant("auto no-fixed-shape", [](TrackerOptions& s) { s.rounds.enabled = false; });
  // The automatic preset with the rounds subset by subset and a second-order main match on every pixel,
  // for their cost and accuracy against the resampled rounds.
  variant("auto subset-by-subset", [](TrackerOptions& s) {
    s.rounds.resampled = false;
    s.main_match.shape = ShapeFunction::kQuadratic;
    s.main_match.subset_stride = 1;
    s.pinned.shape = s.pinned.subset_stride = true;
  });
  variant("auto no-refine", [](TrackerOptions& s) {
    s.refine = false;
    s.neighbours.enabled = false;
  });
  return configs;
}

// Given extra configurations, only those run (and the one named by --only).
void use_custom_configs(const Args& args, const tirstrain::Scene& scene, std::vector<Config>& configs) {
  if (!args.custom.empty()) std::erase_if(configs, [&](const Config& c) { return c.name != args.only; });
  for (const std::string& y : args.custom) {
    tirstrain::Scene with_tracking = scene;
    with_tracking.tracking = tirstrain::SceneSection::parse(y, "--config");
    configs.push_back({y, tirstrain::flow::parse_tracking_options(with_tracking)});
  }
}

// One row per configuration: speed next to error. matched: the share of track-frames that took LK and the
// main match (main_match_period_frames).
void print_table(const Args& args, const std::vector<Config>& configs, const tirstrain::samples::Trial& trial,
                 const tirstrain::flow::testing::RenderedTrial& rendered) {
  std::printf("%-24s %7s %8s %10s %8s %9s %9s %7s %7s %8s %7s\n", "config", "tracks", "alive_end", "points/s",
              "frames/s", "rms_px", "max_px", ">1px", "born", "plate_px", "matched");
  for (const Config& c : configs) {
    if (args.custom.empty() && !args.only.empty() && c.name != args.only) continue;
    const tirstrain::flow::testing::Score s =
        tirstrain::flow::testing::run_and_score(trial, rendered, c.settings, true);
    long tracked = 0;
    for (std::size_t f = 1; f < s.frame_alive.size(); ++f) tracked += s.frame_alive[f];
    const double fps = (trial.frames() - 1) / s.seconds;  // frame 0 (seeding) is included in the time
    const double matched = s.entering > 0 ? static_cast<double>(s.main_matched) / s.entering : 0.0;
    std::printf("%-24s %7d %8d %10.0f %8.2f %9.4f %9.3f %7ld %7d %8.4f %7.2f\n", c.name.c_str(),
                s.tracks_started, s.frame_alive.back(), tracked / s.seconds, fps, s.rms_px, s.max_px, s.wrong,
                s.born, s.plate_rms_px, matched);
    if (args.frame_times && s.frame_seconds.size() > 2) print_frame_times(s.frame_seconds);
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tirstrain;
  const Args args = parse_args(argc, argv);
  if (args.threads >= 0) cv::setNumThreads(args.threads);
  const Scene scene =
      args.scene_file.empty()
          ? parse_scene_text(YAML::Dump(bench_scene(args.width, args.height, args.frames)), "flow-bench.yaml")
          : load_scene(args.scene_file);
  samples::SynthConfig config = samples::parse_synth_config(scene);
  if (args.frames_given) config.timing.frames = args.frames;
  const samples::Trial trial(config);
  std::fprintf(stderr, "rendering %d frames of %dx%d...\n", trial.frames(), trial.width(), trial.height());
  const flow::testing::RenderedTrial rendered = flow::testing::render(trial, true);
  if (std::getenv("FLOW_BENCH_DUMP")) cv::imwrite(std::getenv("FLOW_BENCH_DUMP"), rendered.frames.back());
  const flow::SceneHints hints = flow::hints_from_scene(scene);
  const TrackerOptions automatic = flow::preset_options("auto", hints);
  if (args.crb) {
    run_crb(trial, automatic.seeding.grid_step_px, automatic.border.exclusion_px + 2.0,
            {automatic.main_match.subset_radius_px, automatic.rounds.subset_radius_px, 30},
            automatic.rest.average_frames);
    run_crb(trial, automatic.seeding.grid_step_px, 0.0, {automatic.rounds.subset_radius_px},
            automatic.rest.average_frames);
    return 0;
  }
  run_mesh_configs(args.mesh_configs, trial, rendered);
  if (!args.mesh_configs.empty() && args.only.empty()) return 0;
  std::vector<Config> configs = standard_configs(automatic, flow::preset_options("delhaye2016", hints));
  use_custom_configs(args, scene, configs);
  print_table(args, configs, trial, rendered);
  return 0;
}
