#include "flow/bspline.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace tirstrain::flow {
namespace {

// The cubic B-spline's pole: the coefficients are the pixels through the filter 6 / (z⁻¹ + 4 + z), one
// causal and one anti-causal first-order recursion with this pole and gain (1 − z)(1 − 1/z).
const double kPole = std::sqrt(3.0) - 2.0;
const double kGain = (1.0 - kPole) * (1.0 - 1.0 / kPole);
// Terms of the causal recursion's mirror-symmetric start: |z|^k falls below 1e-7 of the first.
constexpr int kStartTerms = 13;

// One line of n samples `stride` apart, in place (n ≥ 2).
void filter_line(float* c, int n, std::ptrdiff_t stride, std::vector<double>& v) {
  v.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) v[static_cast<std::size_t>(i)] = kGain * c[i * stride];
  double start = v[0], zk = kPole;
  for (int k = 1; k < std::min(n, kStartTerms); ++k, zk *= kPole)
    start += zk * v[static_cast<std::size_t>(k)];
  v[0] = start;
  for (int k = 1; k < n; ++k) v[static_cast<std::size_t>(k)] += kPole * v[static_cast<std::size_t>(k - 1)];
  const std::size_t last = static_cast<std::size_t>(n - 1);
  v[last] = (kPole / (kPole * kPole - 1.0)) * (kPole * v[last - 1] + v[last]);
  for (int k = n - 2; k >= 0; --k)
    v[static_cast<std::size_t>(k)] =
        kPole * (v[static_cast<std::size_t>(k + 1)] - v[static_cast<std::size_t>(k)]);
  for (int i = 0; i < n; ++i) c[i * stride] = static_cast<float>(v[static_cast<std::size_t>(i)]);
}

}  // namespace

void cubic_bspline_coefficients(const cv::Mat& image, cv::Rect region, cv::Mat& coefficients) {
  CV_Assert(image.type() == CV_32F);
  region &= cv::Rect(0, 0, image.cols, image.rows);
  if (coefficients.size() != image.size() || coefficients.type() != CV_32F || coefficients.data == image.data)
    coefficients.create(image.size(), CV_32F);
  image.copyTo(coefficients);
  if (region.width < 2 || region.height < 2) return;
  cv::Mat c = coefficients(region);
  const std::ptrdiff_t row_stride = static_cast<std::ptrdiff_t>(c.step1());
  cv::parallel_for_(cv::Range(0, c.rows), [&](const cv::Range& rows) {
    std::vector<double> v;
    for (int y = rows.start; y < rows.end; ++y) filter_line(c.ptr<float>(y), c.cols, 1, v);
  });
  cv::parallel_for_(cv::Range(0, c.cols), [&](const cv::Range& cols) {
    std::vector<double> v;
    for (int x = cols.start; x < cols.end; ++x) filter_line(c.ptr<float>(0) + x, c.rows, row_stride, v);
  });
}

}  // namespace tirstrain::flow
