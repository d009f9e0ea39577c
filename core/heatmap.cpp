#include "core/heatmap.hpp"
#include "core/png_file.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"

namespace tirstrain {

cv::Vec3b diverging_colour(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double s = std::abs(2.0 * t - 1.0);
  const double fade = 1.0 - s;
  if (t < 0.5) return {255, static_cast<uchar>(255 * fade + 40 * s), static_cast<uchar>(255 * fade + 20 * s)};
  return {static_cast<uchar>(255 * fade + 20 * s), static_cast<uchar>(255 * fade + 30 * s), 255};
}

cv::Vec3b sequential_colour(double t) {
  cv::Mat1b in(1, 1, static_cast<uchar>(std::clamp(t, 0.0, 1.0) * 255.0));
  cv::Mat out;
  cv::applyColorMap(in, out, cv::COLORMAP_VIRIDIS);
  return out.at<cv::Vec3b>(0, 0);
}

namespace {

std::string tick_text(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3g", v);
  return buffer;
}

}  // namespace

cv::Mat render_heatmap(const cv::Mat& values, const HeatmapOptions& options) {
  CV_Assert(values.type() == CV_64FC1 && !values.empty());
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const double v = values.at<double>(r, c);
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
  if (options.diverging) {
    const double m = std::max(std::abs(lo), std::abs(hi));
    lo = -m, hi = m;
  }
  if (options.min) lo = *options.min;
  if (options.max) hi = *options.max;
  if (!(hi > lo)) hi = lo + (lo == 0.0 ? 1.0 : std::abs(lo) * 1e-6);

  const int cell = options.pixels_per_cell > 0 ? options.pixels_per_cell
                                               : std::max(1, 480 / std::max(values.cols, values.rows));
  const int map_w = values.cols * cell, map_h = values.rows * cell;
  const int margin_left = 70, margin_top = 40, margin_bottom = 45, bar_w = 20, bar_gap = 20, bar_labels = 90;
  cv::Mat canvas(map_h + margin_top + margin_bottom, margin_left + map_w + bar_gap + bar_w + bar_labels,
                 CV_8UC3, cv::Scalar(255, 255, 255));
  auto colour_of = [&](double v) {
    const double t = (v - lo) / (hi - lo);
    return options.diverging ? diverging_colour(t) : sequential_colour(t);
  };
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const double v = values.at<double>(r, c);
      const cv::Vec3b colour = std::isfinite(v) ? colour_of(v) : cv::Vec3b(200, 200, 200);
      cv::rectangle(canvas, cv::Rect(margin_left + c * cell, margin_top + r * cell, cell, cell),
                    cv::Scalar(colour[0], colour[1], colour[2]), cv::FILLED);
    }
  const auto to_px = [&](double x, double y) {
    const double fx = (x - options.x_min) / (options.x_max - options.x_min);
    const double fy = (y - options.y_min) / (options.y_max - options.y_min);
    return cv::Point2d(margin_left + (fx * (values.cols - 1) + 0.5) * cell,
                       margin_top + (fy * (values.rows - 1) + 0.5) * cell);
  };
  const double px_per_unit = (values.cols - 1) * cell / (options.x_max - options.x_min);
  for (const auto& circle : options.circles) {
    const cv::Point2d centre = to_px(circle.cx, circle.cy);
    const int radius = static_cast<int>(std::lround(circle.radius * px_per_unit));
    cv::circle(canvas, centre, radius, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    if (!circle.label.empty())
      cv::putText(canvas, circle.label, centre + cv::Point2d(radius * 0.71 + 3, -radius * 0.71 - 3),
                  cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  cv::rectangle(canvas, cv::Rect(margin_left, margin_top, map_w, map_h), cv::Scalar(0, 0, 0), 1);
  cv::putText(canvas, options.title, cv::Point(margin_left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  // Axis extent labels.
  const std::string unit = options.axis_unit.empty() ? "" : " " + options.axis_unit;
  cv::putText(canvas, tick_text(options.x_min) + unit, cv::Point(margin_left, margin_top + map_h + 18),
              cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(canvas, tick_text(options.x_max) + unit,
              cv::Point(margin_left + map_w - 60, margin_top + map_h + 18), cv::FONT_HERSHEY_SIMPLEX, 0.4,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(canvas, "x right, y down", cv::Point(margin_left + map_w / 2 - 50, margin_top + map_h + 36),
              cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(canvas, tick_text(options.y_min), cv::Point(5, margin_top + 10), cv::FONT_HERSHEY_SIMPLEX, 0.4,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(canvas, tick_text(options.y_max), cv::Point(5, margin_top + map_h), cv::FONT_HERSHEY_SIMPLEX,
              0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  // Colour bar with five ticks.
  const int bar_x = margin_left + map_w + bar_gap;
  for (int y = 0; y < map_h; ++y) {
    const double v = hi - (hi - lo) * y / std::max(1, map_h - 1);
    const cv::Vec3b colour = colour_of(v);
    cv::line(canvas, cv::Point(bar_x, margin_top + y), cv::Point(bar_x + bar_w, margin_top + y),
             cv::Scalar(colour[0], colour[1], colour[2]));
  }
  cv::rectangle(canvas, cv::Rect(bar_x, margin_top, bar_w, map_h), cv::Scalar(0, 0, 0), 1);
  for (int k = 0; k <= 4; ++k) {
    const double v = hi - (hi - lo) * k / 4.0;
    const int y = margin_top + static_cast<int>(std::lround((map_h - 1) * k / 4.0));
    cv::line(canvas, cv::Point(bar_x + bar_w, y), cv::Point(bar_x + bar_w + 4, y), cv::Scalar(0, 0, 0));
    cv::putText(canvas, tick_text(v), cv::Point(bar_x + bar_w + 7, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  if (!options.unit.empty())
    cv::putText(canvas, options.unit, cv::Point(bar_x, margin_top - 8), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  return canvas;
}

void write_heatmap_png(const std::string& path, const cv::Mat& values, const HeatmapOptions& options) {
  write_png_file(path, render_heatmap(values, options));
}

}  // namespace tirstrain
