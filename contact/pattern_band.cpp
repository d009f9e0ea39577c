#include "contact/pattern_band.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "core/error.hpp"
#include "core/full_scale.hpp"
#include "core/median.hpp"

namespace tirstrain::contact {
namespace {

// lambda_min of the structure tensor of `image` (CV_32F, full scale 1), and, where `isotropy` is given,
// lambda_min / lambda_max (0 where the image is flat).
cv::Mat smaller_eigenvalue(const cv::Mat& image, const PatternBandOptions& options,
                           cv::Mat* isotropy = nullptr) {
  cv::Mat smooth, gx, gy;
  cv::GaussianBlur(image, smooth, cv::Size(0, 0), options.presmooth_sigma_px, options.presmooth_sigma_px,
                   cv::BORDER_REFLECT);
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3, 0.125, 0.0, cv::BORDER_REFLECT);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3, 0.125, 0.0, cv::BORDER_REFLECT);
  cv::Mat jxx = gx.mul(gx), jyy = gy.mul(gy), jxy = gx.mul(gy);
  const double s = options.integration_sigma_px;
  for (cv::Mat* j : {&jxx, &jyy, &jxy}) cv::GaussianBlur(*j, *j, cv::Size(0, 0), s, s, cv::BORDER_REFLECT);
  cv::Mat out(image.size(), CV_32F);
  if (isotropy) isotropy->create(image.size(), CV_32F);
  for (int y = 0; y < out.rows; ++y) {
    const float *a = jxx.ptr<float>(y), *b = jyy.ptr<float>(y), *c = jxy.ptr<float>(y);
    float* o = out.ptr<float>(y);
    float* r = isotropy ? isotropy->ptr<float>(y) : nullptr;
    for (int x = 0; x < out.cols; ++x) {
      const float half_trace = 0.5f * (a[x] + b[x]), half_diff = 0.5f * (a[x] - b[x]);
      const float root = std::sqrt(half_diff * half_diff + c[x] * c[x]);
      o[x] = std::max(0.0f, half_trace - root);
      if (r) r[x] = half_trace + root > 0.0f ? o[x] / (half_trace + root) : 0.0f;
    }
  }
  return out;
}

// lambda_min's median on white noise of unit variance: what pixel noise alone gives, per unit variance.
double noise_lambda_per_variance(const PatternBandOptions& options) {
  cv::Mat noise(128, 128, CV_32F);
  cv::RNG rng(0x5EED);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  const cv::Mat lambda = smaller_eigenvalue(noise, options);
  std::vector<float> v(lambda.begin<float>(), lambda.end<float>());
  return upper_median_in_place(v);
}

// |second differences| of `image` (Immerkaer's kernel, blind to planes and to slow curvature): a pixel-noise
// measure little touched by structures a few pixels wide. Its median over a line, times 1.4826 / 6, is the
// line's noise sigma for Gaussian noise.
cv::Mat noise_response(const cv::Mat& image) {
  const cv::Mat kernel = (cv::Mat_<float>(3, 3) << 1, -2, 1, -2, 4, -2, 1, -2, 1);
  cv::Mat out;
  cv::filter2D(image, out, CV_32F, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_REFLECT);
  return cv::abs(out);
}

// Median of each row of `m` (CV_32F).
std::vector<double> row_medians(const cv::Mat& m) {
  std::vector<double> out(static_cast<std::size_t>(m.rows));
  std::vector<float> row;
  for (int y = 0; y < m.rows; ++y) {
    row.assign(m.ptr<float>(y), m.ptr<float>(y) + m.cols);
    out[static_cast<std::size_t>(y)] = upper_median_in_place(row);
  }
  return out;
}

double median_of(std::vector<double> v) {
  return v.empty() ? 0.0 : upper_median_in_place(v);
}

// Lines counted inward from `edge` of an image whose lines (rows, or columns as rows of the transpose) are
// `lines`; the profile and the band's rectangle in image pixels.
struct EdgeProfile {
  ImageEdge edge;
  std::vector<double> level;  // median lambda_min, index = distance from the edge in lines
  std::vector<double> noise;  // lambda_min that the line's pixel noise alone would give
};

// The band's width (lines) along one profile, from where the level falls to `threshold`; the crossing is
// interpolated, and the band ends half a line past the last line above it (a blurred step crosses its
// midpoint at the step). The search starts `first` lines in: the lines at the edge itself read less (the
// image is mirrored there, which halves the variety of the dots the structure tensor sees).
double crossing_width(const std::vector<double>& level, double threshold, std::size_t first,
                      std::size_t max_lines) {
  for (std::size_t d = std::max<std::size_t>(1, first); d < std::min(level.size(), max_lines + 1); ++d) {
    if (level[d] >= threshold) continue;
    const double above = level[d - 1], below = level[d];
    const double t = above > below ? (above - threshold) / (above - below) : 0.0;
    return static_cast<double>(d - 1) + t + 0.5;
  }
  return static_cast<double>(max_lines) + 1.0;  // runs past the widest band allowed
}

cv::Rect band_rect(ImageEdge edge, int width_px, cv::Size size) {
  switch (edge) {
    case ImageEdge::kTop:
      return {0, 0, size.width, width_px};
    case ImageEdge::kBottom:
      return {0, size.height - width_px, size.width, width_px};
    case ImageEdge::kLeft:
      return {0, 0, width_px, size.height};
    case ImageEdge::kRight:
      return {size.width - width_px, 0, width_px, size.height};
    case ImageEdge::kNone:
      break;
  }
  return {};
}

double clamp01(double v) {
  return std::clamp(v, 0.0, 1.0);
}

// The candidate band along one edge; confidence below 0.5 means none there.
PatternBand band_along(const EdgeProfile& profile, double typical, const cv::Mat& lambda,
                       const cv::Mat& isotropy, const PatternBandOptions& options) {
  PatternBand band;
  const std::vector<double>& level = profile.level;
  const auto lines = level.size();
  const auto max_lines = static_cast<std::size_t>(options.max_width_fraction * static_cast<double>(lines));
  const auto min_lines = static_cast<std::size_t>(std::max(1, options.min_width_px));
  if (lines < 2 * min_lines || typical <= 0.0 || max_lines < min_lines) return band;
  // The level next to the edge, then the band's own level once its extent is known (one refinement).
  double band_level =
      median_of(std::vector<double>(level.begin(), level.begin() + static_cast<std::ptrdiff_t>(min_lines)));
  band.contrast = band_level / typical;
  double width = 0.0;
  for (int pass = 0; pass < 2; ++pass) {
    width = crossing_width(level, 0.5 * (band_level + typical), min_lines, max_lines);
    const auto inside = static_cast<std::size_t>(std::clamp(width, 1.0, static_cast<double>(max_lines)));
    band_level =
        median_of(std::vector<double>(level.begin(), level.begin() + static_cast<std::ptrdiff_t>(inside)));
    band.contrast = band_level / typical;
  }
  const auto inside = static_cast<std::ptrdiff_t>(std::clamp(width, 1.0, static_cast<double>(max_lines)));
  const double noise_level =
      median_of(std::vector<double>(profile.noise.begin(), profile.noise.begin() + inside));
  band.snr = noise_level > 0.0 ? band_level / noise_level : 1e9;
  const double contrast_score =
      std::min(band.contrast > 1.0 ? std::log(band.contrast) / std::log(options.min_contrast) : 0.0,
               band.snr > 1.0 ? std::log(band.snr) / std::log(options.min_snr) : 0.0);
  if (band.contrast < options.min_contrast || band.snr < options.min_snr ||
      width < static_cast<double>(min_lines) || width > static_cast<double>(max_lines)) {
    band.confidence = 0.5 * clamp01(std::min(contrast_score, 0.99));
    return band;
  }
  band.width_px = width;
  const int width_px = std::max(1, static_cast<int>(std::floor(width)) - std::max(0, options.inset_px));
  const cv::Rect roi = band_rect(profile.edge, width_px, lambda.size());
  // Fill: the band's pixels above the geometric mean of the two levels (between dots lambda_min dips, so the
  // pixel test sits lower than the line test).
  cv::Mat above;
  cv::compare(lambda(roi), std::sqrt(band_level * typical), above, cv::CMP_GT);
  band.fill = static_cast<double>(cv::countNonZero(above)) / static_cast<double>(roi.area());
  if (band.fill < options.min_fill) {
    band.confidence = 0.5 * clamp01(band.fill / options.min_fill);
    return band;
  }
  // Per line, as the level: a contact pressed into the band covers less than half of each of its lines.
  cv::Mat ratios = isotropy(roi);
  if (profile.edge == ImageEdge::kLeft || profile.edge == ImageEdge::kRight) ratios = ratios.t();
  band.isotropy = median_of(row_medians(ratios));
  if (band.isotropy < options.min_isotropy) {
    band.confidence = 0.5 * clamp01(band.isotropy / options.min_isotropy);
    return band;
  }
  const double contrast_part = clamp01(std::min(
      std::log(band.contrast / options.min_contrast) / std::log(options.full_contrast / options.min_contrast),
      std::log(band.snr / options.min_snr) / std::log(options.full_snr / options.min_snr)));
  const double fill_part = clamp01((band.fill - options.min_fill) / (0.95 - options.min_fill));
  band.confidence = 0.5 + 0.5 * std::min(contrast_part, fill_part);
  band.edge = profile.edge;
  band.roi_px = roi;
  // The inset, the boundary's scatter from frame to frame (2 px) and the rounding down of the rectangle.
  band.margin_px = std::max(0, options.inset_px) + 3;
  return band;
}

}  // namespace

std::string to_string(ImageEdge edge) {
  switch (edge) {
    case ImageEdge::kTop:
      return "top";
    case ImageEdge::kBottom:
      return "bottom";
    case ImageEdge::kLeft:
      return "left";
    case ImageEdge::kRight:
      return "right";
    case ImageEdge::kNone:
      break;
  }
  return "none";
}

PatternBand detect_pattern_band(const cv::Mat& image, const PatternBandOptions& options) {
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F))
    throw Error("pattern band detection needs a one-channel 8-bit, 16-bit or float image");
  PatternBand best;
  if (image.rows < 4 * options.min_width_px || image.cols < 4 * options.min_width_px) return best;
  cv::Mat unit;
  image.convertTo(unit, CV_32F, 1.0 / full_scale_of(image));
  cv::Mat isotropy;
  const cv::Mat lambda = smaller_eigenvalue(unit, options, &isotropy);
  cv::Mat lambda_t;
  cv::transpose(lambda, lambda_t);
  const std::vector<double> rows = row_medians(lambda), cols = row_medians(lambda_t);
  // The lambda_min each line's own pixel noise would give (noise may differ across the frame: shot noise
  // grows with the light), so that a noisier strip is not taken for a textured one.
  const cv::Mat response = noise_response(unit);
  cv::Mat response_t;
  cv::transpose(response, response_t);
  const double per_variance = noise_lambda_per_variance(options);
  const auto to_lambda = [&](std::vector<double> medians) {
    for (double& m : medians) m = per_variance * std::pow(1.4826 * m / 6.0, 2);
    return medians;
  };
  const std::vector<double> row_noise = to_lambda(row_medians(response)),
                            col_noise = to_lambda(row_medians(response_t));
  // The typical line: most lines of an image cross no band, so the median line is one of those.
  const double typical_row = median_of(rows), typical_col = median_of(cols);
  const std::array<EdgeProfile, 4> profiles = {
      EdgeProfile{ImageEdge::kTop, rows, row_noise},
      EdgeProfile{ImageEdge::kBottom, {rows.rbegin(), rows.rend()}, {row_noise.rbegin(), row_noise.rend()}},
      EdgeProfile{ImageEdge::kLeft, cols, col_noise},
      EdgeProfile{ImageEdge::kRight, {cols.rbegin(), cols.rend()}, {col_noise.rbegin(), col_noise.rend()}}};
  for (const EdgeProfile& profile : profiles) {
    const bool horizontal = profile.edge == ImageEdge::kTop || profile.edge == ImageEdge::kBottom;
    const PatternBand band =
        band_along(profile, horizontal ? typical_row : typical_col, lambda, isotropy, options);
    if (band.confidence > best.confidence) best = band;
  }
  if (best.edge == ImageEdge::kNone) best.roi_px = cv::Rect();
  return best;
}

}  // namespace tirstrain::contact
