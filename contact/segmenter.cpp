#include "contact/segmenter.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numbers>
#include <numeric>

#include "contact/geometry.hpp"
#include "contact/orientation.hpp"
#include "contact/ridge_labels.hpp"
#include "contact/ridge_period.hpp"
#include "core/error.hpp"

namespace tirstrain::contact {
namespace {

int odd_at_least(double size, int minimum) {
  int k = std::max(minimum, static_cast<int>(std::lround(size)));
  return k % 2 == 0 ? k + 1 : k;
}

// Otsu's threshold on a 256-bin histogram of a non-negative float image.
struct OtsuSplit {
  float threshold = 0.0f;
  double mean_low = 0.0, mean_high = 0.0;
};

OtsuSplit otsu(const cv::Mat& values) {
  double max_value = 0.0;
  cv::minMaxLoc(values, nullptr, &max_value);
  OtsuSplit split;
  if (!(max_value > 0.0)) return split;
  constexpr int kBins = 256;
  const double to_bin = (kBins - 1) / max_value;
  // Counted in four histograms by column: the background is mostly one bin, and in one histogram each
  // increment waited on the last (a quarter of segment_region's own time under perf, now a tenth).
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

// Inlined: the edge search calls it ~100 times per ray, and out of line the call was a fifth of its cost.
[[gnu::always_inline]] inline float bilinear(const cv::Mat& image, double x, double y) {
  x = std::clamp(x, 0.0, image.cols - 1.0);
  y = std::clamp(y, 0.0, image.rows - 1.0);
  const int x0 = std::min(static_cast<int>(x), image.cols - 2),
            y0 = std::min(static_cast<int>(y), image.rows - 2);
  const double fx = x - x0, fy = y - y0;
  const float* r0 = image.ptr<float>(y0);
  const float* r1 = image.ptr<float>(y0 + 1);
  return static_cast<float>((1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) +
                            fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]));
}

// Ridges near the contact border run along it, so averaging along the border keeps their profile across it
// while the pixel noise drops by up to sqrt(2 half_taps + 1). "Along the border" is along the ellipse
// through the pixel that is concentric with and similar to `shape` (2 half_taps + 1 samples about one pixel
// apart). Only pixels within `band_px` of `shape` (in its normalised radius) are averaged, the others copied:
// the edge search and the closing before it look no further. Never closer to the centre than 0.3 of the
// radius: there the arcs are short and, at the centre itself, undefined.
void average_along_border(const cv::Mat& src, const Ellipse& shape, int half_taps, double band_px,
                          cv::Mat& dst) {
  dst.create(src.size(), CV_32F);
  const double c = std::cos(shape.angle_rad), s = std::sin(shape.angle_rad);
  const double a = shape.semi_major_px, b = shape.semi_minor_px;
  const double rho_min = std::max(0.3, 1.0 - band_px / b), rho_max = 1.0 + band_px / b;
  const double inv_taps = 1.0 / (2 * half_taps + 1);
  for (int y = 0; y < src.rows; ++y) {
    float* out = dst.ptr<float>(y);
    const float* in = src.ptr<float>(y);
    for (int x = 0; x < src.cols; ++x) {
      const double dx = x - shape.cx_px, dy = y - shape.cy_px;
      const double nx = (c * dx + s * dy) / a, ny = (-s * dx + c * dy) / b;
      const double rho2 = nx * nx + ny * ny;
      if (rho2 < rho_min * rho_min || rho2 > rho_max * rho_max) {
        out[x] = in[x];
        continue;
      }
      const double rho = std::sqrt(rho2);
      const double cos_phi = nx / rho, sin_phi = ny / rho;
      // One pixel of arc: |d(a cos, b sin)/dphi| = sqrt(a^2 sin^2 + b^2 cos^2) per unit phi at rho = 1. Below
      // 0.2 rad (the usual case) two Taylor terms are exact to 1e-5; small contacts near rho_min take more.
      const double step = 1.0 / (rho * std::sqrt(a * a * sin_phi * sin_phi + b * b * cos_phi * cos_phi));
      const double cs = step < 0.2 ? 1.0 - 0.5 * step * step : std::cos(step);
      const double sn = step < 0.2 ? step * (1.0 - step * step / 6.0) : std::sin(step);
      double sum = in[x];
      for (int side = -1; side <= 1; side += 2) {
        double u = cos_phi, v = sin_phi;
        for (int j = 1; j <= half_taps; ++j) {
          const double un = u * cs - side * v * sn, vn = v * cs + side * u * sn;
          u = un;
          v = vn;
          const double ex = rho * a * u, ey = rho * b * v;
          sum += bilinear(src, shape.cx_px + c * ex - s * ey, shape.cy_px + s * ex + c * ey);
        }
      }
      out[x] = static_cast<float>(sum * inv_taps);
    }
  }
}

// A smooth background under the contact: a quadratic surface in x and y (vignetting and the light's tilt),
// least-squares fitted to every 3rd pixel each way of `image` where `exclude` is zero (a smooth surface needs
// no more), with the RMS residual of those pixels. Returns nothing when fewer than `min_pixels` are left, or
// when the background does not surround `centre` (every 45-degree sector around it must hold
// `min_pixels` / 16 of them): a surface extrapolated across the contact from one side or from the frame's
// corners is no better a background than the level measured along each ray.
struct QuadraticSurface {
  std::array<double, 6> c{};  // 1, u, v, u^2, uv, v^2 with u, v the pixel's position scaled to [-1, 1]
  double x0 = 0.0, y0 = 0.0, scale = 1.0;
  double residual_rms = 0.0;
  double operator()(double x, double y) const {
    const double u = (x - x0) * scale, v = (y - y0) * scale;
    return c[0] + c[1] * u + c[2] * v + c[3] * u * u + c[4] * u * v + c[5] * v * v;
  }
};

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

// Ridges made bright on a flat background. Dividing by the background surface removes the illumination's
// shape from both the background and the ridge contrast it scales; where the background is nearly black
// (bright ridges on a dark field) the division would amplify noise, and the surface is subtracted instead.
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

// Mean of a float image inside a mask (non-zero) and outside it, in one pass.
struct MaskedMeans {
  double inside = 0.0, outside = 0.0, inside_count = 0.0, outside_count = 0.0;
};

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

// Working pixel centre -> full-resolution pixel coordinates.
cv::Point2d to_full(const cv::Point2d& p, int factor) {
  return {(p.x + 0.5) * factor - 0.5, (p.y + 0.5) * factor - 0.5};
}

// Noise can carry a single ray's edge outward, and the convex hull keeps any outward excursion. Clip each
// free point's distance from `centre` to the median of its 11 neighbours (free ones) plus `spike_px`.
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
    const auto middle = window.begin() + static_cast<std::ptrdiff_t>(window.size() / 2);
    std::nth_element(window.begin(), middle, window.end());
    const double limit = *middle + spike_px;
    if (radius[i] > limit) points[i] = centre + (points[i] - centre) * (limit / radius[i]);
  }
}

// Where a ridge valley lies along the border, the contact edge is invisible (a valley reflects like the
// background), so the outline found there dips inward by up to half a ridge period. Such dips are one-sided,
// which lets an outer-envelope ellipse find them: fit, drop points more than `gap_px` inside, refit (twice),
// and move the dropped points onto the ellipse along their ray from its centre. Points on a cut (frame edge,
// excluded band) neither take part nor move.
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

// An ellipse's elongation and direction as the vector (a - b) / 2 (cos 2 angle, sin 2 angle): directions half
// a turn apart agree, and a near-circle's ill-defined direction carries little weight. Its border's radius is
// (a + b) / 2 + that vector . (cos 2 phi, sin 2 phi) to first order (phi about the centre).
cv::Vec2d shape_vector(const Ellipse& e) {
  const double half_difference = 0.5 * (e.semi_major_px - e.semi_minor_px);
  return {half_difference * std::cos(2.0 * e.angle_rad), half_difference * std::sin(2.0 * e.angle_rad)};
}

// `base` with its shape vector moved `weight` of the way to `other`'s, its mean semi-axis kept.
Ellipse with_blended_shape(const Ellipse& base, const Ellipse& other, double weight) {
  const cv::Vec2d blended = (1.0 - weight) * shape_vector(base) + weight * shape_vector(other);
  const double mean_px = 0.5 * (base.semi_major_px + base.semi_minor_px);
  const double half_difference = std::min(cv::norm(blended), 0.9 * mean_px);
  Ellipse e = base;
  e.semi_major_px = mean_px + half_difference;
  e.semi_minor_px = mean_px - half_difference;
  e.angle_rad = 0.5 * std::atan2(blended[1], blended[0]);
  return e;
}

// For each label of `labels` (CV_32S, `count` labels, 0 background), the smallest distance in pixels from
// its pixels to those of label `from` (0 for `from` itself; infinity for the background and, with no other
// label, for all).
std::vector<double> gaps_to_region(const cv::Mat& labels, int count, int from) {
  std::vector<double> gap(static_cast<std::size_t>(count), std::numeric_limits<double>::infinity());
  if (from > 0 && from < count) gap[static_cast<std::size_t>(from)] = 0.0;
  if (count <= 2) return gap;
  cv::Mat outside, distance;
  cv::compare(labels, from, outside, cv::CMP_NE);
  cv::distanceTransform(outside, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  for (int y = 0; y < labels.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    const float* d = distance.ptr<float>(y);
    for (int x = 0; x < labels.cols; ++x) {
      if (l[x] == 0) continue;
      double& g = gap[static_cast<std::size_t>(l[x])];
      g = std::min(g, static_cast<double>(d[x]));
    }
  }
  return gap;
}

}  // namespace

SegmenterOptions with_preset(SegmenterOptions options, SegmentationPreset preset) {
  const SegmenterOptions accurate;
  options.flat_field = accurate.flat_field;
  options.border_average_snr = accurate.border_average_snr;
  options.ridge_label_centre = accurate.ridge_label_centre;
  options.ridge_label_below_periods = accurate.ridge_label_below_periods;
  options.ridge_label_shape_weight = accurate.ridge_label_shape_weight;
  options.border_band_centre = preset == SegmentationPreset::accurate;
  if (preset == SegmentationPreset::fast) {
    options.flat_field = false;
    options.border_average_snr = 0.0;
    options.ridge_label_centre = false;
    options.ridge_label_below_periods = 0.0;
  }
  return options;
}

std::string contact_status_text(std::uint32_t status) {
  if (status == kContactOk) return "ok";
  static const std::array<const char*, 7> names = {"no_contact",   "touches_edge", "multiple_blobs",
                                                   "saturated",    "low_contrast", "no_ellipse",
                                                   "frame_skipped"};
  std::string text;
  for (std::size_t bit = 0; bit < names.size(); ++bit) {
    if ((status & (1u << bit)) == 0) continue;
    // Appended piecewise: GCC 12 at -O3 reports a false -Wrestrict on `"|" + std::string(...)`.
    if (!text.empty()) text.push_back('|');
    text.append(names[bit]);
  }
  return text.empty() ? "unknown" : text;
}

double full_scale_of(const cv::Mat& image) {
  switch (image.depth()) {
    case CV_8U:
      return 255.0;
    case CV_16U: {
      double max_value = 0.0;
      cv::minMaxLoc(image, nullptr, &max_value);
      for (double scale : {1023.0, 4095.0, 16383.0})
        if (max_value <= scale) return scale;
      return 65535.0;
    }
    default:
      return 1.0;
  }
}

ContactSegmenter::ContactSegmenter(SegmenterOptions options) : options_(std::move(options)) {
  if (options_.ridge_period_px) period_px_ = *options_.ridge_period_px;
}

std::size_t ContactSegmenter::to_working(const cv::Mat& image, int factor, double full_scale, cv::Mat& out) {
  const double gain = 1.0 / full_scale;
  if (factor == 1 || image.depth() == CV_32F) {
    if (factor == 1) {
      image.convertTo(out, CV_32F, gain);
    } else {
      block_average_float(image, factor, gain, out, buf_.row_sum);
    }
    if (image.depth() == CV_32F) return 0;
    cv::compare(image, full_scale, buf_.scratch_u8, cv::CMP_GE);
    return static_cast<std::size_t>(cv::countNonZero(buf_.scratch_u8));
  }
  // 8-bit: a column sum of up to 16 rows fits 16 bits (16 x 255); 16-bit data needs 32.
  if (image.depth() == CV_8U && factor <= 16)
    return block_average<std::uint8_t, std::uint16_t>(image, factor, gain, full_scale, out, buf_.sum_u16);
  if (image.depth() == CV_8U)
    return block_average<std::uint8_t, std::uint32_t>(image, factor, gain, full_scale, out, buf_.sum_u32);
  return block_average<std::uint16_t, std::uint32_t>(image, factor, gain, full_scale, out, buf_.sum_u32);
}

double ContactSegmenter::period_for_frame(const cv::Mat& image, double full_scale) {
  if (period_px_) return *period_px_;
  const double ppmm = options_.px_per_mm;
  // Measured at a resolution where the shortest plausible period still spans >= 3 pixels.
  const int factor = std::max(1, static_cast<int>(std::floor(options_.min_period_mm * ppmm / 3.0)));
  to_working(image, factor, full_scale, buf_.measure);
  const auto estimate =
      estimate_ridge_period(buf_.measure, std::max(2.0, options_.min_period_mm * ppmm / factor),
                            options_.max_period_mm * ppmm / factor);
  if (estimate && estimate->confidence >= options_.min_period_confidence) {
    period_px_ = estimate->period_px * factor;
    period_measured_ = true;
    return *period_px_;
  }
  return options_.default_period_mm * ppmm;
}

ContactResult ContactSegmenter::segment(const cv::Mat& image) {
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F))
    throw Error("contact segmentation needs a grey 8-bit, 16-bit or float image");
  const cv::Rect frame(0, 0, image.cols, image.rows);
  // Tracking: around the last contact, unless a whole frame is due or the region is no longer usable.
  if (options_.track_region && roi_.area() > 0 && image.size() == roi_frame_ &&
      frames_since_full_ + 1 < std::max(1, options_.full_frame_every)) {
    bool left_region = false;
    ContactResult tracked = segment_region(image, roi_, &left_region);
    if (!left_region && (tracked.status & (kNoContact | kNoEllipse)) == 0) {
      ++frames_since_full_;
      update_region(tracked, frame);
      return tracked;
    }
  }
  bool unused = false;
  ContactResult result = segment_region(image, frame, &unused);
  frames_since_full_ = 0;
  update_region(result, frame);
  return result;
}

void ContactSegmenter::update_region(const ContactResult& result, const cv::Rect& frame) {
  roi_ = cv::Rect();
  roi_frame_ = frame.size();
  if (!options_.track_region || (result.status & (kNoContact | kNoEllipse)) != 0) return;
  const cv::Rect& box = result.bounding_box_px;
  const int margin = static_cast<int>(
      std::ceil(std::max(options_.region_margin_periods * result.ridge_period_px,
                         options_.region_margin_fraction * std::max(box.width, box.height))));
  const cv::Rect grown =
      cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) & frame;
  // Not worth it when the region is most of the frame.
  if (grown.area() <= 0.6 * frame.area()) roi_ = grown;
}

ContactResult ContactSegmenter::segment_region(const cv::Mat& image, cv::Rect region, bool* left_region) {
  ContactResult result;
  const cv::Size full_size = image.size();
  const int block_px = std::max(1, options_.block_px);
  const cv::Size blocks((full_size.width + block_px - 1) / block_px,
                        (full_size.height + block_px - 1) / block_px);
  result.orientation_rad = cv::Mat::zeros(blocks, CV_32FC1);
  result.coherence = cv::Mat::zeros(blocks, CV_32FC1);
  if (image.empty()) return result;

  const double full_scale = full_scale_of(image);
  const double period_px = period_for_frame(image, full_scale);
  result.ridge_period_px = period_px;
  factor_ = options_.downsample > 0 ? options_.downsample
            : small_contact_pass_   ? std::max(1, static_cast<int>(std::floor(period_px / 11.0)))
                                    : std::max(1, static_cast<int>(std::floor(period_px / 5.5)));
  const int f = factor_;
  // The region snapped outward to whole orientation blocks that are whole working pixels (its origin on
  // that grid, so blocks and working pixels line up with those of the whole frame).
  const cv::Rect frame(0, 0, full_size.width, full_size.height);
  {
    const int grid = std::lcm(f, block_px);
    const int x0 = region.x / grid * grid, y0 = region.y / grid * grid;
    const int x1 = (region.x + region.width + grid - 1) / grid * grid,
              y1 = (region.y + region.height + grid - 1) / grid * grid;
    region = cv::Rect(x0, y0, x1 - x0, y1 - y0) & frame;
  }
  const bool whole_frame = region == frame;
  // Region sides that are frame sides: only there is an outline point on the side a cut (elsewhere the
  // contact has left the region).
  const bool frame_left = region.x == 0, frame_top = region.y == 0,
             frame_right = region.x + region.width == full_size.width,
             frame_bottom = region.y + region.height == full_size.height;
  const cv::Point2d origin(region.x, region.y);
  // The working image, and the saturated pixels counted in the same pass over the frame.
  std::size_t saturated_pixels = to_working(image(region), f, full_scale, buf_.work);
  if (!whole_frame && image.depth() != CV_32F) {
    cv::compare(image, full_scale, buf_.scratch_u8, cv::CMP_GE);
    saturated_pixels = static_cast<std::size_t>(cv::countNonZero(buf_.scratch_u8));
  }
  result.saturated_fraction = static_cast<double>(saturated_pixels) / static_cast<double>(image.total());
  const bool saturated = result.saturated_fraction >= options_.saturated_fraction;
  const std::uint32_t saturated_flag = saturated ? kSaturated : 0u;
  if (region.width / f < 8 || region.height / f < 8) {
    result.status = kNoContact | saturated_flag;
    return result;
  }
  const double period_w = period_px / f;
  // How far each outline ray looks either side of the coarse hull (working pixels).
  const double reach_w = std::max(3.0, 1.5 * period_w);

  // Difference of Gaussians centred on the ridge band: sigma_small passes the ridge period with gain
  // exp(-2 pi^2 0.15^2) = 0.64 while cutting pixel noise; sigma_large removes illumination and the
  // contact's mean step (gain 0.007 at the ridge period).
  // Kernels truncated at 3 sigma (OpenCV's default for float images is 4 sigma: a third more taps for a
  // tail of 0.3 % of the weight).
  const auto gaussian = [](const cv::Mat& in, cv::Mat& out, double sigma) {
    const int k = 2 * std::max(1, static_cast<int>(std::ceil(3.0 * sigma))) + 1;
    cv::GaussianBlur(in, out, cv::Size(k, k), sigma, sigma, cv::BORDER_REFLECT);
  };
  gaussian(buf_.work, buf_.blur_small, 0.15 * period_w);
  gaussian(buf_.work, buf_.blur_large, 0.5 * period_w);
  cv::subtract(buf_.blur_small, buf_.blur_large, buf_.band);
  cv::absdiff(buf_.band, cv::Scalar::all(0.0), buf_.energy);  // |band| into the reused buffer
  cv::Rect excluded_w;
  if (options_.exclude_px) {
    const cv::Rect& r = *options_.exclude_px;
    const auto down = [&](int v) { return static_cast<int>(std::floor(static_cast<double>(v) / f)); };
    const auto up = [&](int v) { return static_cast<int>(std::ceil(static_cast<double>(v) / f)); };
    excluded_w = cv::Rect(cv::Point(down(r.x - region.x), down(r.y - region.y)),
                          cv::Point(up(r.x + r.width - region.x), up(r.y + r.height - region.y))) &
                 cv::Rect(0, 0, buf_.work.cols, buf_.work.rows);
    buf_.energy(excluded_w).setTo(0.0f);
  }
  // Closing spans half a period (the gap between the rectified peaks of a ridge and the next valley);
  // opening with a full period removes noise specks smaller than a ridge.
  const int close_k = odd_at_least(0.5 * period_w + 1.0, 3);
  const int open_k = odd_at_least(period_w, 3);
  cv::morphologyEx(buf_.energy, buf_.scratch, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(close_k, close_k)), cv::Point(-1, -1),
                   1, cv::BORDER_REPLICATE);
  cv::morphologyEx(buf_.scratch, buf_.energy, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(open_k, open_k)), cv::Point(-1, -1), 1,
                   cv::BORDER_REPLICATE);

  const OtsuSplit split = otsu(buf_.energy);
  result.texture_energy = split.mean_high;
  result.energy_ratio =
      split.mean_low > 0.0 ? split.mean_high / split.mean_low : (split.mean_high > 0.0 ? 1e9 : 0.0);
  result.energy_ratio = std::min(result.energy_ratio, 1e9);
  const auto no_contact = [&] {
    ContactResult empty;
    empty.status = kNoContact | saturated_flag;
    empty.orientation_rad = result.orientation_rad;
    empty.coherence = result.coherence;
    empty.ridge_period_px = period_px;
    empty.texture_energy = result.texture_energy;
    empty.energy_ratio = result.energy_ratio;
    empty.saturated_fraction = result.saturated_fraction;
    return empty;
  };
  if (split.mean_high < options_.min_energy || result.energy_ratio < options_.min_energy_ratio)
    return no_contact();

  cv::compare(buf_.energy, split.threshold, buf_.mask, cv::CMP_GT);
  const int labels =
      cv::connectedComponentsWithStats(buf_.mask, buf_.labels, buf_.stats, buf_.centroids, 8, CV_32S);
  const double mm2_per_working_px = (f * f) / (options_.px_per_mm * options_.px_per_mm);
  int largest = 0, largest_area = 0;
  for (int i = 1; i < labels; ++i) {
    const int area = buf_.stats.at<int>(i, cv::CC_STAT_AREA);
    if (area > largest_area) {
      largest_area = area;
      largest = i;
    }
  }
  if (largest == 0 || largest_area * mm2_per_working_px < options_.min_area_mm2) return no_contact();

  std::uint32_t status = saturated_flag;
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(labels), 0);
  const std::vector<double> gap_w = gaps_to_region(buf_.labels, labels, largest);
  const double max_gap_w = options_.merge_gap_periods * period_w;
  cv::Rect kept_box_w;
  for (int i = 1; i < labels; ++i) {
    const int area = buf_.stats.at<int>(i, cv::CC_STAT_AREA);
    if (i != largest && area * mm2_per_working_px >= options_.min_area_mm2) status |= kMultipleBlobs;
    if (i == largest ||
        (area >= options_.merge_fraction * largest_area && gap_w[static_cast<std::size_t>(i)] <= max_gap_w)) {
      keep[static_cast<std::size_t>(i)] = 1;
      const cv::Rect box(buf_.stats.at<int>(i, cv::CC_STAT_LEFT), buf_.stats.at<int>(i, cv::CC_STAT_TOP),
                         buf_.stats.at<int>(i, cv::CC_STAT_WIDTH), buf_.stats.at<int>(i, cv::CC_STAT_HEIGHT));
      kept_box_w = kept_box_w.area() > 0 ? (kept_box_w | box) : box;
    }
  }
  // A contact only a few ridge periods across is mostly fading border: redo it at twice the resolution
  // (automatic resolution only), on the kept regions' bounding box plus 4 ridge periods, so the extra pass
  // costs little; if the outline reaches that box's side, on the whole frame.
  const double radius_px = std::sqrt(largest_area / std::numbers::pi) * f;
  if (options_.downsample == 0 && !small_contact_pass_ && f >= 4 &&
      radius_px < options_.small_contact_periods * period_px) {
    const int margin = static_cast<int>(std::ceil(4.0 * period_px));
    const cv::Rect box(static_cast<int>(origin.x) + kept_box_w.x * f - margin,
                       static_cast<int>(origin.y) + kept_box_w.y * f - margin,
                       kept_box_w.width * f + 2 * margin, kept_box_w.height * f + 2 * margin);
    small_contact_pass_ = true;
    bool fine_left = false;
    ContactResult fine = segment_region(image, box & frame, &fine_left);
    if (fine_left) fine = segment_region(image, frame, &fine_left);
    small_contact_pass_ = false;
    if ((fine.status & kNoContact) == 0) fine.status |= status & kMultipleBlobs;
    return fine;
  }
  // Outline points of the kept regions: their boundary pixels, found row by row (first and last kept pixel
  // of each run is enough for a convex hull).
  std::vector<cv::Point2d> boundary;
  for (int y = 0; y < buf_.labels.rows; ++y) {
    const int* row = buf_.labels.ptr<int>(y);
    int first = -1, last = -1;
    for (int x = 0; x < buf_.labels.cols; ++x) {
      if (keep[static_cast<std::size_t>(row[x])] != 0) {
        if (first < 0) first = x;
        last = x;
      }
    }
    if (first >= 0) {
      boundary.emplace_back(first, y);
      if (last != first) boundary.emplace_back(last, y);
    }
  }
  const std::vector<cv::Point2d> hull_w = convex_hull(boundary);

  cv::Point2d centroid(0.0, 0.0);
  for (const auto& p : hull_w) centroid += p;
  centroid *= 1.0 / static_cast<double>(std::max<std::size_t>(1, hull_w.size()));
  const cv::Rect frame_w(0, 0, buf_.work.cols, buf_.work.rows);
  const auto near_left = [&](const cv::Point2d& p) { return p.x < 1.0; };
  const auto near_top = [&](const cv::Point2d& p) { return p.y < 1.0; };
  const auto near_right = [&](const cv::Point2d& p) { return p.x > frame_w.width - 2.0; };
  const auto near_bottom = [&](const cv::Point2d& p) { return p.y > frame_w.height - 2.0; };
  const auto on_cut = [&](const cv::Point2d& p) {
    // Within a pixel of the frame border or of the excluded band: the outline there is where the view ends,
    // not where the contact ends.
    if ((frame_left && near_left(p)) || (frame_top && near_top(p)) || (frame_right && near_right(p)) ||
        (frame_bottom && near_bottom(p)))
      return true;
    if (excluded_w.area() > 0) {
      const cv::Rect grown(excluded_w.x - 2, excluded_w.y - 2, excluded_w.width + 4, excluded_w.height + 4);
      return grown.contains(
          cv::Point(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y))));
    }
    return false;
  };

  // Polarity: the scene's, or this frame's (mean level inside the coarse hull against outside it).
  buf_.hull_mask = rasterize_polygon(hull_w, buf_.work.size());
  {
    const MaskedMeans means = masked_means(buf_.work, buf_.hull_mask);
    if (means.inside_count > 0 && means.outside_count > static_cast<double>(buf_.work.total() / 100)) {
      const double difference = means.inside - means.outside;
      if (std::abs(difference) > 0.25 * split.mean_high) result.polarity = difference < 0.0 ? -1 : 1;
    }
  }
  const int polarity = options_.polarity != 0 ? options_.polarity : result.polarity;

  // Where the skin stops touching, the frustrated light stops: a step in the image's level, sharper than
  // the fading ridge texture (ridge contrast drops towards the border, so the texture's half-maximum lies
  // inside the contact). With ridges made bright, grey closing over one period merges ridges and valleys
  // into a plateau at crest level (and keeps its outer edge), opening over half a period removes specks;
  // the outline is then the steepest descent of that plateau along the outward ray.
  bool use_level_edge = polarity != 0;
  double level_drop_min = 0.0;
  // The background around the contact (clear of it by the rays' reach and a period, outside the excluded
  // band), for the flat field and its pixel noise.
  std::optional<QuadraticSurface> background;
  if (use_level_edge) {
    if (options_.flat_field) {
      const int grow = odd_at_least(2.0 * (reach_w + period_w) + 1.0, 3);
      cv::dilate(buf_.hull_mask, buf_.scratch_u8,
                 cv::getStructuringElement(cv::MORPH_RECT, cv::Size(grow, grow)));
      if (excluded_w.area() > 0) buf_.scratch_u8(excluded_w).setTo(1);
      // At least 1/40 of the frame, sampled every 3rd pixel each way.
      background = fit_background(buf_.work, buf_.scratch_u8, centroid,
                                  std::max(64, static_cast<int>(buf_.work.total() / 360)));
    }
    if (background) {
      flatten(buf_.work, *background, polarity, buf_.bright);
      // Pixel noise as it would be at the automatic working resolution (5.5 pixels per ridge period; block
      // averaging over f x f divides white noise by f), so the decision does not depend on the resolution.
      const double reference_factor = std::max(1.0, period_px / 5.5);
      const double noise = background->residual_rms * f / reference_factor;
      result.texture_snr = noise > 0.0 ? std::min(split.mean_high / noise, 1e9) : 1e9;
    } else if (polarity < 0) {
      cv::subtract(1.0, buf_.work, buf_.bright);
    } else {
      buf_.work.copyTo(buf_.bright);
    }
    const int half_taps = static_cast<int>(std::lround(0.5 * options_.border_average_periods * period_w));
    if (background && result.texture_snr < options_.border_average_snr && half_taps > 0) {
      // The coarse hull is within a pixel or two of the edge; the rays look 1.5 periods either side of it
      // and the closing one period further.
      const std::optional<Ellipse> shape = fit_ellipse_direct(hull_w);
      if (shape && shape->semi_minor_px >= 5.0) {
        average_along_border(buf_.bright, *shape, half_taps, reach_w + period_w + 2.0, buf_.scratch);
        std::swap(buf_.bright, buf_.scratch);
        result.border_averaged = true;
      }
    }
    const int merge_k = odd_at_least(period_w + 1.0, 3);
    const int speck_k = odd_at_least(0.5 * period_w, 3);
    cv::morphologyEx(buf_.bright, buf_.level, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_RECT, cv::Size(merge_k, merge_k)), cv::Point(-1, -1),
                     1, cv::BORDER_REPLICATE);
    cv::morphologyEx(buf_.level, buf_.scratch, cv::MORPH_OPEN,
                     cv::getStructuringElement(cv::MORPH_RECT, cv::Size(speck_k, speck_k)), cv::Point(-1, -1),
                     1, cv::BORDER_REPLICATE);
    std::swap(buf_.level, buf_.scratch);
    const MaskedMeans means = masked_means(buf_.level, buf_.hull_mask);
    if (means.inside_count > 0 && means.outside_count > 0) {
      // A step must carry a fair part of the contrast between the contact and the background to count.
      level_drop_min = 0.25 * (means.inside - means.outside);
    }
    use_level_edge = level_drop_min > 0.0;
  }

  // Sub-pixel outline along the ray from the hull's centroid through each of 4x hull_points samples: first
  // where the texture energy falls through the threshold (pixel-centre hulls sit ~half a working pixel
  // inside it), then, where the level step is clear, at the steepest descent of the merged level within
  // one ridge period of that.
  const int dense_count = 4 * std::max(options_.hull_points, 8);
  const std::vector<cv::Point2d> dense_w = resample_closed_polygon(hull_w, dense_count);
  std::vector<cv::Point2d> refined_full;
  std::vector<std::uint8_t> cut;
  refined_full.reserve(dense_w.size());
  for (const auto& p : dense_w) {
    // On a side of the region that is not a frame side: the contact has outgrown the region.
    if ((!frame_left && near_left(p)) || (!frame_top && near_top(p)) || (!frame_right && near_right(p)) ||
        (!frame_bottom && near_bottom(p)))
      *left_region = true;
    const bool at_cut = on_cut(p);
    cv::Point2d q = p;
    if (!at_cut) {
      cv::Point2d dir = p - centroid;
      const double length = cv::norm(dir);
      if (length > 1e-9) {
        dir *= 1.0 / length;
        constexpr double kStep = 0.25;
        double crossing = 0.0;
        double prev_s = -1.5;
        float prev_e = bilinear(buf_.energy, p.x + prev_s * dir.x, p.y + prev_s * dir.y);
        for (double s = prev_s + kStep; s <= 2.5 + 1e-9; s += kStep) {
          const float e = bilinear(buf_.energy, p.x + s * dir.x, p.y + s * dir.y);
          if (prev_e > split.threshold && e <= split.threshold) {
            crossing = prev_s + kStep * (prev_e - split.threshold) / std::max(1e-12f, prev_e - e);
            break;
          }
          prev_s = s;
          prev_e = e;
        }
        if (use_level_edge) {
          // Local levels along this ray: the merged crest plateau inside, the background beyond; the edge is
          // where the level falls to edge_level of the way from background to plateau. Local, so vignetting
          // and illumination drift do not move it; low, because ridge contrast fades towards the border.
          const int samples = static_cast<int>(std::lround(2.0 * reach_w / kStep)) + 1;
          double inside = -1e30, outside = 0.0;
          int outside_n = 0, peak = 0;
          ray_.resize(static_cast<std::size_t>(samples));
          for (int k = 0; k < samples; ++k) {
            const double s = crossing - reach_w + k * kStep;
            const float v = bilinear(buf_.level, p.x + s * dir.x, p.y + s * dir.y);
            ray_[static_cast<std::size_t>(k)] = v;
            if (s <= crossing && v > inside) {
              inside = v;
              peak = k;
            }
            if (s >= crossing + reach_w - 1.0) {
              outside += v;
              ++outside_n;
            }
          }
          outside /= std::max(1, outside_n);
          // Pixel noise beyond the edge, from the unmerged ridges-bright image over the outer half of the
          // window: the levels below must stand clear of it, or a faint crest is lost in the background.
          double noise_sum = 0.0, noise_sum2 = 0.0;
          int noise_n = 0;
          for (double s = crossing + 0.5 * reach_w; s <= crossing + reach_w + 1e-9; s += kStep) {
            const double v = bilinear(buf_.bright, p.x + s * dir.x, p.y + s * dir.y);
            noise_sum += v;
            noise_sum2 += v * v;
            ++noise_n;
          }
          const double noise_mean = noise_sum / std::max(1, noise_n);
          const double noise =
              std::sqrt(std::max(0.0, noise_sum2 / std::max(1, noise_n) - noise_mean * noise_mean));
          if (inside - outside >= level_drop_min) {
            // Ridge contrast fades towards the border, so the outermost crest is fainter than the plateau
            // and a level relative to the plateau cuts it well inside the edge. Measure that crest instead:
            // find where the merged level is nearly down to the background (5 % of the plateau, clear of
            // the noise); the outermost crest lies within half a period inside that point, and the merged
            // level there is its height. Rays whose window leaves the view keep the plateau.
            int from = peak;
            double top = inside, fraction = options_.edge_level;
            const cv::Point2d a = p + (crossing - reach_w) * dir, b = p + (crossing + reach_w) * dir;
            const bool in_view = std::min({a.x, a.y, b.x, b.y}) >= 0.0 &&
                                 std::max(a.x, b.x) <= frame_w.width - 1.0 &&
                                 std::max(a.y, b.y) <= frame_w.height - 1.0;
            if (in_view) {
              const double nearly_out = outside + std::max(0.05 * (inside - outside), 3.0 * noise);
              for (int k = peak + 1; k < samples; ++k)
                if (ray_[static_cast<std::size_t>(k)] < nearly_out) {
                  from = std::max(peak, k - static_cast<int>(std::lround(0.5 * period_w / kStep)));
                  top = ray_[static_cast<std::size_t>(from)];
                  fraction = options_.crest_edge_level;
                  break;
                }
            }
            const double level = outside + std::max(fraction * (top - outside), 2.0 * noise);
            for (int k = from + 1; k < samples; ++k) {
              const float v0 = ray_[static_cast<std::size_t>(k - 1)], v1 = ray_[static_cast<std::size_t>(k)];
              if (v0 >= level && v1 < level) {
                crossing = crossing - reach_w + (k - 1 + (v0 - level) / std::max(1e-12f, v0 - v1)) * kStep;
                break;
              }
            }
          }
        }
        q = p + crossing * dir;
      }
    }
    q = to_full(q, f) + origin;
    if (at_cut) {
      // Push cut points onto the frame edge (or the excluded band), so the area counts the visible contact.
      if (frame_left && near_left(p)) q.x = -0.5;
      if (frame_top && near_top(p)) q.y = -0.5;
      if (frame_right && near_right(p)) q.x = full_size.width - 0.5;
      if (frame_bottom && near_bottom(p)) q.y = full_size.height - 0.5;
      status |= kTouchesEdge;
    }
    q.x = std::clamp(q.x, -0.5, full_size.width - 0.5);
    q.y = std::clamp(q.y, -0.5, full_size.height - 0.5);
    refined_full.push_back(q);
    cut.push_back(at_cut ? 1 : 0);
  }
  clip_spikes(refined_full, cut, to_full(centroid, f) + origin, options_.spike_periods * period_px);
  bridge_valleys(refined_full, cut, options_.valley_gap_periods * period_px);
  result.outline_px = convex_hull(refined_full);
  result.area_mm2 = polygon_area_px2(result.outline_px) / (options_.px_per_mm * options_.px_per_mm);
  result.hull_px = resample_closed_polygon(result.outline_px, options_.hull_points);
  const cv::Rect box =
      cv::boundingRect(std::vector<cv::Point2f>(result.outline_px.begin(), result.outline_px.end()));
  result.bounding_box_px = box & cv::Rect(0, 0, full_size.width, full_size.height);

  // Ellipse: the 50 hull points, except those on a cut, which lie on the border rather than the contact.
  std::vector<cv::Point2d> fit_points;
  const double cut_margin_px = 1.5 * f;
  for (const auto& p : result.hull_px) {
    bool free = p.x > cut_margin_px - 0.5 && p.y > cut_margin_px - 0.5 &&
                p.x < full_size.width - 0.5 - cut_margin_px && p.y < full_size.height - 0.5 - cut_margin_px;
    if (free && options_.exclude_px) {
      const cv::Rect& r = *options_.exclude_px;
      free = !(p.x > r.x - cut_margin_px - 0.5 && p.x < r.x + r.width + cut_margin_px - 0.5 &&
               p.y > r.y - cut_margin_px - 0.5 && p.y < r.y + r.height + cut_margin_px - 0.5);
    }
    if (free) fit_points.push_back(p);
  }
  if ((status & kTouchesEdge) != 0 && fit_points.size() < 20) {
    // Short free arcs: use the dense refined outline for more support.
    fit_points.clear();
    for (std::size_t i = 0; i < refined_full.size(); ++i)
      if (cut[i] == 0) fit_points.push_back(refined_full[i]);
  }
  if (fit_points.size() >= 6) result.ellipse = fit_ellipse_direct(fit_points);
  // An ellipse much larger than the frame is an extrapolation from a nearly straight arc: not reported.
  if (result.ellipse && result.ellipse->semi_major_px > 2.0 * std::hypot(full_size.width, full_size.height))
    result.ellipse.reset();
  const bool small_contact =
      result.ellipse && std::sqrt(result.ellipse->semi_major_px * result.ellipse->semi_minor_px) <
                            options_.ridge_label_below_periods * period_px;
  if (result.ellipse && (options_.ridge_label_centre || small_contact) && polarity != 0 &&
      (status & (kTouchesEdge | kSaturated)) == 0 &&
      (!result.border_averaged || (options_.border_band_centre && !small_contact))) {
    // The flat field's surface, from working pixels of the region to frame pixels (none without a flat
    // field).
    std::function<double(double, double)> illumination;
    if (background)
      illumination = [&](double x_px, double y_px) {
        return (*background)((x_px - origin.x + 0.5) / f - 0.5, (y_px - origin.y + 0.5) / f - 0.5);
      };
    RidgeLabelOptions label_options;
    label_options.method = small_contact ? RidgeLabelMethod::logistic : RidgeLabelMethod::brackets;
    if (options_.border_band_centre && !small_contact)
      label_options.border_band = result.border_averaged ? BorderBandUse::alone : BorderBandUse::with_labels;
    const std::optional<RidgeLabelFit> fit = fit_ellipse_to_ridge_labels(
        image, full_scale, *result.ellipse, period_px, polarity, label_options, illumination);
    if (fit) {
      const cv::Point2d shift(fit->ellipse.cx_px - result.ellipse->cx_px,
                              fit->ellipse.cy_px - result.ellipse->cy_px);
      if (cv::norm(shift) <= 0.5 * period_px) {
        // The brackets' size and shape terms as well, where they are of the size the level edge's errors
        // have (a few px: at most half a period; see fit_brackets).
        const bool reshape = !small_contact && std::hypot(fit->shape_size_px, fit->shape_cos2_px,
                                                          fit->shape_sin2_px) <= 0.5 * period_px;
        for (auto& p : result.outline_px) p += shift;
        if (reshape) {
          const cv::Point2d centre(fit->ellipse.cx_px, fit->ellipse.cy_px);
          for (auto& p : result.outline_px) {
            const cv::Point2d d = p - centre;
            const double r = cv::norm(d);
            if (r < 1e-9) continue;
            // cos 2 phi and sin 2 phi from the direction itself: (dx^2 - dy^2) / r^2 and 2 dx dy / r^2.
            const double radial_px = fit->shape_size_px + (fit->shape_cos2_px * (d.x * d.x - d.y * d.y) +
                                                           fit->shape_sin2_px * 2.0 * d.x * d.y) /
                                                              (r * r);
            p += d * (radial_px / r);
          }
          result.outline_px = convex_hull(result.outline_px);
          result.hull_px = resample_closed_polygon(result.outline_px, options_.hull_points);
          result.area_mm2 = polygon_area_px2(result.outline_px) / (options_.px_per_mm * options_.px_per_mm);
          *result.ellipse = fit->ellipse;
          result.ridge_label_shape_px = cv::Vec3d(fit->shape_size_px, fit->shape_cos2_px, fit->shape_sin2_px);
        } else if (small_contact && options_.ridge_label_shape_weight > 0.0) {
          // The outline (already moved by the shift) goes with its ellipse onto the blended one.
          Ellipse level_edge = *result.ellipse;
          level_edge.cx_px += shift.x;
          level_edge.cy_px += shift.y;
          const Ellipse blended =
              with_blended_shape(level_edge, fit->ellipse, options_.ridge_label_shape_weight);
          const cv::Matx23d map = ellipse_to_ellipse(level_edge, blended);
          for (auto& p : result.outline_px) {
            const cv::Vec2d moved = map * cv::Vec3d(p.x, p.y, 1.0);
            p = cv::Point2d(moved[0], moved[1]);
          }
          result.hull_px = resample_closed_polygon(result.outline_px, options_.hull_points);
          result.area_mm2 = polygon_area_px2(result.outline_px) / (options_.px_per_mm * options_.px_per_mm);
          const cv::Vec2d shape_change = shape_vector(blended) - shape_vector(level_edge);
          result.ridge_label_shape_px = cv::Vec3d(0.0, shape_change[0], shape_change[1]);
          *result.ellipse = blended;
        } else {
          for (auto& p : result.hull_px) p += shift;
          result.ellipse->cx_px += shift.x;
          result.ellipse->cy_px += shift.y;
        }
        const cv::Rect moved =
            cv::boundingRect(std::vector<cv::Point2f>(result.outline_px.begin(), result.outline_px.end()));
        result.bounding_box_px = moved & cv::Rect(0, 0, full_size.width, full_size.height);
        result.ridge_label_shift_px = shift;
        result.border_band_used = fit->border_band_used;
      }
    }
  }
  if (result.ellipse) {
    result.normalization = EllipseNormalization(*result.ellipse);
  } else {
    status |= kNoEllipse;
  }

  // Working-resolution contact mask (final hull filled) for the orientation blocks.
  std::vector<cv::Point2d> outline_w;
  outline_w.reserve(result.outline_px.size());
  for (const auto& p : result.outline_px)
    outline_w.emplace_back((p.x - origin.x + 0.5) / f - 0.5, (p.y - origin.y + 0.5) / f - 0.5);
  buf_.hull_mask = rasterize_polygon(outline_w, buf_.work.size());
  if (options_.orientation) {
    // The region's blocks are whole blocks of the frame (its origin is on the block grid).
    OrientationField field = block_orientation(buf_.band, f, region.size(), block_px, buf_.hull_mask);
    const cv::Rect target(region.x / block_px, region.y / block_px, field.orientation_rad.cols,
                          field.orientation_rad.rows);
    const cv::Rect inside = target & cv::Rect(0, 0, blocks.width, blocks.height);
    const cv::Rect source(0, 0, inside.width, inside.height);
    field.orientation_rad(source).copyTo(result.orientation_rad(inside));
    field.coherence(source).copyTo(result.coherence(inside));
  }
  if (split.mean_high < options_.low_contrast) status |= kLowContrast;
  result.status = status;
  return result;
}

}  // namespace tirstrain::contact
