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

// One row of n contiguous samples, in place (n ≥ 2), in double.
void filter_row(float* c, int n, std::vector<double>& v) {
  v.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) v[static_cast<std::size_t>(i)] = kGain * c[i];
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
  for (int i = 0; i < n; ++i) c[i] = static_cast<float>(v[static_cast<std::size_t>(i)]);
}

// The same recursions down the columns of `c`, a band of columns at a time and row by row within it, so
// that every step reads and writes contiguous memory (a column walked alone misses the cache at every pixel).
void filter_columns(cv::Mat& c, int first, int last) {
  const int rows = c.rows;
  const auto row = [&](int y) { return c.ptr<float>(y); };
  const float z = static_cast<float>(kPole), gain = static_cast<float>(kGain);
  for (int y = 0; y < rows; ++y)
    for (int x = first; x < last; ++x) row(y)[x] *= gain;
  std::vector<float> start(static_cast<std::size_t>(last - first), 0.0f);
  float zk = 1.0f;
  for (int k = 0; k < std::min(rows, kStartTerms); ++k, zk *= z)
    for (int x = first; x < last; ++x) start[static_cast<std::size_t>(x - first)] += zk * row(k)[x];
  for (int x = first; x < last; ++x) row(0)[x] = start[static_cast<std::size_t>(x - first)];
  for (int y = 1; y < rows; ++y)
    for (int x = first; x < last; ++x) row(y)[x] += z * row(y - 1)[x];
  const float end = z / (z * z - 1.0f);
  for (int x = first; x < last; ++x) row(rows - 1)[x] = end * (z * row(rows - 2)[x] + row(rows - 1)[x]);
  for (int y = rows - 2; y >= 0; --y)
    for (int x = first; x < last; ++x) row(y)[x] = z * (row(y + 1)[x] - row(y)[x]);
}

}  // namespace

void cubic_bspline_coefficients(const cv::Mat& image, cv::Rect region, cv::Mat& coefficients) {
  CV_Assert(image.type() == CV_32F);
  region &= cv::Rect(0, 0, image.cols, image.rows);
  // Outside the region the pixel values stand in (nothing samples there); they are copied once, when the
  // buffer is new, and the region every call.
  if (coefficients.size() != image.size() || coefficients.type() != CV_32F ||
      coefficients.data == image.data) {
    coefficients.create(image.size(), CV_32F);
    image.copyTo(coefficients);
  } else {
    image(region).copyTo(coefficients(region));
  }
  if (region.width < 2 || region.height < 2) return;
  cv::Mat c = coefficients(region);
  cv::parallel_for_(cv::Range(0, c.rows), [&](const cv::Range& rows) {
    std::vector<double> v;
    for (int y = rows.start; y < rows.end; ++y) filter_row(c.ptr<float>(y), c.cols, v);
  });
  constexpr int kBand = 64;
  const int bands = (c.cols + kBand - 1) / kBand;
  cv::parallel_for_(cv::Range(0, bands), [&](const cv::Range& r) {
    for (int b = r.start; b < r.end; ++b) filter_columns(c, b * kBand, std::min(c.cols, (b + 1) * kBand));
  });
}

}  // namespace tirstrain::flow
