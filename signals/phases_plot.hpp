#pragma once
// A picture of a segmented recording for people to check the phases against: the tared normal force, the
// tared tangential force and μ over time, one panel each, with the phases shaded (approach and after
// contact grey, press blue, loading yellow, each slide green with its direction and mean μ, release red).
// Drawn with OpenCV, as the project's other PNG figures.
#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "signals/phases.hpp"

namespace tirstrain::signals {

struct PhasesPlotOptions {
  int width_px = 1200;        // whole image width
  int panel_height_px = 170;  // height of each of the three panels
  std::string title;          // drawn at the top (e.g. the input file)
};

// BGR colour of the shading of each phase, so tests and docs can name them.
cv::Scalar phase_colour(const std::string& phase);  // "approach", "press", "loading", "slide", "release"

// Panels' plot area in the image: x from time, for tests that look at the shading.
struct PhasesPlotLayout {
  int left = 0, right = 0;  // pixel columns of record start and record end
  std::vector<int> panel_top, panel_bottom;
};

cv::Mat render_phases_plot(const std::vector<double>& time_s, const Phases& phases,
                           const PhasesPlotOptions& options, PhasesPlotLayout* layout = nullptr);
// Renders and writes a PNG (temporary name, then rename); throws Error on failure.
void write_phases_png(const std::string& path, const std::vector<double>& time_s, const Phases& phases,
                      const PhasesPlotOptions& options);

}  // namespace tirstrain::signals
