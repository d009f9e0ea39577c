#pragma once
// Keys bicubic interpolation kernel shared by the subset matcher, the resampled shape pass and the mesh
// correlation (internal to flow/).
#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tirstrain::flow::detail {

// Keys cubic convolution (a = −0.5) of the 4×4 neighbourhood whose top-left sample is `row[0]`, at the
// fraction (tx, ty) ∈ [0, 1) past its second row and column. The weights w(t) = ((A t + B) t + C) t + D per
// tap; the SSE2 path evaluates all four taps of a direction in one vector, and this kernel is most of the
// tracker's time.
#if defined(__SSE2__)
inline __m128 keys_weights(float t) {
  const __m128 vt = _mm_set1_ps(t);
  __m128 w = _mm_add_ps(_mm_mul_ps(_mm_setr_ps(-0.5f, 1.5f, -1.5f, 0.5f), vt),
                        _mm_setr_ps(1.0f, -2.5f, 2.0f, -0.5f));
  w = _mm_add_ps(_mm_mul_ps(w, vt), _mm_setr_ps(-0.5f, 0.0f, 0.5f, 0.0f));
  return _mm_add_ps(_mm_mul_ps(w, vt), _mm_setr_ps(0.0f, 1.0f, 0.0f, 0.0f));
}

inline float interpolate_keys(const float* row, std::size_t step, float tx, float ty) {
  const __m128 wx = keys_weights(tx), wy = keys_weights(ty);
  __m128 acc = _mm_mul_ps(_mm_loadu_ps(row), _mm_shuffle_ps(wy, wy, 0x00));
  acc = _mm_add_ps(acc, _mm_mul_ps(_mm_loadu_ps(row + step), _mm_shuffle_ps(wy, wy, 0x55)));
  acc = _mm_add_ps(acc, _mm_mul_ps(_mm_loadu_ps(row + 2 * step), _mm_shuffle_ps(wy, wy, 0xAA)));
  acc = _mm_add_ps(acc, _mm_mul_ps(_mm_loadu_ps(row + 3 * step), _mm_shuffle_ps(wy, wy, 0xFF)));
  acc = _mm_mul_ps(acc, wx);
  __m128 swapped = _mm_shuffle_ps(acc, acc, _MM_SHUFFLE(2, 3, 0, 1));
  const __m128 pairs = _mm_add_ps(acc, swapped);
  swapped = _mm_movehl_ps(swapped, pairs);
  return _mm_cvtss_f32(_mm_add_ss(pairs, swapped));
}
#else
inline void keys_weights(float t, float w[4]) {
  w[0] = ((-0.5f * t + 1.0f) * t - 0.5f) * t;
  w[1] = ((1.5f * t - 2.5f) * t) * t + 1.0f;
  w[2] = ((-1.5f * t + 2.0f) * t + 0.5f) * t;
  w[3] = ((0.5f * t - 0.5f) * t) * t;
}

inline float interpolate_keys(const float* row, std::size_t step, float tx, float ty) {
  float wx[4], wy[4];
  keys_weights(tx, wx);
  keys_weights(ty, wy);
  float sum = 0.0f;
  for (int k = 0; k < 4; ++k, row += step)
    sum += wy[k] * (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
  return sum;
}
#endif

// The current frame and its mask, as raw pointers: the match loop samples every subset pixel per
// iteration, and going through cv::Mat accessors there cost a fifth of the tracker's time.
class Sampler {
 public:
  Sampler(const cv::Mat& image, const cv::Mat& mask)
      : data_(image.ptr<float>()),
        step_(image.step1()),
        cols_(image.cols),
        rows_(image.rows),
        mask_(mask.empty() ? nullptr : mask.ptr<std::uint8_t>()),
        mask_step_(mask.empty() ? 0 : mask.step1()) {
    CV_Assert(image.type() == CV_32F &&
              (mask.empty() || (mask.type() == CV_8U && mask.size() == image.size())));
  }

  // Keys bicubic value at (x, y), if its 4×4 support is inside the image and the nearest pixel inside the
  // mask. Written for x, y ≥ 1, where truncation is the floor and x + 0.5 truncated the nearest pixel.
  bool sample(double x, double y, float& value) const {
    // Bounds checked on the doubles: a runaway warp's 1e12 must not reach the int conversion (undefined;
    // INT_MIN on x86, which an integer check would let through). Also rejects NaN.
    if (!(x >= 1.0 && y >= 1.0 && x < cols_ - 2 && y < rows_ - 2)) return false;
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    if (mask_ && mask_[static_cast<std::size_t>(static_cast<int>(y + 0.5)) * mask_step_ +
                       static_cast<std::size_t>(static_cast<int>(x + 0.5))] == 0)
      return false;
    value = detail::interpolate_keys(data_ + static_cast<std::size_t>(iy - 1) * step_ + (ix - 1), step_,
                                     static_cast<float>(x - ix), static_cast<float>(y - iy));
    return true;
  }

 private:
  const float* data_;
  std::size_t step_;
  int cols_, rows_;
  const std::uint8_t* mask_;
  std::size_t mask_step_;
};

}  // namespace tirstrain::flow::detail
