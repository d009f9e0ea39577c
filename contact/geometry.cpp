#include "contact/geometry.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

namespace tirstrain::contact {

std::vector<cv::Point2d> resample_closed_polygon(const std::vector<cv::Point2d>& polygon, int count) {
  std::vector<cv::Point2d> out;
  if (polygon.empty() || count <= 0) return out;
  out.reserve(static_cast<std::size_t>(count));
  const std::size_t n = polygon.size();
  std::vector<double> cumulative(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    cumulative[i + 1] = cumulative[i] + cv::norm(polygon[(i + 1) % n] - polygon[i]);
  const double perimeter = cumulative[n];
  if (!(perimeter > 0.0)) {
    out.assign(static_cast<std::size_t>(count), polygon.front());
    return out;
  }
  std::size_t edge = 0;
  for (int k = 0; k < count; ++k) {
    const double s = perimeter * k / count;
    while (edge + 1 < n && cumulative[edge + 1] <= s) ++edge;
    const double length = cumulative[edge + 1] - cumulative[edge];
    const double f = length > 0.0 ? (s - cumulative[edge]) / length : 0.0;
    out.push_back(polygon[edge] + f * (polygon[(edge + 1) % n] - polygon[edge]));
  }
  return out;
}

std::vector<cv::Point2d> convex_hull(const std::vector<cv::Point2d>& points) {
  if (points.size() < 3) return points;
  std::vector<cv::Point2f> as_float(points.begin(), points.end());
  // cv::convexHull works in float; contact outlines are < 10^4 px, so float keeps ~1e-3 px, and the hull
  // vertices are taken back from the double input by index.
  std::vector<int> indices;
  cv::convexHull(as_float, indices, false, false);
  std::vector<cv::Point2d> hull;
  hull.reserve(indices.size());
  for (int i : indices) hull.push_back(points[static_cast<std::size_t>(i)]);
  return hull;
}

double polygon_area_px2(const std::vector<cv::Point2d>& polygon) {
  double twice = 0.0;
  const std::size_t n = polygon.size();
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point2d& a = polygon[i];
    const cv::Point2d& b = polygon[(i + 1) % n];
    twice += a.x * b.y - b.x * a.y;
  }
  return std::abs(twice) / 2.0;
}

cv::Mat rasterize_polygon(const std::vector<cv::Point2d>& polygon, cv::Size size) {
  cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
  const std::size_t n = polygon.size();
  if (n < 3 || size.height <= 0) return mask;
  // Even-odd scanline fill at pixel centres: exact to the pixel, unlike cv::fillPoly, which also paints
  // the pixels its outline passes through and so grows every region by about half a pixel. Each edge adds
  // its crossings with the pixel-centre rows it spans (half-open in y, so a vertex on a row counts once);
  // sorted by row, then x, consecutive pairs are the inside runs.
  std::vector<std::pair<int, double>> crossings;
  crossings.reserve(4 * static_cast<std::size_t>(size.height));
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point2d& a = polygon[i];
    const cv::Point2d& b = polygon[(i + 1) % n];
    if (a.y == b.y) continue;
    const double y_low = std::min(a.y, b.y), y_high = std::max(a.y, b.y);
    // Rows yc with y_low <= yc < y_high, within the image.
    const int first = std::max(0, static_cast<int>(std::ceil(y_low)));
    const int last = std::min(size.height - 1, static_cast<int>(std::ceil(y_high)) - 1);
    const double slope = (b.x - a.x) / (b.y - a.y);
    for (int y = first; y <= last; ++y) crossings.emplace_back(y, a.x + (y - a.y) * slope);
  }
  std::sort(crossings.begin(), crossings.end());
  for (std::size_t k = 0; k + 1 < crossings.size();) {
    const int y = crossings[k].first;
    if (crossings[k + 1].first != y) {  // an odd crossing count on this row cannot happen; skip it safely
      ++k;
      continue;
    }
    auto* row = mask.ptr<std::uint8_t>(y);
    const int x0 = std::max(0, static_cast<int>(std::ceil(crossings[k].second)));
    const int x1 = std::min(size.width - 1, static_cast<int>(std::floor(crossings[k + 1].second)));
    for (int x = x0; x <= x1; ++x) row[x] = 255;
    k += 2;
  }
  return mask;
}

double mask_iou(const cv::Mat& a, const cv::Mat& b) {
  CV_Assert(a.size() == b.size());
  cv::Mat a_bin = a != 0, b_bin = b != 0;
  const double intersection = cv::countNonZero(a_bin & b_bin);
  const double uni = cv::countNonZero(a_bin | b_bin);
  return uni > 0.0 ? intersection / uni : 1.0;
}

}  // namespace tirstrain::contact
