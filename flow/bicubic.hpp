#pragma once
// Cubic interpolation kernels shared by the subset matcher, the resampled shape pass and the mesh
// correlation (internal to flow/): Keys' cubic convolution of pixel values, and the cubic B-spline of an
// image's spline coefficients (flow/bspline.hpp).
#include <opencv2/core.hpp>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "flow/bspline.hpp"
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

// The cubic B-spline's four weights, (1 − t)³/6, (3t³ − 6t² + 4)/6, (−3t³ + 3t² + 3t + 1)/6, t³/6, in the
// same Horner form.
inline __m128 bspline_weights(float t) {
  const __m128 vt = _mm_set1_ps(t);
  __m128 w = _mm_add_ps(_mm_mul_ps(_mm_setr_ps(-1.0f / 6.0f, 0.5f, -0.5f, 1.0f / 6.0f), vt),
                        _mm_setr_ps(0.5f, -1.0f, 0.5f, 0.0f));
  w = _mm_add_ps(_mm_mul_ps(w, vt), _mm_setr_ps(-0.5f, 0.0f, 0.5f, 0.0f));
  return _mm_add_ps(_mm_mul_ps(w, vt), _mm_setr_ps(1.0f / 6.0f, 2.0f / 3.0f, 1.0f / 6.0f, 0.0f));
}

inline __m128 kernel_weights(Interpolation kernel, float t) {
  return kernel == Interpolation::kCubicBSpline ? bspline_weights(t) : keys_weights(t);
}

inline float interpolate_with(const __m128 wx, const __m128 wy, const float* row, std::size_t step) {
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

inline float interpolate_keys(const float* row, std::size_t step, float tx, float ty) {
  return interpolate_with(keys_weights(tx), keys_weights(ty), row, step);
}

// The 4×4 neighbourhood under `kernel`: pixel values for Keys, spline coefficients for the B-spline.
inline float interpolate(Interpolation kernel, const float* row, std::size_t step, float tx, float ty) {
  return interpolate_with(kernel_weights(kernel, tx), kernel_weights(kernel, ty), row, step);
}
#else
inline void keys_weights(float t, float w[4]) {
  w[0] = ((-0.5f * t + 1.0f) * t - 0.5f) * t;
  w[1] = ((1.5f * t - 2.5f) * t) * t + 1.0f;
  w[2] = ((-1.5f * t + 2.0f) * t + 0.5f) * t;
  w[3] = ((0.5f * t - 0.5f) * t) * t;
}

inline void bspline_weights(float t, float w[4]) {
  const float s = 1.0f - t;
  w[0] = s * s * s / 6.0f;
  w[1] = ((0.5f * t - 1.0f) * t) * t + 2.0f / 3.0f;
  w[2] = ((-0.5f * t + 0.5f) * t + 0.5f) * t + 1.0f / 6.0f;
  w[3] = t * t * t / 6.0f;
}

inline void kernel_weights(Interpolation kernel, float t, float w[4]) {
  if (kernel == Interpolation::kCubicBSpline)
    bspline_weights(t, w);
  else
    keys_weights(t, w);
}

inline float interpolate_with(const float wx[4], const float wy[4], const float* row, std::size_t step) {
  float sum = 0.0f;
  for (int k = 0; k < 4; ++k, row += step)
    sum += wy[k] * (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
  return sum;
}

inline float interpolate_keys(const float* row, std::size_t step, float tx, float ty) {
  float wx[4], wy[4];
  keys_weights(tx, wx);
  keys_weights(ty, wy);
  return interpolate_with(wx, wy, row, step);
}

inline float interpolate(Interpolation kernel, const float* row, std::size_t step, float tx, float ty) {
  float wx[4], wy[4];
  kernel_weights(kernel, tx, wx);
  kernel_weights(kernel, ty, wy);
  return interpolate_with(wx, wy, row, step);
}
#endif

// The kernel's four weights at fraction t, as the interpolation above computes them.
inline void weights_of(Interpolation kernel, float t, float w[4]) {
#if defined(__SSE2__)
  _mm_storeu_ps(w, kernel_weights(kernel, t));
#else
  kernel_weights(kernel, t, w);
#endif
}

// Sampling under a pure translation: every pixel moves by the same fraction of a pixel, so the weights are
// computed once and the frame is filtered separably, each row's vertical sums shared by four output pixels
// (8 products a pixel instead of 16, and no weights). The arithmetic is interpolate_keys', term for term
// (vertical first, then the horizontal pairs), so the values agree with Sampler's to float rounding; the
// only difference is that Sampler takes each pixel's fraction from its own (integer + shift) in double.
// Pixels must come row by row (dy not decreasing).
class TranslatedSampler {
 public:
  // Offset (0, 0) lands at (x0, y0); offsets dx lie in [dx_min, dx_max]. Refuses (ok() false) a shift
  // that is not finite or is far outside the image.
  // Keeps raw pointers (as Sampler does), not the matrices: a temporary empty mask may be passed.
  TranslatedSampler(const cv::Mat& image, const cv::Mat& mask, double x0, double y0, int dx_min, int dx_max,
                    Interpolation kernel = Interpolation::kKeys)
      : data_(image.ptr<float>()),
        step_(image.step1()),
        cols_(image.cols),
        rows_(image.rows),
        mask_(mask.empty() ? nullptr : mask.ptr<std::uint8_t>()),
        mask_step_(mask.empty() ? 0 : mask.step1()),
        dx_min_(dx_min),
        dx_max_(dx_max) {
    CV_Assert(image.type() == CV_32F &&
              (mask.empty() || (mask.type() == CV_8U && mask.size() == image.size())));
    ok_ = std::abs(x0) < 1e6 && std::abs(y0) < 1e6;  // also false for NaN
    if (!ok_) return;
    ix0_ = static_cast<int>(std::floor(x0));
    iy0_ = static_cast<int>(std::floor(y0));
    const double fx = x0 - ix0_, fy = y0 - iy0_;
    weights_of(kernel, static_cast<float>(fx), wx_);
    weights_of(kernel, static_cast<float>(fy), wy_);
    mask_dx_ = fx + 0.5 >= 1.0 ? 1 : 0;
    mask_dy_ = fy + 0.5 >= 1.0 ? 1 : 0;
    vertical_.resize(static_cast<std::size_t>(dx_max - dx_min + 4));
  }
  bool ok() const { return ok_; }

  bool sample(int dx, int dy, float& value) {
    if (dy != row_dy_) start_row(dy);
    const int ix = ix0_ + dx;
    if (!row_ok_ || ix < 1 || ix > cols_ - 3) return false;
    if (mask_row_ && mask_row_[ix + mask_dx_] == 0) return false;
    const float* v = vertical_.data() + (dx - dx_min_);  // v[k] is column ix - 1 + k
    value = (v[0] * wx_[0] + v[1] * wx_[1]) + (v[2] * wx_[2] + v[3] * wx_[3]);
    return true;
  }

 private:
  void start_row(int dy) {
    row_dy_ = dy;
    const int iy = iy0_ + dy;
    row_ok_ = iy >= 1 && iy <= rows_ - 3;
    if (!row_ok_) return;
    mask_row_ = mask_ ? mask_ + static_cast<std::size_t>(iy + mask_dy_) * mask_step_ : nullptr;
    const float* r0 = data_ + static_cast<std::size_t>(iy - 1) * step_;
    const std::size_t step = step_;
    // Columns ix0 + dx_min - 1 ... ix0 + dx_max + 2, clipped to the image (a pixel whose support leaves
    // it is refused above).
    const int c0 = ix0_ + dx_min_ - 1;
    const int lo = std::max(0, c0), hi = std::min(cols_ - 1, ix0_ + dx_max_ + 2);
    for (int c = lo; c <= hi; ++c) {
      const float* p = r0 + c;
      vertical_[static_cast<std::size_t>(c - c0)] =
          ((p[0] * wy_[0] + p[step] * wy_[1]) + p[2 * step] * wy_[2]) + p[3 * step] * wy_[3];
    }
  }

  const float* data_;
  std::size_t step_;
  int cols_, rows_;
  const std::uint8_t* mask_;
  std::size_t mask_step_;
  int dx_min_, dx_max_;
  bool ok_ = false;
  int ix0_ = 0, iy0_ = 0, mask_dx_ = 0, mask_dy_ = 0;
  float wx_[4] = {}, wy_[4] = {};
  int row_dy_ = INT_MIN;
  bool row_ok_ = false;
  const std::uint8_t* mask_row_ = nullptr;
  std::vector<float> vertical_;
};

// The current frame and its mask, as raw pointers: the match loop samples every subset pixel per
// iteration, and going through cv::Mat accessors there cost a fifth of the tracker's time.
class Sampler {
 public:
  // `image`: the pixel values for Keys, the spline coefficients for the B-spline.
  Sampler(const cv::Mat& image, const cv::Mat& mask, Interpolation kernel = Interpolation::kKeys)
      : kernel_(kernel),
        data_(image.ptr<float>()),
        step_(image.step1()),
        cols_(image.cols),
        rows_(image.rows),
        mask_(mask.empty() ? nullptr : mask.ptr<std::uint8_t>()),
        mask_step_(mask.empty() ? 0 : mask.step1()) {
    CV_Assert(image.type() == CV_32F &&
              (mask.empty() || (mask.type() == CV_8U && mask.size() == image.size())));
  }

  Interpolation kernel() const { return kernel_; }

  // The interpolated value at (x, y), if its 4×4 support is inside the image and the nearest pixel inside the
  // mask. Written for x, y ≥ 1, where truncation is the floor and x + 0.5 truncated the nearest pixel.
  bool sample(double x, double y, float& value) const {
    // Bounds checked on the doubles: a runaway warp's 1e12 must not reach the int conversion (undefined;
    // INT_MIN on x86, which an integer check would let through). Also rejects NaN.
    if (!(x >= 1.0 && y >= 1.0 && x < cols_ - 2 && y < rows_ - 2)) return false;
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    if (mask_ && mask_[static_cast<std::size_t>(static_cast<int>(y + 0.5)) * mask_step_ +
                       static_cast<std::size_t>(static_cast<int>(x + 0.5))] == 0)
      return false;
    value = detail::interpolate(kernel_, data_ + static_cast<std::size_t>(iy - 1) * step_ + (ix - 1), step_,
                                static_cast<float>(x - ix), static_cast<float>(y - iy));
    return true;
  }

 private:
  Interpolation kernel_;
  const float* data_;
  std::size_t step_;
  int cols_, rows_;
  const std::uint8_t* mask_;
  std::size_t mask_step_;
};

}  // namespace tirstrain::flow::detail
