// The contact segmenter's ellipse-centre error next to what the frame allows at all: for each synthetic scene
// (and optionally other placements of the fingerprint under the same contact), the feasible range of the
// truth ellipse's centre given where ridges show (pipeline/contact_observability.hpp), and the segmenter's
// actual error on the same frame, with the time each took. Run: contact_observability_bench [--frame N]
// [--k-sigma K] [--core-offsets-mm "x,y x,y ..."] SCENE.yaml...
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

#include "contact/segmenter.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "pipeline/contact_observability.hpp"
#include "pipeline/contact_stage.hpp"
#include "samples/synth_config.hpp"

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

void usage(std::FILE* out) {
  std::fprintf(out,
               "usage: contact_observability_bench [--frame N] [--k-sigma K] [--core-offsets-mm \"x,y ...\"] "
               "SCENE.yaml...\n"
               "  For frame N (default 0) of each scene: the half-width of the feasible range of the truth "
               "ellipse's\n"
               "  centre (px) for an observer that sees where ridges show above K (default 2) noise sigmas, "
               "and the\n"
               "  contact segmenter's centre error (px) on the rendered frame. --core-offsets-mm repeats "
               "each scene with\n"
               "  the fingerprint's core at each offset from the contact centre (mm); \"scene\" keeps the "
               "scene's own.\n");
}

struct Row {
  std::string label;
  tirstrain::pipeline::CentreBound bound;
  double bound_ms = 0.0, segment_ms = 0.0, error_px = NAN;
};

Row measure(const tirstrain::Scene& scene, tirstrain::samples::SynthConfig config, int frame, double k_sigma,
            const std::string& label) {
  Row row;
  row.label = label;
  const tirstrain::samples::Trial trial(std::move(config));
  if (frame < 0 || frame >= trial.frames())
    throw tirstrain::Error("frame " + std::to_string(frame) + " is outside the trial's " +
                           std::to_string(trial.frames()) + " frames");
  tirstrain::pipeline::ObservabilityOptions options;
  options.k_sigma = k_sigma;
  auto start = Clock::now();
  row.bound = tirstrain::pipeline::contact_centre_bound(trial, frame, options);
  row.bound_ms = ms_since(start);
  const cv::Mat image = trial.apply_sensor(trial.render_clean(frame), frame);
  tirstrain::contact::ContactSegmenter segmenter(tirstrain::pipeline::segmenter_options_for(scene));
  start = Clock::now();
  const tirstrain::contact::ContactResult result = segmenter.segment(image);
  row.segment_ms = ms_since(start);
  const auto truth = tirstrain::pipeline::truth_contact_ellipse(trial.contact_mask());
  if (result.ellipse && truth)
    row.error_px = std::hypot(result.ellipse->cx_px - truth->cx_px, result.ellipse->cy_px - truth->cy_px);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int frame = 0;
  double k_sigma = 2.0;
  std::vector<std::string> offsets{"scene"}, scenes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--help" || arg == "-h") {
      usage(stdout);
      return 0;
    } else if (arg == "--frame" && has_value) {
      frame = std::atoi(argv[++i]);
    } else if (arg == "--k-sigma" && has_value) {
      k_sigma = std::atof(argv[++i]);
    } else if (arg == "--core-offsets-mm" && has_value) {
      std::istringstream list(argv[++i]);
      offsets.clear();
      for (std::string o; list >> o;) offsets.push_back(o);
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "unknown option or missing value: %s\n", arg.c_str());
      usage(stderr);
      return 2;
    } else {
      scenes.push_back(arg);
    }
  }
  if (scenes.empty() || offsets.empty() || !(k_sigma > 0.0)) {
    usage(stderr);
    return 2;
  }
  std::printf("%-28s %-12s %7s %7s %7s %11s %9s %9s %9s\n", "scene", "core_mm", "inside", "outside", "hidden",
              "bound_px", "error_px", "bound_ms", "segm_ms");
  try {
    for (const std::string& path : scenes) {
      const tirstrain::Scene scene = tirstrain::load_scene(path);
      for (const std::string& offset : offsets) {
        tirstrain::samples::SynthConfig config = tirstrain::samples::parse_synth_config(scene);
        if (offset != "scene") {
          double x = 0.0, y = 0.0;
          if (std::sscanf(offset.c_str(), "%lf,%lf", &x, &y) != 2)
            throw tirstrain::Error("--core-offsets-mm: \"" + offset + "\" is not x,y in mm");
          config.fingerprint.core_offset_mm = {x, y};
        }
        const std::string name = path.substr(path.find_last_of('/') + 1);
        const Row row = measure(scene, std::move(config), frame, k_sigma, name);
        std::printf("%-28s %-12s %7d %7d %7d %11.2f %9.2f %9.0f %9.1f\n", row.label.c_str(), offset.c_str(),
                    row.bound.inside_pixels, row.bound.outside_pixels, row.bound.hidden_pixels,
                    row.bound.half_range_px, row.error_px, row.bound_ms, row.segment_ms);
        std::fflush(stdout);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "contact_observability_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
