#pragma once
// Heat maps for people to look at: a scalar field on a regular grid drawn with a colour bar, title, unit,
// axis extent and optional circles (e.g. stick and contact radii). NaN cells are drawn grey ("no data").
#include <opencv2/core.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace tirstrain {

struct HeatmapCircle {
  double cx = 0.0, cy = 0.0, radius = 0.0;  // in data units (same as the extent)
  std::string label;
};

struct HeatmapOptions {
  std::string title;
  std::string unit;           // shown beside the colour bar
  bool diverging = true;      // blue-white-red, symmetric about zero; otherwise a sequential map
  std::optional<double> min;  // colour range; defaults from the data (range_percentile)
  std::optional<double> max;
  // Default range: this percentile of |value| (diverging, symmetric) or of value and its complement
  // (sequential); below 100 a few outliers saturate, marked "<" / ">" on the colour bar, instead of
  // washing out the rest.
  double range_percentile = 100.0;
  // Data extent of the grid: column 0 is at x_min, the last column at x_max; row 0 at y_min (drawn at top).
  double x_min = 0.0, x_max = 1.0, y_min = 0.0, y_max = 1.0;
  std::string axis_unit;                 // e.g. "mm"
  std::string axes = "x right, y down";  // which way the axes lie, written under the map
  std::vector<HeatmapCircle> circles;
  int pixels_per_cell = 0;  // 0: chosen so the map is about 480 px wide
};

// The colour scales (BGR): diverging blue-white-red with t in [0, 1] and 0.5 white; sequential viridis.
cv::Vec3b diverging_colour(double t);
cv::Vec3b sequential_colour(double t);

// sequential_colour for many values: the viridis table built once.
class SequentialColours {
 public:
  SequentialColours();
  cv::Vec3b operator()(double t) const;

 private:
  std::array<cv::Vec3b, 256> table_{};
};

// values: CV_64FC1, rows = y, cols = x. Returns a BGR 8-bit image.
cv::Mat render_heatmap(const cv::Mat& values, const HeatmapOptions& options);
// Renders and writes a PNG (temporary name, then rename); throws Error on failure.
void write_heatmap_png(const std::string& path, const cv::Mat& values, const HeatmapOptions& options);

}  // namespace tirstrain
