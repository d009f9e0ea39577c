#include "contact/ridge_labels.hpp"

#include "contact/border_band.hpp"
#include "contact/kth_smallest.hpp"

#include <opencv2/imgproc.hpp>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

namespace tirstrain::contact {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr std::size_t kMaxLabels = 2000;  // more add little to a five-parameter fit and cost linearly
constexpr double kAnnulusSamples = 15000.0;
constexpr std::size_t kMaxWaveSamples = 200;
constexpr std::array<double, 6> kPeriodFactors{0.85, 0.9, 0.95, 1.05, 1.1, 1.15};

struct Sample {
  float x, y, value;
};

// One sector's pixels by distance t from the initial ellipse along the ray from its centre (px, > 0 outside).
struct Sector {
  std::vector<float> outer;    // t in [0.9, 1.6] periods: background level and noise
  std::vector<Sample> window;  // t in [-1.5, -0.25] periods: the ridges' plane wave
  std::vector<float> near;     // t in [-0.5, 0] periods: the border's crest level
  std::vector<Sample> band;    // |t| <= 0.75 period: the pixels to label
  std::vector<float> band_t;
  std::vector<Sample> border_band;  // t in [-border_band_inner_periods, 0.75] periods (when asked)
};

// Reorders `values`.
double quantile(std::vector<float>& values, double q) {
  return kth_smallest(values, static_cast<std::size_t>(q * static_cast<double>(values.size() - 1)));
}

// Where a row crosses the band between two normalised radii q_low < q_high of an ellipse (q: the ellipse's
// normalised radius, 1 on it): the columns (as dx from the centre) with q <= q_high, less the hole q < q_low.
class EllipseBand {
 public:
  struct Row {
    bool crosses = false;
    double first = 0.0, last = 0.0;  // q <= q_high
    bool has_hole = false;
    double hole_first = 0.0, hole_last = 0.0;  // q < q_low
  };
  EllipseBand(const Ellipse& e, double q_low, double q_high)
      : q_low_squared_(q_low * q_low), q_high_squared_(q_high * q_high) {
    const double cos_a = std::cos(e.angle_rad), sin_a = std::sin(e.angle_rad);
    const double inv_a2 = 1.0 / (e.semi_major_px * e.semi_major_px);
    const double inv_b2 = 1.0 / (e.semi_minor_px * e.semi_minor_px);
    // q^2 = quad_a dx^2 + quad_b dy dx + quad_c dy^2
    quad_a_ = cos_a * cos_a * inv_a2 + sin_a * sin_a * inv_b2;
    quad_b_ = 2.0 * cos_a * sin_a * (inv_a2 - inv_b2);
    quad_c_ = sin_a * sin_a * inv_a2 + cos_a * cos_a * inv_b2;
  }
  Row at(double dy) const {
    Row row;
    const double b = quad_b_ * dy, c = quad_c_ * dy * dy;
    const double middle = -b / (2.0 * quad_a_);
    const double outer_disc = b * b - 4.0 * quad_a_ * (c - q_high_squared_);
    if (outer_disc < 0.0) return row;
    const double outer_half = std::sqrt(outer_disc) / (2.0 * quad_a_);
    row.crosses = true;
    row.first = middle - outer_half;
    row.last = middle + outer_half;
    const double inner_disc = b * b - 4.0 * quad_a_ * (c - q_low_squared_);
    if (inner_disc > 0.0) {
      const double inner_half = std::sqrt(inner_disc) / (2.0 * quad_a_);
      row.has_hole = true;
      row.hole_first = middle - inner_half;
      row.hole_last = middle + inner_half;
    }
    return row;
  }

 private:
  double q_low_squared_, q_high_squared_;
  double quad_a_ = 0.0, quad_b_ = 0.0, quad_c_ = 0.0;
};

// The columns first, first + step, ..., last of a row less those in [hole_first, hole_last] (empty when
// hole_first > hole_last): up to two runs, an empty one with first > last.
std::array<std::pair<int, int>, 2> runs_beside_hole(int first, int last, int hole_first, int hole_last,
                                                    int step) {
  if (hole_first > hole_last) return {std::pair{first, last}, std::pair{1, 0}};
  return {std::pair{first, std::min(last, hole_first - step)},
          std::pair{std::max(first, hole_last + step), last}};
}

// Binomial weights 1 4 6 4 1 (/16) per axis: a Gaussian of sigma 1 px.
template <typename T>
void smooth_row_span(const cv::Mat& source, int row, int first, int last, float scale,
                     std::vector<float>& column_sums, float* __restrict out) {
  const T* __restrict r0 = source.ptr<T>(row - 2);
  const T* __restrict r1 = source.ptr<T>(row - 1);
  const T* __restrict r2 = source.ptr<T>(row);
  const T* __restrict r3 = source.ptr<T>(row + 1);
  const T* __restrict r4 = source.ptr<T>(row + 2);
  float* __restrict sums = column_sums.data();
  for (int x = first - 2; x <= last + 2; ++x)
    sums[x] = static_cast<float>(r0[x]) + 4.0f * static_cast<float>(r1[x]) +
              6.0f * static_cast<float>(r2[x]) + 4.0f * static_cast<float>(r3[x]) + static_cast<float>(r4[x]);
  const float* __restrict c = column_sums.data();
  const float weight = scale / 256.0f;
  for (int x = first; x <= last; ++x)
    out[x] = weight * (c[x - 2] + 4.0f * c[x - 1] + 6.0f * c[x] + 4.0f * c[x + 1] + c[x + 2]);
}

// The ROI smoothed on the lattice's rows only (ROI rows first_row + step k): the band is a small part of the
// ROI's square on a large contact, and the rows between are not needed.
struct LatticeRows {
  cv::Mat rows;  // CV_32F, one row per lattice row, the ROI's width
  int first_row = 0, step = 1;
  const float* row(int y) const { return rows.ptr<float>((y - first_row) / step); }
  float at(int x, int y) const { return row(y)[x]; }
};

// Smooths the ROI's pixels at the columns within `band` (in ROI coordinates: the band's dy and dx are about
// `centre`) on `lattice`'s rows; elsewhere its values are left unset.
void smooth_band(const cv::Mat& roi_pixels, double full_scale, const EllipseBand& band, cv::Point2d centre,
                 LatticeRows& lattice) {
  std::vector<float> column_sums(static_cast<std::size_t>(roi_pixels.cols));
  const float scale = static_cast<float>(1.0 / full_scale);
  const int min_column = 2, max_column = roi_pixels.cols - 3;
  for (int k = 0; k < lattice.rows.rows; ++k) {
    const int y = lattice.first_row + k * lattice.step;
    const EllipseBand::Row row = band.at(y - centre.y);
    if (!row.crosses) continue;
    const int first = std::max(min_column, static_cast<int>(std::floor(centre.x + row.first)));
    const int last = std::min(max_column, static_cast<int>(std::ceil(centre.x + row.last)));
    int hole_first = last + 1, hole_last = last;
    if (row.has_hole) {
      hole_first = static_cast<int>(std::ceil(centre.x + row.hole_first));
      hole_last = static_cast<int>(std::floor(centre.x + row.hole_last));
    }
    float* out = lattice.rows.ptr<float>(k);
    for (const auto& [span_first, span_last] : runs_beside_hole(first, last, hole_first, hole_last, 1)) {
      if (span_first > span_last) continue;
      switch (roi_pixels.depth()) {
        case CV_8U:
          smooth_row_span<std::uint8_t>(roi_pixels, y, span_first, span_last, scale, column_sums, out);
          break;
        case CV_16U:
          smooth_row_span<std::uint16_t>(roi_pixels, y, span_first, span_last, scale, column_sums, out);
          break;
        default:
          smooth_row_span<float>(roi_pixels, y, span_first, span_last, scale, column_sums, out);
          break;
      }
    }
  }
}

// 1 / illumination at `count` lattice points from (x_px, y_px) every `step_px` along the row, from its values
// at the run's ends and middle: the illumination is a smooth background (the segmenter's is a quadratic
// surface, which this reproduces exactly), and calling it at every point cost more than the rest of the
// lattice's work. All ones without an illumination.
void flat_field_along_run(const std::function<double(double, double)>& illumination, int x_px, int y_px,
                          int step_px, Eigen::Ref<Eigen::ArrayXd> inverse_level) {
  const Eigen::Index count = inverse_level.size();
  if (!illumination) {
    inverse_level.setOnes();
    return;
  }
  if (count < 3) {
    for (Eigen::Index i = 0; i < count; ++i)
      inverse_level(i) = 1.0 / illumination(x_px + static_cast<double>(i * step_px), y_px);
    return;
  }
  // The quadratic through j = 0, m, n (Newton's divided differences).
  const double n = static_cast<double>(count - 1), m = std::floor(0.5 * n);
  const double f0 = illumination(x_px, y_px), fm = illumination(x_px + m * step_px, y_px),
               fn = illumination(x_px + n * step_px, y_px);
  const double slope = (fm - f0) / m, curvature = ((fn - fm) / (n - m) - slope) / n;
  const auto j = Eigen::ArrayXd::LinSpaced(count, 0.0, n);
  inverse_level = (f0 + j * (slope + curvature * (j - m))).inverse();
}

struct Wave {
  double kx = 0.0, ky = 0.0, phase = 0.0, x0 = 0.0, y0 = 0.0;
  double explained = 0.0;  // fraction of the window's variance
  // The wave's cosine at samples[indices[i]], a vector register at a time.
  Eigen::ArrayXf cos_at(const std::vector<Sample>& samples, const std::vector<std::uint32_t>& indices) const {
    Eigen::ArrayXf phases(static_cast<Eigen::Index>(indices.size()));
    for (std::size_t i = 0; i < indices.size(); ++i) {
      const Sample& s = samples[indices[i]];
      phases(static_cast<Eigen::Index>(i)) = static_cast<float>(kx * (s.x - x0) + ky * (s.y - y0) - phase);
    }
    return phases.cos();
  }
};

// Least-squares m + A cos(k.x) + B sin(k.x) over the window for a few wave vectors around the structure
// tensor's direction and the nominal period (+-15 %); the best explains most variance. `dev`: ridge signal
// (ridges positive).
// `smooth`: the frame smoothed on the lattice of spacing `step` that the window's samples lie on; the
// gradients are central differences between lattice neighbours.
Wave fit_wave(const std::vector<Sample>& window, const LatticeRows& smooth, cv::Point origin,
              double background, double sign, double period_px) {
  const int step = smooth.step;
  Wave best;
  double jxx = 0.0, jxy = 0.0, jyy = 0.0;
  for (const Sample& s : window) {
    const int x = static_cast<int>(s.x) - origin.x, y = static_cast<int>(s.y) - origin.y;
    const double gx = smooth.at(x + step, y) - smooth.at(x - step, y);
    const double gy = smooth.at(x, y + step) - smooth.at(x, y - step);
    jxx += gx * gx;
    jxy += gx * gy;
    jyy += gy * gy;
    best.x0 += s.x;
    best.y0 += s.y;
  }
  const double n = static_cast<double>(window.size());
  best.x0 /= n;
  best.y0 /= n;
  // A three-parameter fit needs far fewer samples than a large contact's sector holds.
  const std::size_t stride = (window.size() + kMaxWaveSamples - 1) / kMaxWaveSamples;
  double total = 0.0, subset_mean = 0.0, subset_count = 0.0;
  for (std::size_t i = 0; i < window.size(); i += stride) {
    subset_mean += sign * (window[i].value - background);
    subset_count += 1.0;
  }
  subset_mean /= subset_count;
  for (std::size_t i = 0; i < window.size(); i += stride)
    total += std::pow(sign * (window[i].value - background) - subset_mean, 2);
  const double normal = 0.5 * std::atan2(2.0 * jxy, jxx - jyy);  // gradient direction: across the ridges
  // The wave's direction first (structure tensor +-5 deg at the nominal period), then its period at that
  // direction: near the border of a sliding contact the skin is stretched or compressed by 10-15 % (the
  // leading and trailing edges), and a period off by that much misplaces the extrapolated crests by a third
  // of a period one period out.
  double best_explained = -1.0;
  // The subset's positions and signals as float arrays: the cosines and sines of each trial wave are then
  // evaluated a vector register at a time.
  const Eigen::Index count = static_cast<Eigen::Index>(subset_count);
  Eigen::ArrayXf dx(count), dy(count), signal(count);
  for (Eigen::Index j = 0; j < count; ++j) {
    const Sample& s = window[static_cast<std::size_t>(j) * stride];
    dx(j) = static_cast<float>(s.x - best.x0);
    dy(j) = static_cast<float>(s.y - best.y0);
    signal(j) = static_cast<float>(sign * (s.value - background));
  }
  const double signal_sum = signal.cast<double>().sum();
  const auto try_wave = [&](double theta, double period_factor) {
    const double k = kTwoPi / (period_px * period_factor);
    const double kx = k * std::cos(theta), ky = k * std::sin(theta);
    const Eigen::ArrayXf phase = static_cast<float>(kx) * dx + static_cast<float>(ky) * dy;
    const Eigen::ArrayXf c = phase.cos(), sn = phase.sin();
    Eigen::Matrix3d normal_matrix;
    normal_matrix << static_cast<double>(count), c.sum(), sn.sum(),  //
        0.0, (c * c).sum(), (c * sn).sum(),                          //
        0.0, 0.0, (sn * sn).sum();
    normal_matrix(1, 0) = normal_matrix(0, 1);
    normal_matrix(2, 0) = normal_matrix(0, 2);
    normal_matrix(2, 1) = normal_matrix(1, 2);
    const Eigen::Vector3d rhs(signal_sum, (signal * c).sum(), (signal * sn).sum());
    const Eigen::Vector3d solution = normal_matrix.ldlt().solve(rhs);
    const double explained = solution.dot(rhs) - rhs(0) * rhs(0) / normal_matrix(0, 0);
    if (explained > best_explained) {
      best_explained = explained;
      best.kx = kx;
      best.ky = ky;
      best.phase = std::atan2(solution(2), solution(1));
    }
  };
  constexpr double kStep = 5.0 * std::numbers::pi / 180.0;
  for (const double theta : {normal - kStep, normal, normal + kStep}) try_wave(theta, 1.0);
  const double theta = std::atan2(best.ky, best.kx);
  for (const double period_factor : kPeriodFactors) try_wave(theta, period_factor);
  best.explained = total > 0.0 ? best_explained / total : 0.0;
  return best;
}

// The direction of (dx, dy) in [0, 2 pi), within 0.004 rad (atan z ~ z (pi/4 + 0.273 (1 - |z|)) on each
// octant): it only sorts pixels into sectors, many times per frame.
double direction_rad(double dx, double dy) {
  const double ax = std::abs(dx), ay = std::abs(dy);
  if (ax == 0.0 && ay == 0.0) return 0.0;
  const double z = std::min(ax, ay) / std::max(ax, ay);
  double a = z * (0.25 * std::numbers::pi + 0.273 * (1.0 - z));
  if (ay > ax) a = 0.5 * std::numbers::pi - a;
  if (dx < 0.0) a = std::numbers::pi - a;
  if (dy < 0.0) a = kTwoPi - a;
  return a >= kTwoPi ? a - kTwoPi : a;
}

struct Label {
  double x, y, side;  // side +1 inside, -1 outside
};

using Params = Eigen::Matrix<double, 5, 1>;  // cx, cy, a, b, angle

double softplus(double z) {
  return z > 30.0 ? z : std::log1p(std::exp(z));
}

// Logistic loss of the labels against the ellipse `p`, with its gradient and Fisher information when asked.
// The signed distance (px, > 0 outside) is approximated by r (1 - 1/q): r the distance from the centre, q the
// normalised radius (the ellipse's own radius along that ray is r / q).
double logistic_loss(const Params& p, const std::vector<Label>& labels, double width_px, Params* gradient,
                     Eigen::Matrix<double, 5, 5>* information) {
  const double c = std::cos(p(4)), s = std::sin(p(4)), a = p(2), b = p(3);
  double loss = 0.0;
  if (gradient) gradient->setZero();
  if (information) information->setZero();
  for (const Label& l : labels) {
    const double dx = l.x - p(0), dy = l.y - p(1);
    const double u = (c * dx + s * dy) / a, v = (-s * dx + c * dy) / b;
    const double q = std::max(std::hypot(u, v), 1e-9), r = std::hypot(dx, dy);
    const double z = l.side * r * (1.0 - 1.0 / q) / width_px;
    loss += softplus(z);
    if (!gradient) continue;
    // d(distance)/d(cx, cy, a, b, angle), through r and q.
    const double r_safe = std::max(r, 1e-9);
    const Params dr(-dx / r_safe, -dy / r_safe, 0.0, 0.0, 0.0);
    const Params du(-c / a, -s / a, -u / a, 0.0, v * b / a);
    const Params dv(s / b, -c / b, 0.0, -v / b, -u * a / b);
    const Params dq = (u * du + v * dv) / q;
    const Params dz = l.side * (dr * (1.0 - 1.0 / q) + dq * (r / (q * q))) / width_px;
    const double slope = 1.0 / (1.0 + std::exp(-z));
    *gradient += slope * dz;
    *information += slope * (1.0 - slope) * dz * dz.transpose();
  }
  return loss;
}

// Levenberg-Marquardt (Fisher scoring) on the logistic loss.
std::optional<Params> fit_logistic(Params p, const std::vector<Label>& labels, double width_px,
                                   int max_iterations) {
  Params gradient;
  Eigen::Matrix<double, 5, 5> information;
  double loss = logistic_loss(p, labels, width_px, &gradient, &information), damping = 1e-3;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    bool improved = false;
    for (int attempt = 0; attempt < 12 && !improved; ++attempt) {
      Eigen::Matrix<double, 5, 5> damped = information;
      for (int k = 0; k < 5; ++k) damped(k, k) += damping * (information(k, k) + 1e-12);
      const Params candidate = p + damped.ldlt().solve(-gradient);
      if (!candidate.allFinite() || candidate(2) <= 2.0 || candidate(3) <= 2.0) {
        damping *= 10.0;
        continue;
      }
      Params candidate_gradient;
      Eigen::Matrix<double, 5, 5> candidate_information;
      const double candidate_loss =
          logistic_loss(candidate, labels, width_px, &candidate_gradient, &candidate_information);
      if (candidate_loss < loss) {
        const double gain = loss - candidate_loss;
        p = candidate;
        loss = candidate_loss;
        gradient = candidate_gradient;
        information = candidate_information;
        damping *= 0.3;
        improved = true;
        if (gain < 1e-9 * loss) return p;
      } else {
        damping *= 10.0;
      }
    }
    if (!improved) break;
  }
  if (!p.allFinite()) return std::nullopt;
  return p;
}

// The brackets' outside labels lie where the wave predicts a phase that this sector's ridges show inside the
// contact: a cosine above the lowest (5th percentile) of `inside_cos`, the wave's cosine at the inside labels
// more than a quarter period inside, plus phase_margin_cos; at most predicted_cos. A fixed crest side (cosine
// above 0.3) would not do: where ridges show down into their valleys (to a cosine of -0.7 on the bench
// renderer) a border cutting a flank would leave a gap of most of a period to the next predicted crest, and
// the midway border would land far out (ContactSegmenter.CentreOverRandomScenes holds the centre over random
// scenes; BENCHMARKS.md, contact/).
double bracket_predicted_cos(const Eigen::ArrayXf& inside_cos, const RidgeLabelOptions& options) {
  if (inside_cos.size() < 10) return options.predicted_cos;
  std::vector<float> values(inside_cos.begin(), inside_cos.end());
  return std::clamp(quantile(values, 0.05) + options.phase_margin_cos, -1.0, options.predicted_cos);
}

// Per sector (k of n, direction u_k), the border's distance t_k from the initial ellipse lies between the
// outermost inside labels (their 95th percentile) and the innermost outside labels (5th percentile): it is
// taken midway, or just beyond the inside labels (bracket_reach_px) where the sector has no outside labels.
// Where the gap between the two is wide (a valley along the border, where the border could lie anywhere in
// it), the sector counts less: weight 1 / (1 + (gap / bracket_gap_px)^2). A sector whose outside labels lie
// within its inside labels contradicts itself (the wave's phase has drifted) and is left out. The gap's
// weight matters: with the border put just beyond the inside labels everywhere, a wide valley along an arc of
// a sliding contact moves the centre by over a pixel.
//
// The positions are fitted twice, by weighted least squares with a prior of bracket_prior_px on all but the
// offset: t_k = offset + shift . u_k gives the centre's shift; t_k = offset + shift . u_k + cos2 cos 2 phi_k
// + sin2 sin 2 phi_k the shape (elongation and its direction). That offset is not the size: the labels'
// thresholds sit on the foot of the blurred edge, so where a ridge ends at the border the inside labels reach
// ~1 px and the outside ones ~3.5 px beyond it (both renderers), and the midway border lies ~2 px out (the
// axes would come out 1-2 % long). The size comes from the sectors where ridges end at the border (gap at
// most bracket_size_gap_px): there the inside labels' bracket_size_quantile marks the border; the median over
// those sectors of its distance from the fitted shape is the border's mean radial change, when at least
// bracket_size_min_sectors of them exist (what the size and shape give: BENCHMARKS.md, contact/).
struct BracketFit {
  cv::Point2d shift;
  double cos2_px = 0.0, sin2_px = 0.0;
  std::optional<double> size_px;
};

std::optional<BracketFit> fit_brackets(std::vector<std::vector<float>>& inside_t,
                                       std::vector<std::vector<float>>& outside_t,
                                       const RidgeLabelOptions& options) {
  const double n = static_cast<double>(inside_t.size());
  using Matrix5d = Eigen::Matrix<double, 5, 5>;
  using Vector5d = Eigen::Matrix<double, 5, 1>;
  Matrix5d normal_matrix = Matrix5d::Zero();
  Vector5d rhs = Vector5d::Zero();
  const double prior_weight = 1.0 / (options.bracket_prior_px * options.bracket_prior_px);
  for (int i = 1; i < 5; ++i) normal_matrix(i, i) = prior_weight;
  int used = 0;
  std::vector<std::pair<double, double>> ridge_ends;  // (phi, the inside labels' size quantile)
  for (std::size_t k = 0; k < inside_t.size(); ++k) {
    if (inside_t[k].size() < 3) continue;
    const double outermost_inside = quantile(inside_t[k], 0.95);
    double border = outermost_inside + options.bracket_reach_px;
    double weight = 1.0;
    const double phi = (static_cast<double>(k) + 0.5) * kTwoPi / n;
    if (outside_t[k].size() >= 3) {
      const double gap = quantile(outside_t[k], 0.05) - outermost_inside;
      if (gap < 0.0) continue;
      border = outermost_inside + 0.5 * gap;
      weight = 1.0 / (1.0 + std::pow(gap / options.bracket_gap_px, 2));
      if (gap <= options.bracket_size_gap_px)
        ridge_ends.emplace_back(phi, quantile(inside_t[k], options.bracket_size_quantile));
    }
    Vector5d f;
    f << 1.0, std::cos(phi), std::sin(phi), std::cos(2.0 * phi), std::sin(2.0 * phi);
    normal_matrix += weight * f * f.transpose();
    rhs += weight * border * f;
    ++used;
  }
  if (used < options.min_sectors) return std::nullopt;
  const Eigen::Vector3d centre = normal_matrix.topLeftCorner<3, 3>().ldlt().solve(rhs.head<3>());
  const Vector5d shape = normal_matrix.ldlt().solve(rhs);
  if (!centre.allFinite() || !shape.allFinite()) return std::nullopt;
  BracketFit fit{cv::Point2d(centre(1), centre(2)), shape(3), shape(4), std::nullopt};
  if (static_cast<int>(ridge_ends.size()) >= options.bracket_size_min_sectors) {
    std::vector<float> sizes;
    sizes.reserve(ridge_ends.size());
    for (const auto& [phi, border] : ridge_ends)
      sizes.push_back(static_cast<float>(border - shape(1) * std::cos(phi) - shape(2) * std::sin(phi) -
                                         shape(3) * std::cos(2.0 * phi) - shape(4) * std::sin(2.0 * phi)));
    const double size = quantile(sizes, 0.5);
    if (std::isfinite(size)) fit.size_px = size;
  }
  return fit;
}

// `e` with its border moved radially by size + cos2 cos 2 phi + sin2 sin 2 phi (phi about its centre): the
// direct fit of 360 points of that border. The change is symmetric about the centre, which stays.
Ellipse reshaped(const Ellipse& e, double size_px, double cos2_px, double sin2_px) {
  std::vector<cv::Point2d> border;
  border.reserve(360);
  const double c = std::cos(e.angle_rad), s = std::sin(e.angle_rad);
  for (int i = 0; i < 360; ++i) {
    const double phi = (i + 0.5) * kTwoPi / 360.0, ux = std::cos(phi), uy = std::sin(phi);
    const double u = (c * ux + s * uy) / e.semi_major_px, v = (-s * ux + c * uy) / e.semi_minor_px;
    const double r =
        1.0 / std::hypot(u, v) + size_px + cos2_px * std::cos(2.0 * phi) + sin2_px * std::sin(2.0 * phi);
    border.emplace_back(e.cx_px + r * ux, e.cy_px + r * uy);
  }
  return fit_ellipse_direct(border).value_or(e);
}

// The band visited around the initial ellipse: its ROI of the frame and the lattice of about kAnnulusSamples
// points on it (every `step` px from 3 px in the ROI; 3 px for the smoothing).
struct Annulus {
  cv::Rect roi;
  cv::Mat roi_pixels;  // CV_8U, CV_16U or CV_32F
  int step = 1;
  double illumination_at_centre = 1.0;
  double q_inner = 0.0, q_inner_squared = 0.0, q_outer_squared = 0.0;  // the band's normalised radii
  cv::Point2d centre;                                                  // the ellipse's centre in the ROI
};

// Nothing when the band leaves the frame, the frame is not grey, or the illumination is not positive at the
// centre.
std::optional<Annulus> annulus_around(const cv::Mat& frame, const Ellipse& initial, double p,
                                      const std::function<double(double, double)>& illumination) {
  Annulus annulus;
  // The outer band reaches 1.6 periods beyond the ellipse; 4 more pixels for the smoothing and gradients.
  const double reach = initial.semi_major_px + 1.6 * p + 4.0;
  annulus.roi = cv::Rect(static_cast<int>(std::floor(initial.cx_px - reach)),
                         static_cast<int>(std::floor(initial.cy_px - reach)),
                         static_cast<int>(2.0 * reach) + 2, static_cast<int>(2.0 * reach) + 2);
  const cv::Rect& roi = annulus.roi;
  if ((roi & cv::Rect(0, 0, frame.cols, frame.rows)) != roi) return std::nullopt;
  if (frame.channels() != 1) return std::nullopt;
  annulus.roi_pixels = frame(roi);
  if (annulus.roi_pixels.depth() != CV_8U && annulus.roi_pixels.depth() != CV_16U &&
      annulus.roi_pixels.depth() != CV_32F)
    frame(roi).convertTo(annulus.roi_pixels, CV_32F);
  // A large contact's annulus holds far more pixels than its statistics, waves and five-parameter fit need:
  // visit a lattice of about kAnnulusSamples of them.
  const double perimeter_px = kTwoPi * std::sqrt(0.5 * (initial.semi_major_px * initial.semi_major_px +
                                                        initial.semi_minor_px * initial.semi_minor_px));
  annulus.step =
      std::max(1, static_cast<int>(std::lround(std::sqrt(perimeter_px * 3.1 * p / kAnnulusSamples))));
  annulus.illumination_at_centre = illumination ? illumination(initial.cx_px, initial.cy_px) : 1.0;
  if (illumination && !(annulus.illumination_at_centre > 0.0)) return std::nullopt;
  annulus.q_inner = std::max(0.0, 1.0 - 1.5 * p / initial.semi_minor_px);
  annulus.q_inner_squared = annulus.q_inner * annulus.q_inner;
  annulus.q_outer_squared = std::pow(1.0 + 1.6 * p / initial.semi_minor_px, 2);
  annulus.centre = cv::Point2d(initial.cx_px - roi.x, initial.cy_px - roi.y);
  return annulus;
}

// What sorting one run of lattice columns into sectors reads.
struct RunSorter {
  const Annulus* annulus = nullptr;
  const Ellipse* initial = nullptr;
  double p = 0.0;
  double sectors_per_rad = 0.0;
  bool border_band = false;
  double band_inner_t = 0.0;
  const std::function<double(double, double)>* illumination = nullptr;
};

// Per run of lattice columns: dx, q^2, t and 1 / illumination, a vector register at a time.
struct RunArrays {
  Eigen::ArrayXf dx, q_squared, t;
  Eigen::ArrayXd flat;
};

// The lattice columns run_first, run_first + step, ..., run_last of ROI row y (smoothed: `row`), each put in
// its sector's lists by its distance t from the initial ellipse.
void sort_run(const RunSorter& sorter, int y, int run_first, int run_last, const float* row,
              RunArrays& arrays, std::vector<Sector>& sectors) {
  const Annulus& annulus = *sorter.annulus;
  const Ellipse& initial = *sorter.initial;
  const cv::Rect& roi = annulus.roi;
  const int step = annulus.step;
  const double p = sorter.p;
  const double dy = y + roi.y - initial.cy_px;
  const double cos_a = std::cos(initial.angle_rad), sin_a = std::sin(initial.angle_rad);
  const Eigen::Index count = (run_last - run_first) / step + 1;
  auto dx = arrays.dx.head(count);
  auto q_squared = arrays.q_squared.head(count);
  auto t = arrays.t.head(count);
  auto flat = arrays.flat.head(count);
  const double dx_first = run_first + roi.x - initial.cx_px;
  const float along_x = static_cast<float>(cos_a), along_y = static_cast<float>(sin_a * dy);
  const float across_x = static_cast<float>(-sin_a), across_y = static_cast<float>(cos_a * dy);
  const float inverse_a = static_cast<float>(1.0 / initial.semi_major_px);
  const float inverse_b = static_cast<float>(1.0 / initial.semi_minor_px);
  const float dy_squared = static_cast<float>(dy * dy);
  dx = Eigen::ArrayXf::LinSpaced(count, static_cast<float>(dx_first),
                                 static_cast<float>(dx_first + step * (count - 1.0)));
  // Along the ray from the centre the ellipse's radius is r / q (q: normalised radius), so t = r (1 - 1/q).
  // In float, four at a time: t to 1e-4 px.
  q_squared =
      ((along_x * dx + along_y) * inverse_a).square() + ((across_x * dx + across_y) * inverse_b).square();
  t = (dx * dx + dy_squared).sqrt() * (1.0f - q_squared.max(1e-18f).rsqrt());
  flat_field_along_run(*sorter.illumination, run_first + roi.x, y + roi.y, step, flat);
  for (Eigen::Index j = 0; j < count; ++j) {
    if (q_squared(j) < annulus.q_inner_squared || q_squared(j) > annulus.q_outer_squared ||
        q_squared(j) < 1e-18)
      continue;
    if (t(j) < -1.5 * p || t(j) > 1.6 * p) continue;
    const int x = run_first + static_cast<int>(j) * step;
    const double fx = x + roi.x, fy = y + roi.y;
    const double phi = direction_rad(dx(j), dy);
    // A multiplication and a signed conversion: a division and an unsigned one per sample cost a tenth of
    // this loop's time.
    const auto index = std::min<std::size_t>(
        sectors.size() - 1, static_cast<std::size_t>(static_cast<int>(phi * sorter.sectors_per_rad)));
    Sector& s = sectors[index];
    const float value = static_cast<float>(row[x] * annulus.illumination_at_centre * flat(j));
    const Sample sample{static_cast<float>(fx), static_cast<float>(fy), value};
    const double tj = t(j);
    if (tj >= 0.9 * p) s.outer.push_back(value);
    if (tj <= -0.25 * p) s.window.push_back(sample);
    if (tj >= -0.5 * p && tj <= 0.0) s.near.push_back(value);
    if (sorter.border_band && tj >= sorter.band_inner_t && tj <= 0.75 * p) s.border_band.push_back(sample);
    if (std::abs(tj) <= 0.75 * p) {
      s.band.push_back(sample);
      s.band_t.push_back(static_cast<float>(tj));
    }
  }
}

// The frame smoothed on the lattice's rows and every lattice point of the band sorted into its sector. Per
// row only the lattice columns where q lies between the band's limits (plus a column either side) are
// visited, and the frame is smoothed only there: over the band widened by a lattice step and a pixel (the
// gradients' neighbours).
std::vector<Sector> collect_sectors(const Annulus& annulus, const Ellipse& initial, double p,
                                    double full_scale, const RidgeLabelOptions& options,
                                    const std::function<double(double, double)>& illumination,
                                    LatticeRows& smooth) {
  const cv::Rect& roi = annulus.roi;
  const int step = annulus.step;
  const cv::Point2d centre = annulus.centre;
  const EllipseBand lattice_band(initial, annulus.q_inner, std::sqrt(annulus.q_outer_squared));
  const double margin_q = (step + 1.0) / initial.semi_minor_px;
  const EllipseBand smoothed_band(initial, std::max(0.0, annulus.q_inner - margin_q),
                                  std::sqrt(annulus.q_outer_squared) + margin_q);
  smooth = LatticeRows{cv::Mat((roi.height - 7) / step + 1, roi.width, CV_32F), 3, step};
  smooth_band(annulus.roi_pixels, full_scale, smoothed_band, centre, smooth);
  const auto lattice_column = [&](double dx_px, bool up) {
    const double x = (dx_px + centre.x - 3.0) / step;
    return 3 + step * static_cast<int>(up ? std::ceil(x) : std::floor(x));
  };
  std::vector<Sector> sectors(static_cast<std::size_t>(options.sectors));
  for (auto& sector : sectors) {
    const std::size_t expected = static_cast<std::size_t>(kAnnulusSamples / options.sectors);
    sector.outer.reserve(expected / 2);
    sector.window.reserve(expected / 2);
    sector.near.reserve(expected / 4);
    sector.band.reserve(expected / 2);
    sector.band_t.reserve(expected / 2);
  }
  const RunSorter sorter{&annulus,
                         &initial,
                         p,
                         options.sectors / kTwoPi,
                         options.border_band != BorderBandUse::off,
                         -options.border_band_inner_periods * p,
                         &illumination};
  const Eigen::Index max_run = roi.width / step + 2;
  RunArrays arrays{Eigen::ArrayXf(max_run), Eigen::ArrayXf(max_run), Eigen::ArrayXf(max_run),
                   Eigen::ArrayXd(max_run)};
  for (int y = 3; y < roi.height - 3; y += step) {
    const EllipseBand::Row span = lattice_band.at(y - centre.y);
    if (!span.crosses) continue;
    const int x_first = std::max(3, lattice_column(span.first, false) - step);
    const int x_last = std::min(roi.width - 4, lattice_column(span.last, true) + step);
    int hole_first = x_last + 1, hole_last = x_last;  // lattice columns certainly inside the band's hole
    if (span.has_hole) {
      hole_first = lattice_column(span.hole_first, true) + step;
      hole_last = lattice_column(span.hole_last, false) - step;
    }
    // The lattice columns either side of the hole.
    for (const auto& [run_first, run_last] : runs_beside_hole(x_first, x_last, hole_first, hole_last, step))
      if (run_first <= run_last) sort_run(sorter, y, run_first, run_last, smooth.row(y), arrays, sectors);
  }
  return sectors;
}

// Every sector's labels, as the chosen method takes them, and the border band's samples.
struct SectorLabels {
  std::vector<Label> labels;  // the logistic fit's
  // Each sector's labels' distances t from the initial ellipse, for the brackets.
  std::vector<std::vector<float>> inside_t, outside_t;
  std::vector<BorderBandSample> band_samples;
  std::vector<cv::Vec2d> band_waves;
  std::vector<std::uint32_t> candidates, deep_inside;  // a sector's band samples whose wave cosine is read
};

// The sector's border band samples (every stride-th) against its background, and its wave vector.
void collect_band_samples(std::size_t k, const Sector& s, const Wave& wave, double background, double sign,
                          const RidgeLabelOptions& options, SectorLabels& out) {
  const std::size_t stride = static_cast<std::size_t>(std::max(1, options.border_band == BorderBandUse::alone
                                                                      ? options.border_band_alone_stride
                                                                      : options.border_band_stride));
  for (std::size_t i = 0; i < s.border_band.size(); i += stride) {
    const Sample& b = s.border_band[i];
    out.band_samples.push_back({static_cast<int>(k), b.x, b.y,
                                static_cast<float>(sign * (b.value - background)),
                                static_cast<float>(b.x - wave.x0), static_cast<float>(b.y - wave.y0)});
  }
  out.band_waves[k] = cv::Vec2d(wave.kx, wave.ky);
}

// What labelling one sector's band reads: its background level, the noise sigma and the crest level at the
// border.
struct SectorLevels {
  double background = 0.0, sigma = 0.0, border_crest = 0.0;
};

// The sector's band labelled: inside where the ridge signal exceeds in_sigmas; outside where it is below
// out_sigmas, at most a quarter period inside, and the wave predicts a ridge that would show there. The
// wave's cosine is read only at the outside candidates and, for the brackets, at the inside labels deeper
// than a quarter period: it is evaluated there alone, and the labels are then taken in band order.
void label_band(std::size_t k, const Sector& s, const Wave& wave, const SectorLevels& levels, double sign,
                double p, const RidgeLabelOptions& options, RidgeLabelFit& fit, SectorLabels& out) {
  const bool logistic = options.method == RidgeLabelMethod::logistic;
  const double background = levels.background, sigma = levels.sigma;
  out.candidates.clear();
  out.deep_inside.clear();
  for (std::size_t i = 0; i < s.band.size(); ++i) {
    const double signal = sign * (s.band[i].value - background);
    const bool deep = s.band_t[i] < -0.25 * p;
    if (signal > options.in_sigmas * sigma) {
      if (deep && !logistic) out.deep_inside.push_back(static_cast<std::uint32_t>(i));
    } else if (!deep && signal < options.out_sigmas * sigma) {
      out.candidates.push_back(static_cast<std::uint32_t>(i));
    }
  }
  const double predicted_cos =
      logistic ? options.predicted_cos : bracket_predicted_cos(wave.cos_at(s.band, out.deep_inside), options);
  const Eigen::ArrayXf candidate_cos = wave.cos_at(s.band, out.candidates);
  std::size_t next_candidate = 0;
  for (std::size_t i = 0; i < s.band.size(); ++i) {
    const Sample& b = s.band[i];
    if (next_candidate < out.candidates.size() && out.candidates[next_candidate] == i) {
      const double c = candidate_cos(static_cast<Eigen::Index>(next_candidate++));
      if (c > predicted_cos && levels.border_crest * 0.5 * (1.0 + c) > options.visible_sigmas * sigma) {
        if (logistic) out.labels.push_back({b.x, b.y, -1.0});
        out.outside_t[k].push_back(s.band_t[i]);
        ++fit.outside_labels;
      }
    } else if (sign * (b.value - background) > options.in_sigmas * sigma) {
      if (logistic) out.labels.push_back({b.x, b.y, 1.0});
      out.inside_t[k].push_back(s.band_t[i]);
      ++fit.inside_labels;
    }
  }
}

// Each sector with enough pixels and a ridge wave that explains its window: its border band samples (when
// asked) and its labels (unless the band fit is used alone), counted in `fit`.
SectorLabels label_sectors(std::vector<Sector>& sectors, const LatticeRows& smooth, cv::Point roi_origin,
                           double p, int polarity, const RidgeLabelOptions& options, RidgeLabelFit& fit) {
  SectorLabels out;
  out.inside_t.resize(sectors.size());
  out.outside_t.resize(sectors.size());
  out.band_waves.assign(sectors.size(), cv::Vec2d(0.0, 0.0));
  const double sign = polarity < 0 ? -1.0 : 1.0;
  for (std::size_t k = 0; k < sectors.size(); ++k) {
    Sector& s = sectors[k];
    if (s.outer.size() < 20 || s.window.size() < 30 || s.near.empty()) continue;
    SectorLevels levels;
    levels.background = quantile(s.outer, 0.5);
    std::vector<float> deviation(s.outer.size());
    for (std::size_t i = 0; i < s.outer.size(); ++i)
      deviation[i] = static_cast<float>(std::abs(s.outer[i] - levels.background));
    levels.sigma = std::max(1.4826 * quantile(deviation, 0.5), 1e-6);
    const Wave wave = fit_wave(s.window, smooth, roi_origin, levels.background, sign, p);
    if (wave.explained < options.min_fit_fraction) continue;
    if (options.border_band != BorderBandUse::off) {
      collect_band_samples(k, s, wave, levels.background, sign, options, out);
      if (options.border_band == BorderBandUse::alone) {
        ++fit.sectors_used;
        continue;  // no labels
      }
    }
    std::vector<float> near_signal(s.near.size());
    for (std::size_t i = 0; i < s.near.size(); ++i)
      near_signal[i] = static_cast<float>(sign * (s.near[i] - levels.background));
    levels.border_crest = quantile(near_signal, 0.95);
    // A noise-free frame's spread is its quantisation: the thresholds would then sit on any residual slope of
    // the background.
    levels.sigma = std::max(levels.sigma, options.min_sigma_crest_fraction * levels.border_crest);
    ++fit.sectors_used;
    label_band(k, s, wave, levels, sign, p, options, fit, out);
  }
  return out;
}

// The band fit alone: `initial` moved to its centre.
std::optional<RidgeLabelFit> fit_band_alone(RidgeLabelFit fit, SectorLabels& labels, const Ellipse& initial,
                                            double period_px, const RidgeLabelOptions& options) {
  if (fit.sectors_used < options.min_sectors) return std::nullopt;
  const std::optional<BorderBandFit> band =
      fit_border_band(std::move(labels.band_samples), std::move(labels.band_waves), initial, period_px);
  if (!band) return std::nullopt;
  fit.ellipse = initial;
  fit.ellipse.cx_px = band->ellipse.cx_px;
  fit.ellipse.cy_px = band->ellipse.cy_px;
  fit.border_band_used = true;
  return fit;
}

// The brackets' centre, size and shape; with the border band, the centre the mean of the two.
std::optional<RidgeLabelFit> fit_with_brackets(RidgeLabelFit fit, SectorLabels& labels,
                                               const Ellipse& initial, double period_px,
                                               const RidgeLabelOptions& options) {
  const std::optional<BracketFit> brackets = fit_brackets(labels.inside_t, labels.outside_t, options);
  if (!brackets) return std::nullopt;
  Ellipse moved = initial;
  moved.cx_px += brackets->shift.x;
  moved.cy_px += brackets->shift.y;
  fit.shape_size_px = brackets->size_px.value_or(0.0);
  fit.shape_cos2_px = brackets->cos2_px;
  fit.shape_sin2_px = brackets->sin2_px;
  fit.ellipse = reshaped(moved, fit.shape_size_px, brackets->cos2_px, brackets->sin2_px);
  if (options.border_band == BorderBandUse::with_labels) {
    // The mean of the two centres: each errs by where the fingerprint lies along the border, partly
    // independently, so the mean errs less than either (BENCHMARKS.md, contact/).
    const std::optional<BorderBandFit> band =
        fit_border_band(std::move(labels.band_samples), std::move(labels.band_waves), fit.ellipse, period_px);
    if (band) {
      fit.ellipse.cx_px = 0.5 * (fit.ellipse.cx_px + band->ellipse.cx_px);
      fit.ellipse.cy_px = 0.5 * (fit.ellipse.cy_px + band->ellipse.cy_px);
      fit.border_band_used = true;
    }
  }
  return fit;
}

// The logistic fit of the ellipse's five parameters to at most kMaxLabels of the labels (every n-th).
std::optional<RidgeLabelFit> fit_with_logistic(RidgeLabelFit fit, std::vector<Label>& labels,
                                               const Ellipse& initial, const RidgeLabelOptions& options) {
  if (labels.size() > kMaxLabels) {
    const std::size_t stride = (labels.size() + kMaxLabels - 1) / kMaxLabels;
    std::vector<Label> kept;
    kept.reserve(labels.size() / stride + 1);
    for (std::size_t i = 0; i < labels.size(); i += stride) kept.push_back(labels[i]);
    labels.swap(kept);
  }
  Params start;
  start << initial.cx_px, initial.cy_px, initial.semi_major_px, initial.semi_minor_px, initial.angle_rad;
  const std::optional<Params> fitted =
      fit_logistic(start, labels, options.transition_px, options.max_iterations);
  if (!fitted) return std::nullopt;
  Ellipse& e = fit.ellipse;
  e.cx_px = (*fitted)(0);
  e.cy_px = (*fitted)(1);
  e.semi_major_px = (*fitted)(2);
  e.semi_minor_px = (*fitted)(3);
  e.angle_rad = (*fitted)(4);
  if (e.semi_minor_px > e.semi_major_px) {
    std::swap(e.semi_major_px, e.semi_minor_px);
    e.angle_rad += 0.5 * std::numbers::pi;
  }
  e.angle_rad = std::remainder(e.angle_rad, std::numbers::pi);
  if (e.angle_rad <= -0.5 * std::numbers::pi) e.angle_rad += std::numbers::pi;
  return fit;
}

}  // namespace

// The recipe: the band around the initial ellipse, its lattice sorted into sectors, each sector's ridge wave
// and labels, then the fit the options ask for.
std::optional<RidgeLabelFit> fit_ellipse_to_ridge_labels(
    const cv::Mat& frame, double full_scale, const Ellipse& initial, double period_px, int polarity,
    const RidgeLabelOptions& options, const std::function<double(double x_px, double y_px)>& illumination) {
  if (polarity == 0 || !(period_px > 0.0) || options.sectors < 4 || initial.semi_minor_px < 2.0)
    return std::nullopt;
  const std::optional<Annulus> annulus = annulus_around(frame, initial, period_px, illumination);
  if (!annulus) return std::nullopt;
  LatticeRows smooth;
  std::vector<Sector> sectors =
      collect_sectors(*annulus, initial, period_px, full_scale, options, illumination, smooth);
  RidgeLabelFit fit;
  SectorLabels labels = label_sectors(sectors, smooth, annulus->roi.tl(), period_px, polarity, options, fit);
  if (options.border_band == BorderBandUse::alone)
    return fit_band_alone(fit, labels, initial, period_px, options);
  if (fit.sectors_used < options.min_sectors || fit.inside_labels == 0 || fit.outside_labels == 0)
    return std::nullopt;
  if (options.method == RidgeLabelMethod::brackets)
    return fit_with_brackets(fit, labels, initial, period_px, options);
  return fit_with_logistic(fit, labels.labels, initial, options);
}

}  // namespace tirstrain::contact
