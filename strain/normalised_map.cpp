#include "strain/normalised_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tirstrain::strain {

std::vector<std::int32_t> rasterise_triangles(const NormalisedGrid& grid, std::span<const Triangle> triangles,
                                              std::span<const Vec2> reference_px,
                                              std::span<const std::uint8_t> usable) {
  const int n = grid.cells;
  std::vector<std::int32_t> owner(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), -1);
  const double step = 2.0 / (n - 1);
  const auto& m = grid.to_normalised;
  const auto map = [&](const Vec2& p) {
    return Vec2{m(0, 0) * p.x + m(0, 1) * p.y + m(0, 2), m(1, 0) * p.x + m(1, 1) * p.y + m(1, 2)};
  };
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!usable.empty() && !usable[t]) continue;
    const Vec2 a = map(reference_px[static_cast<std::size_t>(triangles[t][0])]);
    const Vec2 b = map(reference_px[static_cast<std::size_t>(triangles[t][1])]);
    const Vec2 c = map(reference_px[static_cast<std::size_t>(triangles[t][2])]);
    const double area2 = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
    if (!(std::abs(area2) > 0.0)) continue;
    const auto index_range = [&](double lo, double hi) {
      const int first = std::max(0, static_cast<int>(std::ceil((lo + 1.0) / step - 1e-9)));
      const int last = std::min(n - 1, static_cast<int>(std::floor((hi + 1.0) / step + 1e-9)));
      return std::pair{first, last};
    };
    const auto [i0, i1] = index_range(std::min({a.x, b.x, c.x}), std::max({a.x, b.x, c.x}));
    const auto [j0, j1] = index_range(std::min({a.y, b.y, c.y}), std::max({a.y, b.y, c.y}));
    for (int j = j0; j <= j1; ++j) {
      const double y = grid.coordinate(j);
      for (int i = i0; i <= i1; ++i) {
        const double x = grid.coordinate(i);
        // Barycentric signs relative to the triangle's orientation; cells on a shared edge go to the first
        // triangle that claims them.
        const double w0 = ((b.x - x) * (c.y - y) - (c.x - x) * (b.y - y)) / area2;
        const double w1 = ((c.x - x) * (a.y - y) - (a.x - x) * (c.y - y)) / area2;
        const double w2 = 1.0 - w0 - w1;
        constexpr double kEdge = -1e-12;
        if (w0 < kEdge || w1 < kEdge || w2 < kEdge) continue;
        auto& cell =
            owner[static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)];
        if (cell < 0) cell = static_cast<std::int32_t>(t);
      }
    }
  }
  return owner;
}

cv::Mat nan_mean(std::span<const cv::Mat> maps, cv::Mat* count) {
  if (maps.empty()) return {};
  cv::Mat sum = cv::Mat::zeros(maps[0].size(), CV_64FC(maps[0].channels()));
  cv::Mat n = cv::Mat::zeros(maps[0].size(), CV_64FC(maps[0].channels()));
  for (const cv::Mat& map : maps) {
    CV_Assert(map.size() == sum.size() && map.type() == sum.type());
    const auto* in = map.ptr<double>();
    auto* s = sum.ptr<double>();
    auto* c = n.ptr<double>();
    for (std::size_t k = 0; k < map.total() * static_cast<std::size_t>(map.channels()); ++k)
      if (std::isfinite(in[k])) {
        s[k] += in[k];
        c[k] += 1.0;
      }
  }
  auto* s = sum.ptr<double>();
  const auto* c = n.ptr<double>();
  for (std::size_t k = 0; k < sum.total() * static_cast<std::size_t>(sum.channels()); ++k)
    s[k] = c[k] > 0.0 ? s[k] / c[k] : std::numeric_limits<double>::quiet_NaN();
  if (count) *count = n;
  return sum;
}

}  // namespace tirstrain::strain
