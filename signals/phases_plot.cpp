#include "signals/phases_plot.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/png_file.hpp"

namespace tirstrain::signals {
namespace {

constexpr int kLeft = 80, kRight = 20, kTop = 36, kGap = 28, kBottom = 40;

std::string text_of(double v, const char* format = "%.3g") {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

void put(cv::Mat& img, const std::string& text, cv::Point at, double scale = 0.42) {
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

struct Axis {
  double t0, t1;
  int left, right;
  int x(double t) const {
    return left + static_cast<int>(std::lround((t - t0) / (t1 - t0) * (right - left)));
  }
};

void shade(cv::Mat& img, const Axis& ax, int top, int bottom, double from_s, double to_s,
           const cv::Scalar& c) {
  const int x0 = std::clamp(ax.x(from_s), ax.left, ax.right), x1 = std::clamp(ax.x(to_s), ax.left, ax.right);
  if (x1 > x0) cv::rectangle(img, cv::Rect(x0, top, x1 - x0, bottom - top), c, cv::FILLED);
}

void shade_phases(cv::Mat& img, const Axis& ax, int top, int bottom, const Phases& p) {
  shade(img, ax, top, bottom, p.record_start_s, p.contact_start_s, phase_colour("approach"));
  shade(img, ax, top, bottom, p.contact_start_s, p.loaded_s, phase_colour("press"));
  shade(img, ax, top, bottom, p.loaded_s, p.release_s, phase_colour("loading"));
  for (const Stroke& s : p.strokes)
    shade(img, ax, top, bottom, s.slide_start_s, s.slide_end_s, phase_colour("slide"));
  shade(img, ax, top, bottom, p.release_s, p.contact_end_s, phase_colour("release"));
  shade(img, ax, top, bottom, p.contact_end_s, p.record_end_s, phase_colour("approach"));
}

// One channel as the min–max envelope of the samples in each pixel column (nothing is lost to aliasing).
void trace(cv::Mat& img, const Axis& ax, int top, int bottom, const std::vector<double>& t,
           const std::vector<double>& v, const std::vector<char>* valid, double lo, double hi) {
  const auto y = [&](double value) {
    const double f = (value - lo) / (hi - lo);
    return std::clamp(bottom - static_cast<int>(std::lround(f * (bottom - top))), top, bottom);
  };
  int column = -1, y_min = 0, y_max = 0;
  const auto flush = [&] {
    if (column >= 0) cv::line(img, {column, y_min}, {column, y_max}, cv::Scalar(60, 30, 10), 1);
  };
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (valid && !(*valid)[i]) continue;
    const int c = ax.x(t[i]), yy = y(v[i]);
    if (c != column) {
      flush();
      column = c;
      y_min = y_max = yy;
    }
    y_min = std::min(y_min, yy);
    y_max = std::max(y_max, yy);
  }
  flush();
}

void panel(cv::Mat& img, const Axis& ax, int top, int bottom, const std::string& label,
           const std::vector<double>& t, const std::vector<double>& v, const std::vector<char>* valid,
           const Phases& p) {
  double lo = 0.0, hi = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!valid || (*valid)[i]) lo = std::min(lo, v[i]), hi = std::max(hi, v[i]);
  if (!(hi > lo)) hi = lo + 1.0;
  const double pad = 0.05 * (hi - lo);
  lo -= pad;
  hi += pad;
  shade_phases(img, ax, top, bottom, p);
  const int zero = bottom - static_cast<int>(std::lround(-lo / (hi - lo) * (bottom - top)));
  if (zero > top && zero < bottom)
    cv::line(img, {ax.left, zero}, {ax.right, zero}, cv::Scalar(150, 150, 150), 1);
  trace(img, ax, top, bottom, t, v, valid, lo, hi);
  cv::rectangle(img, cv::Rect(ax.left, top, ax.right - ax.left, bottom - top), cv::Scalar(0, 0, 0), 1);
  put(img, label, {ax.left + 4, top + 14});
  put(img, text_of(hi), {4, top + 10});
  put(img, text_of(lo), {4, bottom});
}

void time_ticks(cv::Mat& img, const Axis& ax, int bottom) {
  const double span = ax.t1 - ax.t0;
  const double raw = span / 10.0, magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double step = raw / magnitude < 2   ? 2 * magnitude
                      : raw / magnitude < 5 ? 5 * magnitude
                                            : 10 * magnitude;
  for (double t = std::ceil(ax.t0 / step) * step; t <= ax.t1 + 1e-9 * span; t += step) {
    cv::line(img, {ax.x(t), bottom}, {ax.x(t), bottom + 4}, cv::Scalar(0, 0, 0), 1);
    put(img, text_of(t, "%g"), {ax.x(t) - 8, bottom + 18});
  }
  put(img, "t (s)", {ax.right - 40, bottom + 34});
}

void stroke_labels(cv::Mat& img, const Axis& ax, int top, const Phases& p) {
  for (const Stroke& s : p.strokes)
    put(img, std::string(s.direction > 0 ? "+" : "-") + " mu " + text_of(s.mu_mean),
        {ax.x(s.slide_start_s) + 3, top + 30}, 0.38);
}

}  // namespace

cv::Scalar phase_colour(const std::string& phase) {
  if (phase == "press") return {245, 215, 180};
  if (phase == "loading") return {190, 240, 250};
  if (phase == "slide") return {195, 240, 195};
  if (phase == "release") return {200, 200, 250};
  return {232, 232, 232};
}

cv::Mat render_phases_plot(const std::vector<double>& time_s, const Phases& phases,
                           const PhasesPlotOptions& options, PhasesPlotLayout* layout) {
  if (time_s.size() < 2 || phases.normal_N.size() != time_s.size())
    throw Error("internal: the phases plot needs the phases' own samples");
  const int h = options.panel_height_px;
  cv::Mat img(kTop + 3 * h + 2 * kGap + kBottom, options.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const Axis ax{time_s.front(), time_s.back(), kLeft, options.width_px - kRight};
  std::vector<double> mu(time_s.size(), 0.0);
  std::vector<char> valid(time_s.size(), 0);
  for (std::size_t i = 0; i < mu.size(); ++i)
    if (phases.normal_N[i] * phases.normal_sign > 0.2 * std::abs(phases.normal_level_N)) {
      mu[i] = phases.tangential_N[i] / phases.normal_N[i];
      valid[i] = 1;
    }
  const std::vector<std::string> labels{"normal force W (N, tared)", "tangential force F_t (N, tared)",
                                        "mu = F_t / W (where W > 20 % of its level)"};
  const std::vector<const std::vector<double>*> values{&phases.normal_N, &phases.tangential_N, &mu};
  PhasesPlotLayout lay{ax.left, ax.right, {}, {}};
  for (int k = 0; k < 3; ++k) {
    const int top = kTop + k * (h + kGap);
    panel(img, ax, top, top + h, labels[k], time_s, *values[k], k == 2 ? &valid : nullptr, phases);
    lay.panel_top.push_back(top);
    lay.panel_bottom.push_back(top + h);
  }
  stroke_labels(img, ax, lay.panel_top[2], phases);
  time_ticks(img, ax, lay.panel_bottom.back());
  put(img, options.title, {kLeft, 22}, 0.45);
  put(img, "grey: no contact  blue: press  yellow: loading  green: slide  red: release",
      {options.width_px - kRight - 560, 22}, 0.42);
  if (layout) *layout = lay;
  return img;
}

void write_phases_png(const std::string& path, const std::vector<double>& time_s, const Phases& phases,
                      const PhasesPlotOptions& options) {
  write_png_file(path, render_phases_plot(time_s, phases, options));
}

}  // namespace tirstrain::signals
