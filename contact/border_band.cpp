#include "contact/border_band.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>

#include "core/smoothstep.hpp"

namespace tirstrain::contact {
namespace {

// cx, cy, semi-axes a and b, angle; the border profile's edge width, floor and fade length.
constexpr int kParams = 8;
using Params = Eigen::Matrix<double, kParams, 1>;
constexpr std::size_t kMinSamples = 100;
constexpr int kMinSamplesPerSector = 30;

// The border profile A(d) at each sample for the ellipse and profile `p`. d is approximated by r (1 - 1/q),
// r the distance from the centre and q the normalised radius, as in the ridge labels' logistic fit.
Eigen::VectorXd border_profile(const std::vector<BorderBandSample>& samples, const Params& p) {
  const double c = std::cos(p(4)), s = std::sin(p(4));
  const double inverse_a = 1.0 / p(2), inverse_b = 1.0 / p(3);
  const double edge = p(5), floor = p(6), fade = p(7);
  Eigen::VectorXd profile(static_cast<Eigen::Index>(samples.size()));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double dx = samples[i].x_px - p(0), dy = samples[i].y_px - p(1);
    const double u = (c * dx + s * dy) * inverse_a, v = (-s * dx + c * dy) * inverse_b;
    const double q = std::max(std::hypot(u, v), 1e-9);
    const double d = std::hypot(dx, dy) * (1.0 - 1.0 / q);
    const double step = 1.0 / (1.0 + std::exp(std::clamp(d / edge, -50.0, 50.0)));
    profile(static_cast<Eigen::Index>(i)) = step * (floor + (1.0 - floor) * smoothstep5(-d / fade));
  }
  return profile;
}

// The band against the model with the linear coefficients (the common level c0, each sector's c1 and c2)
// solved by least squares for `profile`: the residuals.
class Band {
 public:
  Band(std::vector<BorderBandSample> samples, std::vector<cv::Vec2d> waves)
      : samples_(std::move(samples)), waves_(std::move(waves)) {
    update_phases();
  }
  std::size_t size() const { return samples_.size(); }
  const std::vector<BorderBandSample>& samples() const { return samples_; }

  // `level` (optional): the fitted common level c0.
  Eigen::VectorXd residuals(const Eigen::VectorXd& profile, double* level = nullptr) const {
    // Normal equations of [c0, c1_0, c2_0, c1_1, ...]: c0 couples every sector, each pair only its own.
    const int sectors = static_cast<int>(waves_.size());
    const int unknowns = 1 + 2 * sectors;
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(unknowns, unknowns);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(unknowns);
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const double a = profile(static_cast<Eigen::Index>(i));
      const int k = 1 + 2 * samples_[i].sector;
      const double b1 = a * cos_[i], b2 = a * sin_[i], y = samples_[i].signal;
      normal(0, 0) += a * a;
      normal(0, k) += a * b1;
      normal(0, k + 1) += a * b2;
      normal(k, k) += b1 * b1;
      normal(k, k + 1) += b1 * b2;
      normal(k + 1, k + 1) += b2 * b2;
      rhs(0) += a * y;
      rhs(k) += b1 * y;
      rhs(k + 1) += b2 * y;
    }
    normal.triangularView<Eigen::StrictlyLower>() = normal.transpose();
    // A tiny ridge keeps a sector without samples (or with a degenerate phase) solvable.
    normal.diagonal().array() += 1e-9 * (normal.trace() / unknowns + 1e-12);
    const Eigen::VectorXd x = normal.ldlt().solve(rhs);
    if (level) *level = x(0);
    Eigen::VectorXd e(static_cast<Eigen::Index>(samples_.size()));
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const int k = 1 + 2 * samples_[i].sector;
      e(static_cast<Eigen::Index>(i)) = samples_[i].signal - profile(static_cast<Eigen::Index>(i)) *
                                                                 (x(0) + x(k) * cos_[i] + x(k + 1) * sin_[i]);
    }
    return e;
  }

  // Each sector's wave vector refined against the band with `profile` held (Levenberg-Marquardt on kx, ky
  // with the sector's own level and phase solved at each step): a plane wave fitted 0.25-1.5 periods inside
  // misplaces the crests by a few px at the border where the ridges curve or the skin is stretched, and the
  // model then reads the misplaced crest as the border.
  void refine_waves(const Eigen::VectorXd& profile) {
    std::vector<std::vector<std::size_t>> members(waves_.size());
    for (std::size_t i = 0; i < samples_.size(); ++i)
      members[static_cast<std::size_t>(samples_[i].sector)].push_back(i);
    for (std::size_t k = 0; k < waves_.size(); ++k)
      if (static_cast<int>(members[k].size()) >= kMinSamplesPerSector)
        waves_[k] = refined_wave(members[k], waves_[k], profile);
    update_phases();
  }

 private:
  Eigen::VectorXd sector_residuals(const std::vector<std::size_t>& members, cv::Vec2d wave,
                                   const Eigen::VectorXd& profile) const {
    const Eigen::Index n = static_cast<Eigen::Index>(members.size());
    Eigen::MatrixXd basis(n, 3);
    Eigen::VectorXd y(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const BorderBandSample& s = samples_[members[static_cast<std::size_t>(j)]];
      const double a = profile(static_cast<Eigen::Index>(members[static_cast<std::size_t>(j)]));
      const double phase = wave[0] * s.dx_px + wave[1] * s.dy_px;
      basis.row(j) << a, a * std::cos(phase), a * std::sin(phase);
      y(j) = s.signal;
    }
    Eigen::Matrix3d normal = basis.transpose() * basis;
    normal.diagonal().array() += 1e-9 * (normal.trace() + 1e-12);
    const Eigen::Vector3d coefficients = normal.ldlt().solve(basis.transpose() * y);
    return y - basis * coefficients;
  }

  cv::Vec2d refined_wave(const std::vector<std::size_t>& members, cv::Vec2d wave,
                         const Eigen::VectorXd& profile) const {
    const double k0 = std::hypot(wave[0], wave[1]);
    if (!(k0 > 0.0)) return wave;
    Eigen::VectorXd e = sector_residuals(members, wave, profile);
    double cost = e.squaredNorm(), damping = 1e-3;
    const double h = 1e-4 * k0;
    for (int iteration = 0; iteration < 6; ++iteration) {
      Eigen::MatrixXd jacobian(e.size(), 2);
      jacobian.col(0) = (sector_residuals(members, wave + cv::Vec2d(h, 0.0), profile) - e) / h;
      jacobian.col(1) = (sector_residuals(members, wave + cv::Vec2d(0.0, h), profile) - e) / h;
      const Eigen::Matrix2d jtj = jacobian.transpose() * jacobian;
      const Eigen::Vector2d gradient = jacobian.transpose() * e;
      bool improved = false;
      for (int attempt = 0; attempt < 8 && !improved; ++attempt) {
        Eigen::Matrix2d damped = jtj;
        damped.diagonal() += damping * jtj.diagonal();
        const Eigen::Vector2d step = -damped.ldlt().solve(gradient);
        const cv::Vec2d candidate = wave + cv::Vec2d(step(0), step(1));
        // The period and direction stay within 25 % of the window's: beyond, the wave is another ridge's.
        if (!std::isfinite(candidate[0]) || !std::isfinite(candidate[1]) ||
            std::abs(std::hypot(candidate[0], candidate[1]) / k0 - 1.0) > 0.25) {
          damping *= 10.0;
          continue;
        }
        const Eigen::VectorXd candidate_e = sector_residuals(members, candidate, profile);
        if (candidate_e.squaredNorm() < cost) {
          wave = candidate;
          e = candidate_e;
          cost = e.squaredNorm();
          damping *= 0.3;
          improved = true;
        } else {
          damping *= 10.0;
        }
      }
      if (!improved) break;
    }
    return wave;
  }

  void update_phases() {
    cos_.resize(samples_.size());
    sin_.resize(samples_.size());
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const cv::Vec2d& k = waves_[static_cast<std::size_t>(samples_[i].sector)];
      const double phase = k[0] * samples_[i].dx_px + k[1] * samples_[i].dy_px;
      cos_[i] = std::cos(phase);
      sin_[i] = std::sin(phase);
    }
  }

  std::vector<BorderBandSample> samples_;
  std::vector<cv::Vec2d> waves_;
  std::vector<double> cos_, sin_;
};

Params clamped_profile(Params p, double period_px) {
  p(5) = std::clamp(p(5), 0.3, 5.0);
  p(6) = std::clamp(p(6), 0.0, 1.0);
  p(7) = std::clamp(p(7), 2.0, 2.0 * period_px);
  return p;
}

// Levenberg-Marquardt on the eight parameters, the Jacobian of the projected residuals by forward
// differences (each column one evaluation of the band: the linear coefficients move with the parameters).
Params fit_parameters(const Band& band, Params p, double period_px, int iterations, double* rms) {
  constexpr std::array<double, kParams> kSteps{0.05, 0.05, 0.05, 0.05, 5e-4, 0.02, 0.005, 0.1};
  Eigen::VectorXd e = band.residuals(border_profile(band.samples(), p));
  double cost = e.squaredNorm(), damping = 1e-3;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    Eigen::MatrixXd jacobian(e.size(), kParams);
    for (int j = 0; j < kParams; ++j) {
      Params stepped = p;
      stepped(j) += kSteps[static_cast<std::size_t>(j)];
      jacobian.col(j) =
          (band.residuals(border_profile(band.samples(), stepped)) - e) / kSteps[static_cast<std::size_t>(j)];
    }
    const Eigen::Matrix<double, kParams, kParams> jtj = jacobian.transpose() * jacobian;
    const Params gradient = jacobian.transpose() * e;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, kParams, kParams> damped = jtj;
      for (int k = 0; k < kParams; ++k) damped(k, k) += damping * (jtj(k, k) + 1e-12);
      const Params candidate = clamped_profile(p - damped.ldlt().solve(gradient), period_px);
      if (!candidate.allFinite() || candidate(2) <= 2.0 || candidate(3) <= 2.0) {
        damping *= 10.0;
        continue;
      }
      const Eigen::VectorXd candidate_e = band.residuals(border_profile(band.samples(), candidate));
      const double candidate_cost = candidate_e.squaredNorm();
      if (candidate_cost < cost) {
        const double gain = cost - candidate_cost;
        p = candidate;
        e = candidate_e;
        cost = candidate_cost;
        damping *= 0.3;
        improved = true;
        if (gain < 1e-7 * cost) iteration = iterations;
      } else {
        damping *= 10.0;
      }
    }
    if (!improved) break;
  }
  *rms = std::sqrt(cost / static_cast<double>(std::max<Eigen::Index>(1, e.size())));
  return p;
}

}  // namespace

std::optional<BorderBandFit> fit_border_band(std::vector<BorderBandSample> samples,
                                             std::vector<cv::Vec2d> wave_vectors, const Ellipse& start,
                                             double period_px, const BorderBandOptions& options) {
  if (!(period_px > 0.0) || !(start.semi_minor_px > 2.0) || wave_vectors.empty()) return std::nullopt;
  const int sectors = static_cast<int>(wave_vectors.size());
  std::erase_if(samples, [&](const BorderBandSample& s) {
    return s.sector < 0 || s.sector >= sectors || !std::isfinite(s.signal) ||
           wave_vectors[static_cast<std::size_t>(s.sector)] == cv::Vec2d(0.0, 0.0);
  });
  if (samples.size() < kMinSamples) return std::nullopt;
  Band band(std::move(samples), std::move(wave_vectors));
  Params p;
  p << start.cx_px, start.cy_px, start.semi_major_px, start.semi_minor_px, start.angle_rad,
      options.initial_edge_px, options.initial_floor, options.initial_fade_periods * period_px;
  p = clamped_profile(p, period_px);
  double rms = 0.0;
  p = fit_parameters(band, p, period_px, options.iterations, &rms);
  for (int round = 0; round < options.wave_rounds; ++round) {
    band.refine_waves(border_profile(band.samples(), p));
    p = fit_parameters(band, p, period_px, options.iterations, &rms);
  }
  // No ridges in the band (a common level that does not stand five standard errors above the background's):
  // nothing placed the border.
  double level = 0.0;
  band.residuals(border_profile(band.samples(), p), &level);
  const double level_error = rms / std::sqrt(static_cast<double>(band.size()));
  if (!p.allFinite() || !std::isfinite(rms) || !(level > 5.0 * level_error)) return std::nullopt;
  BorderBandFit fit;
  fit.ellipse = Ellipse{p(0), p(1), p(2), p(3), p(4)};
  Ellipse& e = fit.ellipse;
  if (e.semi_minor_px > e.semi_major_px) {
    std::swap(e.semi_major_px, e.semi_minor_px);
    e.angle_rad += 0.5 * std::numbers::pi;
  }
  e.angle_rad = std::remainder(e.angle_rad, std::numbers::pi);
  if (e.angle_rad <= -0.5 * std::numbers::pi) e.angle_rad += std::numbers::pi;
  fit.edge_px = p(5);
  fit.fade_floor = p(6);
  fit.fade_px = p(7);
  fit.rms_residual = rms;
  return fit;
}

}  // namespace tirstrain::contact
