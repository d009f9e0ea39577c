#include "contact/image_stats.hpp"

#include <array>
#include <cstddef>
#include <cstdint>

namespace tirstrain::contact {

OtsuSplit otsu(const cv::Mat& values) {
  double max_value = 0.0;
  cv::minMaxLoc(values, nullptr, &max_value);
  OtsuSplit split;
  if (!(max_value > 0.0)) return split;
  constexpr int kBins = 256;
  const double to_bin = (kBins - 1) / max_value;
  // Counted in four histograms by column: the background is mostly one bin, and in a single histogram each
  // increment would wait on the last.
  std::array<std::array<std::uint32_t, kBins>, 4> counts{};
  for (int y = 0; y < values.rows; ++y) {
    const float* row = values.ptr<float>(y);
    for (int x = 0; x < values.cols; ++x) ++counts[x & 3][static_cast<std::size_t>(row[x] * to_bin + 0.5)];
  }
  std::array<double, kBins> hist{};
  for (std::size_t i = 0; i < kBins; ++i)
    hist[i] = static_cast<double>(counts[0][i]) + counts[1][i] + counts[2][i] + counts[3][i];
  double total = 0.0, total_sum = 0.0;
  for (int i = 0; i < kBins; ++i) {
    total += hist[static_cast<std::size_t>(i)];
    total_sum += i * hist[static_cast<std::size_t>(i)];
  }
  double w0 = 0.0, sum0 = 0.0, best = -1.0;
  int best_bin = 0;
  for (int i = 0; i < kBins - 1; ++i) {
    w0 += hist[static_cast<std::size_t>(i)];
    sum0 += i * hist[static_cast<std::size_t>(i)];
    const double w1 = total - w0;
    if (w0 <= 0.0 || w1 <= 0.0) continue;
    const double m0 = sum0 / w0, m1 = (total_sum - sum0) / w1;
    const double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best) {
      best = between;
      best_bin = i;
      split.mean_low = m0 / to_bin;
      split.mean_high = m1 / to_bin;
    }
  }
  split.threshold = static_cast<float>((best_bin + 0.5) / to_bin);
  return split;
}

MaskedMeans masked_means(const cv::Mat& image, const cv::Mat& mask) {
  MaskedMeans m;
  double inside_sum = 0.0, outside_sum = 0.0;
  std::size_t inside_n = 0;
  // Each row summed in kLanes interleaved float sums (a vector register's worth): one running sum per row
  // waited on its last addition at every pixel.
  constexpr int kLanes = 8;
  for (int y = 0; y < image.rows; ++y) {
    const float* v = image.ptr<float>(y);
    const std::uint8_t* in = mask.ptr<std::uint8_t>(y);
    std::array<float, kLanes> lane_in{}, lane_out{};
    std::array<int, kLanes> lane_n{};
    int x = 0;
    for (; x + kLanes <= image.cols; x += kLanes) {
      for (int l = 0; l < kLanes; ++l) {
        const bool inside = in[x + l] != 0;
        lane_in[l] += inside ? v[x + l] : 0.0f;
        lane_out[l] += inside ? 0.0f : v[x + l];
        lane_n[l] += inside ? 1 : 0;
      }
    }
    for (; x < image.cols; ++x) {
      const bool inside = in[x] != 0;
      lane_in[0] += inside ? v[x] : 0.0f;
      lane_out[0] += inside ? 0.0f : v[x];
      lane_n[0] += inside ? 1 : 0;
    }
    for (int l = 0; l < kLanes; ++l) {
      inside_sum += lane_in[l];
      outside_sum += lane_out[l];
      inside_n += static_cast<std::size_t>(lane_n[l]);
    }
  }
  m.inside_count = static_cast<double>(inside_n);
  m.outside_count = static_cast<double>(image.total() - inside_n);
  if (m.inside_count > 0.0) m.inside = inside_sum / m.inside_count;
  if (m.outside_count > 0.0) m.outside = outside_sum / m.outside_count;
  return m;
}

}  // namespace tirstrain::contact
