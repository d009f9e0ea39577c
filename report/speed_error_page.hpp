#pragma once
// The benchmark's speed-against-error plot as a self-contained HTML page (`tirstrain bench` writes it as
// OUT/bench.html): one panel per scene, log axes, the Pareto front (no other configuration both faster and
// more accurate) drawn as a line.
#include <string>
#include <vector>

namespace tirstrain::report {

struct SpeedErrorPoint {
  std::string scene;        // the panel it belongs to
  std::string config;       // the configuration's name
  double frames_per_s = 0;  // end-to-end speed
  double strain_rms = 0;    // strain error against the truth (dimensionless)
};

// The page's HTML; points whose speed or error is not finite and positive are left out (a log axis has no
// place for them) and counted in the caption.
std::string speed_error_page(const std::vector<SpeedErrorPoint>& points, const std::string& caption_note);

}  // namespace tirstrain::report
