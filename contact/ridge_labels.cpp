#include "contact/ridge_labels.hpp"

#include <opencv2/imgproc.hpp>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
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
};

double quantile(std::vector<float> values, double q) {
  const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<std::size_t>(k)];
}

struct Wave {
  double kx = 0.0, ky = 0.0, phase = 0.0, x0 = 0.0, y0 = 0.0;
  double explained = 0.0;  // fraction of the window's variance
  double cos_at(double x, double y) const { return std::cos(kx * (x - x0) + ky * (y - y0) - phase); }
};

// Least-squares m + A cos(k.x) + B sin(k.x) over the window for a few wave vectors around the structure
// tensor's direction and the nominal period (+-15 %); the best explains most variance. `dev`: ridge signal
// (ridges positive).
Wave fit_wave(const std::vector<Sample>& window, const cv::Mat& smooth, cv::Point origin, double background,
              double sign, double period_px) {
  Wave best;
  double jxx = 0.0, jxy = 0.0, jyy = 0.0;
  for (const Sample& s : window) {
    const int x = static_cast<int>(s.x) - origin.x, y = static_cast<int>(s.y) - origin.y;
    const double gx = 0.5 * (smooth.at<float>(y, x + 1) - smooth.at<float>(y, x - 1));
    const double gy = 0.5 * (smooth.at<float>(y + 1, x) - smooth.at<float>(y - 1, x));
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

// Per sector (k of n, direction u_k), the border's distance t_k from the initial ellipse: just beyond the
// outermost inside labels (their 95th percentile), or midway to the innermost outside labels (5th percentile)
// where those are within 2 bracket_reach_px. Where a ridge valley runs along the border the next ridge that
// would show is a period out, and the midpoint would put the border half a period beyond the last ridge. In
// the frames examined sector by sector (direction_proximal frame 40, the bench renderer's whorl), some ridge
// reached the border along every sector, its outermost pixels within 1 px of the truth (BENCHMARKS.md,
// contact/, session 21). The shift is then the least-squares fit of
// t_k = offset + shift . u_k over the sectors with labels, with a prior of bracket_prior_px on the shift.
std::optional<cv::Point2d> bracket_centre_shift(const std::vector<std::vector<float>>& inside_t,
                                                const std::vector<std::vector<float>>& outside_t,
                                                const RidgeLabelOptions& options) {
  const double n = static_cast<double>(inside_t.size());
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  const double prior_weight = 1.0 / (options.bracket_prior_px * options.bracket_prior_px);
  normal_matrix(1, 1) = normal_matrix(2, 2) = prior_weight;
  int used = 0;
  for (std::size_t k = 0; k < inside_t.size(); ++k) {
    if (inside_t[k].size() < 3) continue;
    const double outermost_inside = quantile(inside_t[k], 0.95);
    double border = outermost_inside + options.bracket_reach_px;
    if (outside_t[k].size() >= 3)
      border = std::min(border, 0.5 * (outermost_inside + quantile(outside_t[k], 0.05)));
    const double phi = (static_cast<double>(k) + 0.5) * kTwoPi / n;
    const Eigen::Vector3d f(1.0, std::cos(phi), std::sin(phi));
    normal_matrix += f * f.transpose();
    rhs += f * border;
    ++used;
  }
  if (used < options.min_sectors) return std::nullopt;
  const Eigen::Vector3d solution = normal_matrix.ldlt().solve(rhs);
  if (!solution.allFinite()) return std::nullopt;
  return cv::Point2d(solution(1), solution(2));
}

}  // namespace

std::optional<RidgeLabelFit> fit_ellipse_to_ridge_labels(
    const cv::Mat& frame, double full_scale, const Ellipse& initial, double period_px, int polarity,
    const RidgeLabelOptions& options, const std::function<double(double x_px, double y_px)>& illumination) {
  if (polarity == 0 || !(period_px > 0.0) || options.sectors < 4 || initial.semi_minor_px < 2.0)
    return std::nullopt;
  // The outer band reaches 1.6 periods beyond the ellipse; one more pixel for the gradients.
  const double reach = initial.semi_major_px + 1.6 * period_px + 2.0;
  const cv::Rect roi(static_cast<int>(std::floor(initial.cx_px - reach)),
                     static_cast<int>(std::floor(initial.cy_px - reach)), static_cast<int>(2.0 * reach) + 2,
                     static_cast<int>(2.0 * reach) + 2);
  if ((roi & cv::Rect(0, 0, frame.cols, frame.rows)) != roi) return std::nullopt;
  cv::Mat smooth;
  frame(roi).convertTo(smooth, CV_32F, 1.0 / full_scale);
  cv::GaussianBlur(smooth, smooth, cv::Size(0, 0), options.smooth_sigma_px, options.smooth_sigma_px,
                   cv::BORDER_REPLICATE);

  std::vector<Sector> sectors(static_cast<std::size_t>(options.sectors));
  const double p = period_px;
  const double cos_a = std::cos(initial.angle_rad), sin_a = std::sin(initial.angle_rad);
  // A large contact's annulus holds far more pixels than its statistics, waves and five-parameter fit need:
  // visit a lattice of about kAnnulusSamples of them.
  const double perimeter_px = kTwoPi * std::sqrt(0.5 * (initial.semi_major_px * initial.semi_major_px +
                                                        initial.semi_minor_px * initial.semi_minor_px));
  const int step =
      std::max(1, static_cast<int>(std::lround(std::sqrt(perimeter_px * 3.1 * p / kAnnulusSamples))));
  const double illumination_at_centre = illumination ? illumination(initial.cx_px, initial.cy_px) : 1.0;
  if (illumination && !(illumination_at_centre > 0.0)) return std::nullopt;
  const double q_inner = std::max(0.0, 1.0 - 1.5 * p / initial.semi_minor_px);
  const double q_inner_squared = q_inner * q_inner;
  const double q_outer_squared = std::pow(1.0 + 1.6 * p / initial.semi_minor_px, 2);
  for (int y = 1; y < smooth.rows - 1; y += step) {
    const float* row = smooth.ptr<float>(y);
    for (int x = 1; x < smooth.cols - 1; x += step) {
      const double fx = x + roi.x, fy = y + roi.y, dx = fx - initial.cx_px, dy = fy - initial.cy_px;
      // Along the ray from the centre the ellipse's radius is r / q (q: normalised radius), so t = r (1 -
      // 1/q).
      const double u = (cos_a * dx + sin_a * dy) / initial.semi_major_px;
      const double v = (-sin_a * dx + cos_a * dy) / initial.semi_minor_px;
      const double q_squared = u * u + v * v;
      // Most of the square lies well inside or outside the band: t = rho (q - 1) with the ellipse's radius
      // rho between the semi-axes, so q alone rejects them before the square roots and the angle.
      if (q_squared < q_inner_squared || q_squared > q_outer_squared || q_squared < 1e-18) continue;
      const double q = std::sqrt(q_squared);
      const double t = std::sqrt(dx * dx + dy * dy) * (1.0 - 1.0 / q);
      if (t < -1.5 * p || t > 1.6 * p) continue;
      const double phi = direction_rad(dx, dy);
      const auto index =
          std::min<std::size_t>(sectors.size() - 1, static_cast<std::size_t>(phi / kTwoPi * options.sectors));
      Sector& s = sectors[index];
      const float value =
          illumination ? static_cast<float>(row[x] * illumination_at_centre / illumination(fx, fy)) : row[x];
      const Sample sample{static_cast<float>(fx), static_cast<float>(fy), value};
      if (t >= 0.9 * p) s.outer.push_back(value);
      if (t <= -0.25 * p) s.window.push_back(sample);
      if (t >= -0.5 * p && t <= 0.0) s.near.push_back(value);
      if (std::abs(t) <= 0.75 * p) {
        s.band.push_back(sample);
        s.band_t.push_back(static_cast<float>(t));
      }
    }
  }

  RidgeLabelFit fit;
  std::vector<Label> labels;
  // Each sector's labels' distances t from the initial ellipse, for the brackets.
  std::vector<std::vector<float>> inside_t(sectors.size()), outside_t(sectors.size());
  const double sign = polarity < 0 ? -1.0 : 1.0;
  for (std::size_t k = 0; k < sectors.size(); ++k) {
    const Sector& s = sectors[k];
    if (s.outer.size() < 20 || s.window.size() < 30 || s.near.empty()) continue;
    const double background = quantile(s.outer, 0.5);
    std::vector<float> deviation(s.outer.size());
    for (std::size_t i = 0; i < s.outer.size(); ++i)
      deviation[i] = static_cast<float>(std::abs(s.outer[i] - background));
    double sigma = std::max(1.4826 * quantile(deviation, 0.5), 1e-6);
    const Wave wave = fit_wave(s.window, smooth, roi.tl(), background, sign, p);
    if (wave.explained < options.min_fit_fraction) continue;
    std::vector<float> near_signal(s.near.size());
    for (std::size_t i = 0; i < s.near.size(); ++i)
      near_signal[i] = static_cast<float>(sign * (s.near[i] - background));
    const double border_crest = quantile(near_signal, 0.95);
    // A noise-free frame's spread is its quantisation: the thresholds would then sit on any residual slope
    // of the background.
    sigma = std::max(sigma, options.min_sigma_crest_fraction * border_crest);
    ++fit.sectors_used;
    for (std::size_t i = 0; i < s.band.size(); ++i) {
      const Sample& b = s.band[i];
      const double signal = sign * (b.value - background);
      if (signal > options.in_sigmas * sigma) {
        labels.push_back({b.x, b.y, 1.0});
        inside_t[k].push_back(s.band_t[i]);
        ++fit.inside_labels;
        continue;
      }
      if (s.band_t[i] < -0.25 * p || signal >= options.out_sigmas * sigma) continue;
      const double c = wave.cos_at(b.x, b.y);
      if (c > options.predicted_cos && border_crest * 0.5 * (1.0 + c) > options.visible_sigmas * sigma) {
        labels.push_back({b.x, b.y, -1.0});
        outside_t[k].push_back(s.band_t[i]);
        ++fit.outside_labels;
      }
    }
  }
  if (fit.sectors_used < options.min_sectors || fit.inside_labels == 0 || fit.outside_labels == 0)
    return std::nullopt;
  if (options.method == RidgeLabelMethod::brackets) {
    const std::optional<cv::Point2d> shift = bracket_centre_shift(inside_t, outside_t, options);
    if (!shift) return std::nullopt;
    fit.ellipse = initial;
    fit.ellipse.cx_px += shift->x;
    fit.ellipse.cy_px += shift->y;
    return fit;
  }
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

}  // namespace tirstrain::contact
