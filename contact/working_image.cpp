#include "contact/working_image.hpp"

#include <algorithm>
#include <limits>

namespace tirstrain::contact {
namespace {

// Means of factor x factor blocks, times `gain`, and the number of pixels >= `saturation` over the whole
// image (counted on the way, so the frame is read once). Columns are summed first in the source's integer
// type widened to Acc (vectorises; no per-pixel float conversion), then each block's columns.
template <typename T, typename Acc>
std::size_t block_average(const cv::Mat& src, int factor, double gain, double saturation, cv::Mat& dst,
                          std::vector<Acc>& column_sum) {
  const int out_w = src.cols / factor, out_h = src.rows / factor;
  dst.create(out_h, out_w, CV_32FC1);
  const auto at_full_scale = [&](int y) {
    const T* in = src.ptr<T>(y);
    std::size_t count = 0;
    for (int x = 0; x < src.cols; ++x) count += static_cast<double>(in[x]) >= saturation ? 1 : 0;
    return count;
  };
  std::size_t saturated = 0;
  // Narrower or shorter than one block: nothing to average (and no row pointer of an empty Mat to take).
  if (out_w <= 0 || out_h <= 0) {
    for (int y = 0; y < src.rows; ++y) saturated += at_full_scale(y);
    return saturated;
  }
  const auto limit = static_cast<T>(std::min(saturation, static_cast<double>(std::numeric_limits<T>::max())));
  const int used_w = out_w * factor;
  // Per column: the block's sum, and how many of its pixels so far were at full scale (same lane width, so
  // both loops vectorise).
  column_sum.resize(2 * static_cast<std::size_t>(src.cols));
  Acc* acc = column_sum.data();
  Acc* at_limit = acc + src.cols;
  std::fill(at_limit, at_limit + src.cols, Acc{0});
  const auto g = static_cast<float>(gain / (factor * factor));
  for (int y = 0; y < out_h; ++y) {
    for (int r = 0; r < factor; ++r) {
      const T* in = src.ptr<T>(y * factor + r);
      const Acc keep = r == 0 ? 0 : 1;  // the first row of a block starts the sums
      for (int x = 0; x < src.cols; ++x) {
        acc[x] = static_cast<Acc>(acc[x] * keep + static_cast<Acc>(in[x]));
        at_limit[x] = static_cast<Acc>(at_limit[x] + (in[x] >= limit ? 1 : 0));
      }
    }
    // Flush the counts before they could overflow the lane (a 16-bit lane holds 65535 rows).
    if ((y + 1) % 4096 == 0) {
      for (int x = 0; x < src.cols; ++x) saturated += at_limit[x];
      std::fill(at_limit, at_limit + src.cols, Acc{0});
    }
    float* out = dst.ptr<float>(y);
    for (int x = 0, k0 = 0; k0 < used_w; ++x, k0 += factor) {
      std::uint32_t s = 0;
      for (int k = 0; k < factor; ++k) s += static_cast<std::uint32_t>(acc[k0 + k]);
      out[x] = static_cast<float>(s) * g;
    }
  }
  for (int x = 0; x < src.cols; ++x) saturated += at_limit[x];
  for (int y = out_h * factor; y < src.rows; ++y) saturated += at_full_scale(y);
  return saturated;
}

// Float images: the same in float (no saturation: float frames carry no full-scale code).
void block_average_float(const cv::Mat& src, int factor, double gain, cv::Mat& dst,
                         std::vector<float>& row_sum) {
  const int out_w = src.cols / factor, out_h = src.rows / factor;
  dst.create(out_h, out_w, CV_32FC1);
  if (out_w <= 0 || out_h <= 0) return;
  row_sum.resize(static_cast<std::size_t>(src.cols));
  float* acc = row_sum.data();
  const auto g = static_cast<float>(gain / (factor * factor));
  for (int y = 0; y < out_h; ++y) {
    for (int r = 0; r < factor; ++r) {
      const float* in = src.ptr<float>(y * factor + r);
      if (r == 0) {
        std::copy(in, in + src.cols, acc);
      } else {
        for (int x = 0; x < src.cols; ++x) acc[x] += in[x];
      }
    }
    float* out = dst.ptr<float>(y);
    for (int x = 0; x < out_w; ++x) {
      float s = 0.0f;
      for (int k = 0; k < factor; ++k) s += acc[x * factor + k];
      out[x] = s * g;
    }
  }
}

}  // namespace

std::size_t count_at_full_scale(const cv::Mat& image, double full_scale, WorkingImageBuffers& buffers) {
  cv::compare(image, full_scale, buffers.at_full_scale, cv::CMP_GE);
  return static_cast<std::size_t>(cv::countNonZero(buffers.at_full_scale));
}

std::size_t to_working_image(const cv::Mat& image, int factor, double full_scale, cv::Mat& out,
                             WorkingImageBuffers& buffers) {
  const double gain = 1.0 / full_scale;
  if (factor == 1 || image.depth() == CV_32F) {
    if (factor == 1) {
      image.convertTo(out, CV_32F, gain);
    } else {
      block_average_float(image, factor, gain, out, buffers.row_sum);
    }
    if (image.depth() == CV_32F) return 0;
    return count_at_full_scale(image, full_scale, buffers);
  }
  // 8-bit: a column sum of up to 16 rows fits 16 bits (16 x 255); 16-bit data needs 32.
  if (image.depth() == CV_8U && factor <= 16)
    return block_average<std::uint8_t, std::uint16_t>(image, factor, gain, full_scale, out, buffers.sum_u16);
  if (image.depth() == CV_8U)
    return block_average<std::uint8_t, std::uint32_t>(image, factor, gain, full_scale, out, buffers.sum_u32);
  return block_average<std::uint16_t, std::uint32_t>(image, factor, gain, full_scale, out, buffers.sum_u32);
}

}  // namespace tirstrain::contact
