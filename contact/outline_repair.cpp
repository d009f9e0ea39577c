#include "contact/outline_repair.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "contact/ellipse.hpp"
#include "core/median.hpp"

namespace tirstrain::contact {

void clip_spikes(std::vector<cv::Point2d>& points, const std::vector<std::uint8_t>& cut,
                 const cv::Point2d& centre, double spike_px) {
  constexpr int kHalf = 5;
  const std::size_t n = points.size();
  if (n < 2 * kHalf + 1) return;
  std::vector<double> radius(n), window;
  for (std::size_t i = 0; i < n; ++i) radius[i] = cv::norm(points[i] - centre);
  for (std::size_t i = 0; i < n; ++i) {
    if (cut[i] != 0 || radius[i] <= 0.0) continue;
    window.clear();
    for (std::size_t k = 0; k <= 2 * kHalf; ++k) {
      const std::size_t j = (i + n - kHalf + k) % n;
      if (cut[j] == 0) window.push_back(radius[j]);
    }
    const double limit = upper_median_in_place(window) + spike_px;
    if (radius[i] > limit) points[i] = centre + (points[i] - centre) * (limit / radius[i]);
  }
}

void bridge_valleys(std::vector<cv::Point2d>& points, const std::vector<std::uint8_t>& cut, double gap_px) {
  std::vector<cv::Point2d> free;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (cut[i] == 0) {
      free.push_back(points[i]);
      index.push_back(i);
    }
  if (free.size() < 20) return;
  std::optional<Ellipse> ellipse = fit_ellipse_direct(free);
  // Signed distance along the ray from the centre: negative inside.
  const auto radial_gap = [](const Ellipse& e, const cv::Point2d& p, double* scale) {
    const double rho = std::sqrt(std::max(0.0, ellipse_level(e, p) + 1.0));
    *scale = rho;
    return rho > 0.0 ? (rho - 1.0) * cv::norm(p - cv::Point2d(e.cx_px, e.cy_px)) / rho : 0.0;
  };
  for (int iteration = 0; iteration < 2 && ellipse; ++iteration) {
    std::vector<cv::Point2d> outer;
    for (const auto& p : free) {
      double rho = 0.0;
      if (radial_gap(*ellipse, p, &rho) >= -gap_px) outer.push_back(p);
    }
    if (outer.size() < 20 || outer.size() == free.size()) break;
    ellipse = fit_ellipse_direct(outer);
  }
  if (!ellipse) return;
  const cv::Point2d centre(ellipse->cx_px, ellipse->cy_px);
  for (std::size_t k = 0; k < free.size(); ++k) {
    double rho = 0.0;
    if (radial_gap(*ellipse, free[k], &rho) < -gap_px && rho > 0.0)
      points[index[k]] = centre + (free[k] - centre) * (1.0 / rho);
  }
}

}  // namespace tirstrain::contact
