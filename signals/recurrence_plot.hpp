#pragma once
// The recurrence plot as a picture: cell (i, j) dark when states i and j recur, i to the right and j
// upwards, axes in the series' own unit. A matrix larger than the plot area is shown in square blocks, each
// as dark as the fraction of its cells that recur; an ensemble's summed matrix is shown the same way, each
// cell as the fraction of trials in which it recurs. Drawn with OpenCV, as the project's other figures.
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "signals/rqa.hpp"

namespace tirstrain::signals {

struct RecurrencePlotOptions {
  int max_side_px = 800;         // largest side of the plot area; larger matrices are shown in blocks
  double spacing = 1.0;          // index units per embedded point (s per sample, mm per sample, or 1)
  std::string axis_label = "i";  // axis title with its unit, e.g. "time, s"
  std::string title;             // drawn above the plot
};

struct RecurrencePlotLayout {
  int left = 0, top = 0, side = 0;  // plot area in the image, pixels
  std::size_t block = 1;            // matrix cells per pixel along each axis
};

cv::Mat render_recurrence_plot(const RecurrenceMatrix& r, const RecurrencePlotOptions& options,
                               RecurrencePlotLayout* layout = nullptr);
// counts: M×M, row-major, the number of trials in which each cell recurs (ensemble_sum).
cv::Mat render_ensemble_plot(const std::vector<std::uint16_t>& counts, std::size_t size, std::size_t trials,
                             const RecurrencePlotOptions& options, RecurrencePlotLayout* layout = nullptr);
// Written with core/png_file.hpp's write_png_file.

}  // namespace tirstrain::signals
