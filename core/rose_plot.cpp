#include "core/rose_plot.hpp"
#include "core/png_file.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.hpp"

namespace tirstrain {
namespace {

const cv::Scalar kColours[] = {{200, 90, 30}, {40, 40, 210}, {40, 160, 40}, {160, 40, 160}, {0, 140, 220}};

cv::Point at(cv::Point centre, double radius, double angle) {
  return {centre.x + static_cast<int>(std::lround(radius * std::cos(angle))),
          centre.y + static_cast<int>(std::lround(radius * std::sin(angle)))};
}

void draw_group(cv::Mat& img, cv::Point centre, const RoseGroup& g, double largest_share, int radius_px,
                const cv::Scalar& colour) {
  std::size_t total = 0;
  for (auto c : g.counts) total += c;
  if (total == 0 || g.counts.empty()) return;
  const double width = std::numbers::pi / static_cast<double>(g.counts.size());
  for (std::size_t k = 0; k < g.counts.size(); ++k) {
    const double share = static_cast<double>(g.counts[k]) / static_cast<double>(total);
    const double r = radius_px * std::sqrt(share / largest_share);
    for (double mirror : {0.0, std::numbers::pi}) {
      std::vector<cv::Point> sector{centre};
      for (int s = 0; s <= 8; ++s) sector.push_back(at(centre, r, mirror + width * (k + s / 8.0)));
      cv::polylines(img, sector, true, colour, 2, cv::LINE_AA);
    }
  }
  cv::line(img, at(centre, radius_px * 1.05, g.mean_direction_rad),
           at(centre, radius_px * 1.05, g.mean_direction_rad + std::numbers::pi), colour, 1, cv::LINE_AA);
}

}  // namespace

cv::Mat render_rose(const std::vector<RoseGroup>& groups, const RoseOptions& o) {
  if (o.radius_px < 20) throw Error("rose radius must be at least 20 px");
  const int margin = 60, legend = 22 * static_cast<int>(groups.size()) + 40;
  cv::Mat img(2 * (o.radius_px + margin) + legend, 2 * (o.radius_px + margin), CV_8UC3,
              cv::Scalar(255, 255, 255));
  const cv::Point centre(o.radius_px + margin, o.radius_px + margin + 20);
  double largest = 0.0;
  for (const auto& g : groups) {
    std::size_t total = 0;
    for (auto c : g.counts) total += c;
    for (auto c : g.counts)
      if (total > 0) largest = std::max(largest, static_cast<double>(c) / static_cast<double>(total));
  }
  const cv::Scalar grey(190, 190, 190), black(0, 0, 0);
  for (double f : {0.25, 0.5, 1.0})
    cv::circle(img, centre, static_cast<int>(o.radius_px * std::sqrt(f)), grey, 1, cv::LINE_AA);
  for (int deg = 0; deg < 360; deg += 45) {
    const double a = deg * std::numbers::pi / 180.0;
    cv::line(img, centre, at(centre, o.radius_px, a), grey, 1, cv::LINE_AA);
    cv::putText(img, std::to_string(deg % 180), at(centre, o.radius_px + 22, a) - cv::Point(12, -5),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1, cv::LINE_AA);
  }
  if (largest > 0.0)
    for (std::size_t g = 0; g < groups.size(); ++g)
      draw_group(img, centre, groups[g], largest, o.radius_px, kColours[g % std::size(kColours)]);
  cv::putText(img, o.title, {10, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.55, black, 1, cv::LINE_AA);
  int y = 2 * (o.radius_px + margin) + 20;
  cv::putText(img,
              "deg from +x towards +y (image); outer circle: largest sector share " +
                  std::to_string(static_cast<int>(std::lround(100 * largest))) + " %",
              {10, y}, cv::FONT_HERSHEY_SIMPLEX, 0.42, black, 1, cv::LINE_AA);
  for (std::size_t g = 0; g < groups.size(); ++g) {
    y += 22;
    cv::rectangle(img, {10, y - 10}, {24, y}, kColours[g % std::size(kColours)], cv::FILLED);
    cv::putText(img, groups[g].label, {32, y}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1, cv::LINE_AA);
  }
  return img;
}

void write_rose_png(const std::string& path, const std::vector<RoseGroup>& groups,
                    const RoseOptions& options) {
  write_png_file(path, render_rose(groups, options));
}

}  // namespace tirstrain
