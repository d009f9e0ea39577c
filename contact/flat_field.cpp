#include "contact/flat_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace tirstrain::contact {

std::optional<QuadraticSurface> fit_background(const cv::Mat& image, const cv::Mat& exclude,
                                               cv::Point2d centre, int min_pixels) {
  constexpr int kStride = 3;
  std::array<int, 8> per_sector{};
  QuadraticSurface surface;
  surface.x0 = 0.5 * (image.cols - 1);
  surface.y0 = 0.5 * (image.rows - 1);
  surface.scale = 2.0 / std::max(1, std::max(image.cols, image.rows));
  cv::Matx66d normal = cv::Matx66d::zeros();
  cv::Vec6d rhs(0, 0, 0, 0, 0, 0);
  double sum_z2 = 0.0;
  int count = 0;
  for (int y = 0; y < image.rows; y += kStride) {
    const float* row = image.ptr<float>(y);
    const std::uint8_t* skip = exclude.ptr<std::uint8_t>(y);
    const double v = (y - surface.y0) * surface.scale;
    for (int x = 0; x < image.cols; x += kStride) {
      if (skip[x] != 0) continue;
      const double u = (x - surface.x0) * surface.scale, z = row[x];
      const double basis[6] = {1.0, u, v, u * u, u * v, v * v};
      for (int i = 0; i < 6; ++i) {
        for (int j = i; j < 6; ++j) normal(i, j) += basis[i] * basis[j];
        rhs[i] += basis[i] * z;
      }
      sum_z2 += z * z;
      ++count;
      // Sector of the direction from the centre: octant by the signs and the larger of |dx|, |dy|.
      const double dx = x - centre.x, dy = y - centre.y;
      const int octant = (dy < 0 ? 4 : 0) + (dx < 0 ? 2 : 0) + (std::abs(dx) < std::abs(dy) ? 1 : 0);
      ++per_sector[static_cast<std::size_t>(octant)];
    }
  }
  if (count < min_pixels) return std::nullopt;
  for (const int n : per_sector)
    if (n < min_pixels / 16) return std::nullopt;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < i; ++j) normal(i, j) = normal(j, i);
  cv::Vec6d solution;
  if (!cv::solve(normal, rhs, solution, cv::DECOMP_CHOLESKY)) return std::nullopt;
  for (int i = 0; i < 6; ++i)
    if (!std::isfinite(solution[i])) return std::nullopt;  // non-finite pixels (float frames): no surface
  for (int i = 0; i < 6; ++i) surface.c[static_cast<std::size_t>(i)] = solution[i];
  // Least squares: the residual sum of squares is z.z - c.(A^T z).
  surface.residual_rms = std::sqrt(std::max(0.0, (sum_z2 - solution.dot(rhs)) / count));
  return surface;
}

void flatten(const cv::Mat& work, const QuadraticSurface& background, int polarity, cv::Mat& bright) {
  bright.create(work.size(), CV_32F);
  double darkest = std::numeric_limits<double>::infinity();
  for (const auto& corner :
       {cv::Point(0, 0), cv::Point(work.cols - 1, 0), cv::Point(0, work.rows - 1),
        cv::Point(work.cols - 1, work.rows - 1), cv::Point(work.cols / 2, work.rows / 2)})
    darkest = std::min(darkest, background(corner.x, corner.y));
  const bool divide = darkest >= 0.05;
  const float sign = polarity < 0 ? -1.0f : 1.0f;
  std::vector<float> surface_row(static_cast<std::size_t>(work.cols));
  for (int y = 0; y < work.rows; ++y) {
    for (int x = 0; x < work.cols; ++x)
      surface_row[static_cast<std::size_t>(x)] = static_cast<float>(background(x, y));
    const float* in = work.ptr<float>(y);
    const float* b = surface_row.data();
    float* out = bright.ptr<float>(y);
    if (divide) {
      for (int x = 0; x < work.cols; ++x) out[x] = sign * (in[x] / b[x] - 1.0f);
    } else {
      for (int x = 0; x < work.cols; ++x) out[x] = sign * (in[x] - b[x]);
    }
  }
}

}  // namespace tirstrain::contact
