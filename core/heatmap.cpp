#include "core/heatmap.hpp"
#include "core/png_file.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "core/error.hpp"

namespace tirstrain {

cv::Vec3b diverging_colour(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double s = std::abs(2.0 * t - 1.0);
  const double fade = 1.0 - s;
  if (t < 0.5) return {255, static_cast<uchar>(255 * fade + 40 * s), static_cast<uchar>(255 * fade + 20 * s)};
  return {static_cast<uchar>(255 * fade + 20 * s), static_cast<uchar>(255 * fade + 30 * s), 255};
}

SequentialColours::SequentialColours() {
  cv::Mat1b ramp(1, 256);
  for (int i = 0; i < 256; ++i) ramp(0, i) = static_cast<uchar>(i);
  cv::Mat out;
  cv::applyColorMap(ramp, out, cv::COLORMAP_VIRIDIS);
  for (int i = 0; i < 256; ++i) table_[static_cast<std::size_t>(i)] = out.at<cv::Vec3b>(0, i);
}

cv::Vec3b SequentialColours::operator()(double t) const {
  return table_[static_cast<uchar>(std::clamp(t, 0.0, 1.0) * 255.0)];
}

cv::Vec3b sequential_colour(double t) {
  return SequentialColours()(t);
}

namespace {

std::string tick_text(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3g", v);
  return buffer;
}

constexpr double kFont = 0.5;        // Hershey scale of labels and ticks: legible at 100 % on a 480 px map
constexpr double kTitleFont = 0.65;  // the title's

// The colour range: the options' bounds where given; otherwise the `range_percentile` of the finite values
// (of |v| for a diverging map, symmetric about zero), so a few outliers saturate instead of washing out the
// rest. `clamped` tells whether any value lies beyond the range.
struct ColourRange {
  double lo = 0.0, hi = 1.0;
  bool clamped_low = false, clamped_high = false;
};

double percentile(std::vector<double> v, double p) {
  const auto k = static_cast<std::size_t>(std::lround(p / 100.0 * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

ColourRange colour_range(const cv::Mat& values, const HeatmapOptions& options) {
  std::vector<double> finite, magnitude;
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c)
      if (const double v = values.at<double>(r, c); std::isfinite(v)) {
        finite.push_back(v);
        magnitude.push_back(std::abs(v));
      }
  ColourRange range;
  if (!finite.empty() && options.diverging) {
    range.hi = percentile(magnitude, options.range_percentile);
    range.lo = -range.hi;
  } else if (!finite.empty()) {
    range.lo = percentile(finite, 100.0 - options.range_percentile);
    range.hi = percentile(finite, options.range_percentile);
  }
  if (options.min) range.lo = *options.min;
  if (options.max) range.hi = *options.max;
  if (!(range.hi > range.lo)) range.hi = range.lo + (range.lo == 0.0 ? 1.0 : std::abs(range.lo) * 1e-6);
  for (double v : finite) {
    range.clamped_low = range.clamped_low || v < range.lo;
    range.clamped_high = range.clamped_high || v > range.hi;
  }
  return range;
}

void put(cv::Mat& canvas, const std::string& text, cv::Point at, double font = kFont) {
  cv::putText(canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

int text_width(const std::string& text, double font = kFont) {
  int baseline = 0;
  return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, font, 1, &baseline).width;
}

struct Layout {
  int cell = 1, map_w = 0, map_h = 0;
  int margin_left = 70, margin_top = 58, margin_bottom = 50;
  int bar_x = 0, bar_w = 20, labels_w = 90;
};

Layout layout_of(const cv::Mat& values, const HeatmapOptions& options) {
  Layout l;
  l.cell = options.pixels_per_cell > 0 ? options.pixels_per_cell
                                       : std::max(1, 480 / std::max(values.cols, values.rows));
  l.map_w = values.cols * l.cell;
  l.map_h = values.rows * l.cell;
  l.bar_x = l.margin_left + l.map_w + 20;
  // Room for the unit above the bar and the tick labels beside it.
  l.labels_w = std::max(90, text_width(options.unit) - l.bar_w + 10);
  return l;
}

void draw_cells(cv::Mat& canvas, const cv::Mat& values, const Layout& l,
                const std::function<cv::Vec3b(double)>& colour_of) {
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const double v = values.at<double>(r, c);
      const cv::Vec3b colour = std::isfinite(v) ? colour_of(v) : cv::Vec3b(200, 200, 200);
      cv::rectangle(canvas, cv::Rect(l.margin_left + c * l.cell, l.margin_top + r * l.cell, l.cell, l.cell),
                    cv::Scalar(colour[0], colour[1], colour[2]), cv::FILLED);
    }
}

void draw_circles(cv::Mat& canvas, const cv::Mat& values, const Layout& l, const HeatmapOptions& options) {
  const auto to_px = [&](double x, double y) {
    const double fx = (x - options.x_min) / (options.x_max - options.x_min);
    const double fy = (y - options.y_min) / (options.y_max - options.y_min);
    return cv::Point2d(l.margin_left + (fx * (values.cols - 1) + 0.5) * l.cell,
                       l.margin_top + (fy * (values.rows - 1) + 0.5) * l.cell);
  };
  const double px_per_unit = (values.cols - 1) * l.cell / (options.x_max - options.x_min);
  for (const auto& circle : options.circles) {
    const cv::Point2d centre = to_px(circle.cx, circle.cy);
    const int radius = static_cast<int>(std::lround(circle.radius * px_per_unit));
    cv::circle(canvas, centre, radius, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (!circle.label.empty())
      put(canvas, circle.label, centre + cv::Point2d(radius * 0.71 + 3, -radius * 0.71 - 3));
  }
}

void draw_axes(cv::Mat& canvas, const Layout& l, const HeatmapOptions& options) {
  cv::rectangle(canvas, cv::Rect(l.margin_left, l.margin_top, l.map_w, l.map_h), cv::Scalar(0, 0, 0), 1);
  put(canvas, options.title, cv::Point(l.margin_left, 26), kTitleFont);
  const std::string unit = options.axis_unit.empty() ? "" : " " + options.axis_unit;
  const int below = l.margin_top + l.map_h + 20;
  put(canvas, tick_text(options.x_min) + unit, cv::Point(l.margin_left, below));
  const std::string right = tick_text(options.x_max) + unit;
  put(canvas, right, cv::Point(l.margin_left + l.map_w - text_width(right), below));
  put(canvas, options.axes,
      cv::Point(l.margin_left + l.map_w / 2 - text_width(options.axes) / 2, below + 22));
  put(canvas, tick_text(options.y_min), cv::Point(5, l.margin_top + 12));
  put(canvas, tick_text(options.y_max), cv::Point(5, l.margin_top + l.map_h));
}

// The colour bar with five ticks; an end beyond which values were clamped is marked "<" or ">".
void draw_colour_bar(cv::Mat& canvas, const Layout& l, const ColourRange& range,
                     const HeatmapOptions& options, const std::function<cv::Vec3b(double)>& colour_of) {
  for (int y = 0; y < l.map_h; ++y) {
    const cv::Vec3b colour = colour_of(range.hi - (range.hi - range.lo) * y / std::max(1, l.map_h - 1));
    cv::line(canvas, cv::Point(l.bar_x, l.margin_top + y), cv::Point(l.bar_x + l.bar_w, l.margin_top + y),
             cv::Scalar(colour[0], colour[1], colour[2]));
  }
  cv::rectangle(canvas, cv::Rect(l.bar_x, l.margin_top, l.bar_w, l.map_h), cv::Scalar(0, 0, 0), 1);
  for (int k = 0; k <= 4; ++k) {
    const double v = range.hi - (range.hi - range.lo) * k / 4.0;
    const int y = l.margin_top + static_cast<int>(std::lround((l.map_h - 1) * k / 4.0));
    const std::string mark = k == 0 && range.clamped_high ? ">" : k == 4 && range.clamped_low ? "<" : "";
    cv::line(canvas, cv::Point(l.bar_x + l.bar_w, y), cv::Point(l.bar_x + l.bar_w + 4, y),
             cv::Scalar(0, 0, 0));
    put(canvas, mark + tick_text(v), cv::Point(l.bar_x + l.bar_w + 7, y + 5));
  }
  if (!options.unit.empty()) put(canvas, options.unit, cv::Point(l.bar_x, l.margin_top - 12));
}

}  // namespace

cv::Mat render_heatmap(const cv::Mat& values, const HeatmapOptions& options) {
  CV_Assert(values.type() == CV_64FC1 && !values.empty());
  const ColourRange range = colour_range(values, options);
  const Layout l = layout_of(values, options);
  cv::Mat canvas(l.map_h + l.margin_top + l.margin_bottom, l.bar_x + l.bar_w + l.labels_w, CV_8UC3,
                 cv::Scalar(255, 255, 255));
  const SequentialColours sequential;  // one table for every cell: applyColorMap builds one per call
  const auto colour_of = [&](double v) {
    const double t = (v - range.lo) / (range.hi - range.lo);
    return options.diverging ? diverging_colour(t) : sequential(t);
  };
  draw_cells(canvas, values, l, colour_of);
  draw_circles(canvas, values, l, options);
  draw_axes(canvas, l, options);
  draw_colour_bar(canvas, l, range, options, colour_of);
  return canvas;
}

void write_heatmap_png(const std::string& path, const cv::Mat& values, const HeatmapOptions& options) {
  write_png_file(path, render_heatmap(values, options));
}

}  // namespace tirstrain
