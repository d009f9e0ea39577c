#include "fit/fit_plots.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "core/heatmap.hpp"
#include "core/median.hpp"

namespace tirstrain::fit {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kCellPx = 8.0;

bool loaded(const FrameFit& f) {
  const bool fitted = f.status == FitStatus::ok || f.status == FitStatus::no_covariance;
  return fitted && f.model != FieldModel::rest;
}

// Mean residual length per cell of the reference positions' bounding box.
cv::Mat residual_grid(const ResultForFit& r, const FrameFit& f, double* x0, double* y0) {
  double xmin = 1e300, ymin = 1e300, xmax = -1e300, ymax = -1e300;
  for (std::size_t k = 0; k < r.tracks(); ++k) {
    if (!std::isfinite(f.residual_px[k].x)) continue;
    xmin = std::min(xmin, r.reference_px[k].x);
    xmax = std::max(xmax, r.reference_px[k].x);
    ymin = std::min(ymin, r.reference_px[k].y);
    ymax = std::max(ymax, r.reference_px[k].y);
  }
  const int nx = static_cast<int>((xmax - xmin) / kCellPx) + 1,
            ny = static_cast<int>((ymax - ymin) / kCellPx) + 1;
  cv::Mat sum = cv::Mat::zeros(ny, nx, CV_64F), count = cv::Mat::zeros(ny, nx, CV_64F);
  for (std::size_t k = 0; k < r.tracks(); ++k) {
    const Vec2& e = f.residual_px[k];
    if (!std::isfinite(e.x)) continue;
    const int i = static_cast<int>((r.reference_px[k].y - ymin) / kCellPx);
    const int j = static_cast<int>((r.reference_px[k].x - xmin) / kCellPx);
    sum.at<double>(i, j) += std::hypot(e.x, e.y);
    count.at<double>(i, j) += 1.0;
  }
  for (int i = 0; i < ny; ++i)
    for (int j = 0; j < nx; ++j)
      sum.at<double>(i, j) =
          count.at<double>(i, j) > 0 ? sum.at<double>(i, j) / count.at<double>(i, j) : kNaN;
  *x0 = xmin;
  *y0 = ymin;
  return sum;
}

void write_residual_map(const std::string& path, const std::string& moment, long frame, const ResultForFit& r,
                        const FrameFit& f) {
  double x0 = 0, y0 = 0;
  const cv::Mat grid = residual_grid(r, f, &x0, &y0);
  HeatmapOptions o;
  o.title = "|measured - " + std::string(field_model_name(f.model)) + "| at " + moment + " (frame " +
            std::to_string(frame) + ")";
  o.unit = "px";
  o.diverging = false;
  o.min = 0.0;
  o.x_min = x0;
  o.x_max = x0 + kCellPx * (grid.cols - 1);
  o.y_min = y0;
  o.y_max = y0 + kCellPx * (grid.rows - 1);
  o.axis_unit = "px";
  const double mm_to_px = r.px_per_mm;
  if (std::isfinite(f.centre_x_px.value)) {
    o.circles.push_back({f.centre_x_px.value, f.centre_y_px.value, f.a_mm.value * mm_to_px, "a"});
    if (f.c_mm.value > 0.0)
      o.circles.push_back({f.centre_x_px.value, f.centre_y_px.value, f.c_mm.value * mm_to_px, "c"});
  }
  write_heatmap_png(path, grid, o);
}

// μP of the trial: the one the fit held (fit/fit_result.hpp, trial_limit), else the median over the frames
// that determine it.
double friction_limit_N(const std::vector<FrameFit>& fits) {
  for (const FrameFit& f : fits)
    if (f.limit_from_trial && std::isfinite(f.limit_N.value)) return f.limit_N.value;
  std::vector<double> v;
  for (const FrameFit& f : fits)
    if (loaded(f) && std::isfinite(f.limit_N.value)) v.push_back(f.limit_N.value);
  if (v.empty()) return kNaN;
  return upper_median_in_place(v);
}

struct Axes {
  cv::Rect area;
  double t0, t1;
  cv::Point at(double t, double y) const {
    const double fx = (t - t0) / std::max(t1 - t0, 1e-12);
    return {area.x + static_cast<int>(fx * area.width),
            area.y + static_cast<int>((1.0 - y / 1.1) * area.height)};
  }
};

void draw_axes(cv::Mat& img, const Axes& ax) {
  cv::rectangle(img, ax.area, cv::Scalar(0, 0, 0), 1);
  for (const double y : {0.0, 0.5, 1.0}) {
    const cv::Point p = ax.at(ax.t0, y);
    cv::putText(img, cv::format("%.1f", y), {p.x - 32, p.y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0},
                1);
  }
  cv::putText(img, cv::format("%.3f s", ax.t0), {ax.area.x, ax.area.br().y + 18}, cv::FONT_HERSHEY_SIMPLEX,
              0.45, {0, 0, 0}, 1);
  cv::putText(img, cv::format("%.3f s", ax.t1), {ax.area.br().x - 60, ax.area.br().y + 18},
              cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1);
}

void write_time_plot(const std::string& path, const ResultForFit& r, const std::vector<FrameFit>& fits) {
  cv::Mat img(420, 720, CV_8UC3, cv::Scalar(255, 255, 255));
  const Axes ax{cv::Rect(60, 40, 620, 320), r.t_s.front(), r.t_s.back()};
  draw_axes(img, ax);
  const double limit = friction_limit_N(fits);
  const bool held =
      std::any_of(fits.begin(), fits.end(), [](const FrameFit& f) { return f.limit_from_trial; });
  const cv::Scalar blue(200, 80, 0), green(40, 160, 40), red(0, 0, 220);
  for (std::size_t i = 0; i < fits.size(); ++i) {
    const FrameFit& f = fits[i];
    if (!loaded(f)) continue;
    const double q = f.tangential_N.value / limit;
    if (std::isfinite(f.c_mm.value / f.a_mm.value))
      cv::circle(img, ax.at(r.t_s[i], f.c_mm.value / f.a_mm.value), 3, blue, -1);
    if (std::isfinite(q)) {
      cv::circle(img, ax.at(r.t_s[i], q), 3, green, -1);
      cv::drawMarker(img, ax.at(r.t_s[i], std::cbrt(std::max(0.0, 1.0 - q))), red, cv::MARKER_CROSS, 8, 1);
    }
  }
  cv::putText(img, "c/a fitted", {70, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, blue, 1);
  cv::putText(img, "Q / muP", {200, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, green, 1);
  cv::putText(img, "(1 - Q/muP)^(1/3)", {310, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, red, 1);
  cv::putText(img,
              std::isfinite(limit)
                  ? cv::format("muP = %.3f N (%s)", limit, held ? "the trial's, held" : "median of fits")
                  : "muP undetermined",
              {60, 400}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0}, 1);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", img, png)) throw Error("cannot encode the plot", {.file = path});
  AtomicFile out(path);
  out.append(std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  out.commit();
}

}  // namespace

KeyFrames key_frames(const std::vector<FrameFit>& fits) {
  KeyFrames k;
  double q_max = 0.0;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (!loaded(fits[i])) continue;
    q_max = std::max(q_max, fits[i].tangential_N.value);
    if (k.onset < 0 && (i == 0 || !loaded(fits[i - 1]))) k.onset = static_cast<long>(i);
    if (k.full_slip < 0 && fits[i].model == FieldModel::full_slip) k.full_slip = static_cast<long>(i);
  }
  for (std::size_t i = 0; i < fits.size() && q_max > 0.0; ++i)
    if (loaded(fits[i]) && fits[i].tangential_N.value >= 0.9 * q_max) {
      k.t90 = static_cast<long>(i);
      break;
    }
  return k;
}

void write_fit_plots(const std::string& dir, const ResultForFit& result, const std::vector<FrameFit>& fits) {
  if (fits.empty()) return;
  const KeyFrames k = key_frames(fits);
  const std::pair<const char*, long> moments[] = {
      {"onset", k.onset}, {"t90", k.t90}, {"full_slip", k.full_slip}};
  for (const auto& [name, frame] : moments)
    if (frame >= 0)
      write_residual_map((fs::path(dir) / ("residual_" + std::string(name) + ".png")).string(), name, frame,
                         result, fits[static_cast<std::size_t>(frame)]);
  write_time_plot((fs::path(dir) / "c_q_vs_time.png").string(), result, fits);
}

}  // namespace tirstrain::fit
