#include "signals/recurrence_plot.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

constexpr int kLeft = 70, kRight = 40, kTop = 56, kBottom = 60;

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.5) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

std::string tick_label(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", value);
  return buf;
}

void draw_axes(cv::Mat& img, const RecurrencePlotLayout& l, std::size_t size,
               const RecurrencePlotOptions& o) {
  const cv::Scalar black(0, 0, 0);
  cv::rectangle(img, {l.left - 1, l.top - 1}, {l.left + l.side, l.top + l.side}, black, 1);
  const double extent = static_cast<double>(size) * o.spacing;
  for (int k = 0; k <= 4; ++k) {
    const int px = l.side * k / 4;
    const std::string label = tick_label(extent * k / 4.0);
    cv::line(img, {l.left + px, l.top + l.side}, {l.left + px, l.top + l.side + 5}, black, 1);
    text(img, label, {l.left + px - 12, l.top + l.side + 20}, 0.45);
    cv::line(img, {l.left - 5, l.top + l.side - px}, {l.left, l.top + l.side - px}, black, 1);
    text(img, label, {l.left - 8 - 9 * static_cast<int>(label.size()), l.top + l.side - px + 5}, 0.45);
  }
  text(img, o.axis_label + " (i)", {l.left + l.side / 2 - 40, l.top + l.side + 45});
  text(img, o.axis_label + " (j)", {8, l.top - 10});
  text(img, o.title, {l.left, 22}, 0.55);
}

// fraction(i, j) in [0, 1] for each matrix cell; a pixel shows the mean over its block, dark = 1.
cv::Mat render(std::size_t size, const std::function<double(std::size_t, std::size_t)>& fraction,
               const RecurrencePlotOptions& o, RecurrencePlotLayout* layout_out) {
  if (size == 0) throw Error("the recurrence matrix is empty");
  if (o.max_side_px < 16) throw Error("plot side must be at least 16 px", {.key = "max_side_px"});
  RecurrencePlotLayout l;
  l.block = (size + static_cast<std::size_t>(o.max_side_px) - 1) / static_cast<std::size_t>(o.max_side_px);
  l.side = static_cast<int>((size + l.block - 1) / l.block);
  l.left = kLeft;
  l.top = kTop;
  cv::Mat img(l.top + l.side + kBottom, l.left + l.side + kRight, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int py = 0; py < l.side; ++py)
    for (int px = 0; px < l.side; ++px) {
      const std::size_t i0 = static_cast<std::size_t>(px) * l.block,
                        j0 = static_cast<std::size_t>(py) * l.block;
      const std::size_t i1 = std::min(size, i0 + l.block), j1 = std::min(size, j0 + l.block);
      double sum = 0.0;
      for (std::size_t i = i0; i < i1; ++i)
        for (std::size_t j = j0; j < j1; ++j) sum += fraction(i, j);
      const double mean = sum / static_cast<double>((i1 - i0) * (j1 - j0));
      const auto grey = static_cast<unsigned char>(std::lround(255.0 * (1.0 - std::clamp(mean, 0.0, 1.0))));
      img.at<cv::Vec3b>(l.top + l.side - 1 - py, l.left + px) = cv::Vec3b(grey, grey, grey);
    }
  draw_axes(img, l, size, o);
  if (layout_out) *layout_out = l;
  return img;
}

}  // namespace

cv::Mat render_recurrence_plot(const RecurrenceMatrix& r, const RecurrencePlotOptions& options,
                               RecurrencePlotLayout* layout) {
  return render(
      r.size(), [&](std::size_t i, std::size_t j) { return r.get(i, j) ? 1.0 : 0.0; }, options, layout);
}

cv::Mat render_ensemble_plot(const std::vector<std::uint16_t>& counts, std::size_t size, std::size_t trials,
                             const RecurrencePlotOptions& options, RecurrencePlotLayout* layout) {
  if (counts.size() != size * size || trials == 0)
    throw Error("ensemble counts do not match the matrix size");
  const double per_trial = 1.0 / static_cast<double>(trials);
  return render(
      size, [&](std::size_t i, std::size_t j) { return counts[i * size + j] * per_trial; }, options, layout);
}

}  // namespace tirstrain::signals
