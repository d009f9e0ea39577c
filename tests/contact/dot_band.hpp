#pragma once
// The pattern printed on a TIR glass plate, for tests: random Gaussian dots on a jittered lattice (spacing
// 8 px, sigma 1.5 px, 70 % of the sites), darkening the image by `opacity` under each dot, inside `band`
// only, the pattern shifted by `offset_px` (the plate's displacement; |offset| <= 64 px).
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

namespace tirstrain::test {

inline void add_dots(cv::Mat& image8, const cv::Rect& band, double opacity = 0.6, unsigned seed = 7,
                     cv::Point2d offset_px = {0.0, 0.0}) {
  const double spacing = 8.0, sigma = 1.5;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  cv::Mat darkness = cv::Mat::zeros(image8.size(), CV_32F);
  // Lattice sites over the image and a margin, the same sites (and random draws) for every offset: offsets
  // up to 64 px keep the band covered.
  const double reach = spacing + 64.0;
  for (double y0 = -reach; y0 < image8.rows + reach; y0 += spacing)
    for (double x0 = -reach; x0 < image8.cols + reach; x0 += spacing) {
      if (u(rng) > 0.7) continue;
      const double cx = x0 + spacing * (0.15 + 0.7 * u(rng)) + offset_px.x;
      const double cy = y0 + spacing * (0.15 + 0.7 * u(rng)) + offset_px.y;
      const int y_lo = std::max(0, static_cast<int>(cy - 4 * sigma)),
                y_hi = std::min(image8.rows - 1, static_cast<int>(cy + 4 * sigma));
      const int x_lo = std::max(0, static_cast<int>(cx - 4 * sigma)),
                x_hi = std::min(image8.cols - 1, static_cast<int>(cx + 4 * sigma));
      for (int y = y_lo; y <= y_hi; ++y)
        for (int x = x_lo; x <= x_hi; ++x)
          darkness.at<float>(y, x) += static_cast<float>(
              std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * sigma * sigma)));
    }
  for (int y = band.y; y < band.y + band.height; ++y)
    for (int x = band.x; x < band.x + band.width; ++x) {
      const double d = 1.0 - std::exp(-1.5 * darkness.at<float>(y, x));
      auto& v = image8.at<std::uint8_t>(y, x);
      v = cv::saturate_cast<std::uint8_t>(v * (1.0 - opacity * d));
    }
}

}  // namespace tirstrain::test
