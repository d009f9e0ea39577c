#include "contact/border_band.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "core/smoothstep.hpp"

namespace tirstrain::contact {
namespace {

// cx, cy, semi-axes a and b, angle; the border profile's edge width, floor and fade length.
constexpr int kParams = 8;
using Params = BorderBandParams;
constexpr std::size_t kMinSamples = 100;
constexpr int kMinSamplesPerSector = 30;

// The normal equations of the linear coefficients [c0, c1_0, c2_0, c1_1, ...] are shaped like an arrow: c0
// couples every sector, each (c1, c2) pair only its own. Solved by eliminating the pairs, in O(sectors): a
// dense factorisation (O(sectors^3)) was about half of each solve on a frame's 20-odd sectors.
class ArrowNormal {
 public:
  // `level`: c0's diagonal; per sector, `coupling` (c0 with the pair) and `blocks` (the pair's 2 x 2);
  // `ridge` added to every diagonal.
  ArrowNormal(double level, const std::vector<Eigen::Vector2d>& coupling, std::vector<Eigen::Matrix2d> blocks,
              double ridge)
      : block_inverse_(std::move(blocks)), along_(coupling.size()), schur_(level + ridge) {
    for (std::size_t k = 0; k < block_inverse_.size(); ++k) {
      Eigen::Matrix2d& b = block_inverse_[k];
      b.diagonal().array() += ridge;
      b = b.inverse().eval();
      along_[k] = b * coupling[k];
      schur_ -= coupling[k].dot(along_[k]);
    }
  }

  // The solution for each column of `rhs` (1 + 2 sectors rows).
  Eigen::MatrixXd solve(const Eigen::MatrixXd& rhs) const {
    Eigen::MatrixXd x(rhs.rows(), rhs.cols());
    Eigen::RowVectorXd level = rhs.row(0);
    for (std::size_t k = 0; k < block_inverse_.size(); ++k) {
      const Eigen::Index row = 1 + 2 * static_cast<Eigen::Index>(k);
      x.middleRows(row, 2).noalias() = block_inverse_[k] * rhs.middleRows(row, 2);
      level.noalias() -= along_[k].transpose() * rhs.middleRows(row, 2);
    }
    x.row(0) = level / schur_;
    for (std::size_t k = 0; k < block_inverse_.size(); ++k)
      x.middleRows(1 + 2 * static_cast<Eigen::Index>(k), 2).noalias() -= along_[k] * x.row(0);
    return x;
  }

 private:
  std::vector<Eigen::Matrix2d> block_inverse_;
  std::vector<Eigen::Vector2d> along_;  // each block's inverse times its coupling
  double schur_;                        // c0's diagonal with the pairs eliminated
};

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

  // The linear coefficients' least-squares solution for a profile, and the residuals it leaves.
  struct Solution {
    Eigen::VectorXd residuals;
    Eigen::VectorXd coefficients;  // c0, c1_0, c2_0, c1_1, ...
    ArrowNormal normal;
  };

  Solution solve(const Eigen::VectorXd& profile) const {
    const std::size_t sectors = waves_.size();
    double level = 0.0;
    std::vector<Eigen::Vector2d> coupling(sectors, Eigen::Vector2d::Zero());
    std::vector<Eigen::Matrix2d> blocks(sectors, Eigen::Matrix2d::Zero());
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(1 + 2 * static_cast<Eigen::Index>(sectors));
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const double a = profile(static_cast<Eigen::Index>(i));
      const std::size_t k = static_cast<std::size_t>(samples_[i].sector);
      const Eigen::Index row = 1 + 2 * static_cast<Eigen::Index>(k);
      const double b1 = a * cos_[i], b2 = a * sin_[i], y = samples_[i].signal;
      level += a * a;
      coupling[k] += Eigen::Vector2d(a * b1, a * b2);
      blocks[k](0, 0) += b1 * b1;
      blocks[k](0, 1) += b1 * b2;
      blocks[k](1, 1) += b2 * b2;
      rhs(0) += a * y;
      rhs(row) += b1 * y;
      rhs(row + 1) += b2 * y;
    }
    double trace = level;
    for (Eigen::Matrix2d& block : blocks) {
      block(1, 0) = block(0, 1);
      trace += block.trace();
    }
    // A tiny ridge keeps a sector without samples (or with a degenerate phase) solvable.
    const double ridge = 1e-9 * (trace / static_cast<double>(rhs.size()) + 1e-12);
    Solution solution{Eigen::VectorXd(static_cast<Eigen::Index>(samples_.size())), Eigen::VectorXd(),
                      ArrowNormal(level, coupling, std::move(blocks), ridge)};
    solution.coefficients = solution.normal.solve(rhs).col(0);
    for (std::size_t i = 0; i < samples_.size(); ++i)
      solution.residuals(static_cast<Eigen::Index>(i)) =
          samples_[i].signal - profile(static_cast<Eigen::Index>(i)) * modulation(solution.coefficients, i);
    return solution;
  }

  // The residuals' Jacobian with respect to the eight parameters, from the profile's (`profile_gradient`),
  // by Kaufman's approximation of the variable projection: the profile's change times the fitted
  // modulation, projected off the linear basis (the coefficients' own change is what the projection
  // removes to first order). One pass over the band, against nine evaluations by forward differences.
  BorderBandGradient jacobian(const Eigen::VectorXd& profile, const BorderBandGradient& profile_gradient,
                              const Solution& solution) const {
    const Eigen::Index n = static_cast<Eigen::Index>(samples_.size());
    BorderBandGradient change(n, kParams);
    Eigen::MatrixXd basis_dot_change = Eigen::MatrixXd::Zero(solution.coefficients.size(), kParams);
    for (Eigen::Index i = 0; i < n; ++i) {
      const std::size_t si = static_cast<std::size_t>(i);
      change.row(i) = profile_gradient.row(i) * modulation(solution.coefficients, si);
      const int k = 1 + 2 * samples_[si].sector;
      const double a = profile(i);
      basis_dot_change.row(0) += a * change.row(i);
      basis_dot_change.row(k) += a * cos_[si] * change.row(i);
      basis_dot_change.row(k + 1) += a * sin_[si] * change.row(i);
    }
    const Eigen::MatrixXd along_basis = solution.normal.solve(basis_dot_change);
    for (Eigen::Index i = 0; i < n; ++i) {
      const std::size_t si = static_cast<std::size_t>(i);
      const int k = 1 + 2 * samples_[si].sector;
      const double a = profile(i);
      change.row(i) -=
          a * (along_basis.row(0) + cos_[si] * along_basis.row(k) + sin_[si] * along_basis.row(k + 1));
    }
    return -change;
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
  // c0 + c1_k cos + c2_k sin at sample i.
  double modulation(const Eigen::VectorXd& coefficients, std::size_t i) const {
    const int k = 1 + 2 * samples_[i].sector;
    return coefficients(0) + coefficients(k) * cos_[i] + coefficients(k + 1) * sin_[i];
  }

  // A sector's residuals for the wave vector `wave` (its level and phase solved) and (optional) their
  // Jacobian with respect to the wave vector, by variable projection as in jacobian().
  Eigen::VectorXd sector_residuals(const std::vector<std::size_t>& members, cv::Vec2d wave,
                                   const Eigen::VectorXd& profile,
                                   Eigen::MatrixX2d* jacobian = nullptr) const {
    const Eigen::Index n = static_cast<Eigen::Index>(members.size());
    Eigen::ArrayXf phase(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const BorderBandSample& s = samples_[members[static_cast<std::size_t>(j)]];
      phase(j) = static_cast<float>(wave[0] * s.dx_px + wave[1] * s.dy_px);
    }
    const Eigen::ArrayXf cosine = phase.cos(), sine = phase.sin();  // in float, a vector register at a time
    // The products below in fixed 3 x 3 and 3 x 2 sizes, accumulated sample by sample: a sector holds a few
    // hundred samples, where Eigen's general matrix product spent more on its set-up than on the sums.
    Eigen::MatrixX3d basis(n, 3);
    Eigen::VectorXd y(n);
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (Eigen::Index j = 0; j < n; ++j) {
      const BorderBandSample& s = samples_[members[static_cast<std::size_t>(j)]];
      const double a = profile(static_cast<Eigen::Index>(members[static_cast<std::size_t>(j)]));
      const Eigen::Vector3d b(a, a * cosine(j), a * sine(j));
      basis.row(j) = b.transpose();
      y(j) = s.signal;
      normal.noalias() += b * b.transpose();
      rhs += b * y(j);
    }
    normal.diagonal().array() += 1e-9 * (normal.trace() + 1e-12);
    const Eigen::LDLT<Eigen::Matrix3d> factor = normal.ldlt();
    const Eigen::Vector3d coefficients = factor.solve(rhs);
    Eigen::VectorXd residuals(n);
    for (Eigen::Index j = 0; j < n; ++j) residuals(j) = y(j) - basis.row(j).dot(coefficients);
    if (jacobian) {
      // d/dphase of a (c1 cos + c2 sin) = a (c2 cos - c1 sin); dphase/dk = (dx, dy).
      Eigen::MatrixX2d change(n, 2);
      Eigen::Matrix<double, 3, 2> basis_dot_change = Eigen::Matrix<double, 3, 2>::Zero();
      for (Eigen::Index j = 0; j < n; ++j) {
        const BorderBandSample& s = samples_[members[static_cast<std::size_t>(j)]];
        const double along = coefficients(2) * basis(j, 1) - coefficients(1) * basis(j, 2);
        const Eigen::RowVector2d c(along * s.dx_px, along * s.dy_px);
        change.row(j) = c;
        basis_dot_change.noalias() += basis.row(j).transpose() * c;
      }
      const Eigen::Matrix<double, 3, 2> along_basis = factor.solve(basis_dot_change);
      jacobian->resize(n, 2);
      for (Eigen::Index j = 0; j < n; ++j) jacobian->row(j) = basis.row(j) * along_basis - change.row(j);
    }
    return residuals;
  }

  cv::Vec2d refined_wave(const std::vector<std::size_t>& members, cv::Vec2d wave,
                         const Eigen::VectorXd& profile) const {
    const double k0 = std::hypot(wave[0], wave[1]);
    if (!(k0 > 0.0)) return wave;
    Eigen::MatrixX2d jacobian;
    Eigen::VectorXd e = sector_residuals(members, wave, profile, &jacobian);
    double cost = e.squaredNorm(), damping = 1e-3;
    for (int iteration = 0; iteration < 6; ++iteration) {
      Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();
      Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
      for (Eigen::Index j = 0; j < e.size(); ++j) {
        jtj.noalias() += jacobian.row(j).transpose() * jacobian.row(j);
        gradient += jacobian.row(j).transpose() * e(j);
      }
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
        Eigen::MatrixX2d candidate_jacobian;
        const Eigen::VectorXd candidate_e =
            sector_residuals(members, candidate, profile, &candidate_jacobian);
        if (candidate_e.squaredNorm() < cost) {
          wave = candidate;
          e = candidate_e;
          jacobian = std::move(candidate_jacobian);
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
    Eigen::ArrayXf phase(static_cast<Eigen::Index>(samples_.size()));
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const cv::Vec2d& k = waves_[static_cast<std::size_t>(samples_[i].sector)];
      phase(static_cast<Eigen::Index>(i)) =
          static_cast<float>(k[0] * samples_[i].dx_px + k[1] * samples_[i].dy_px);
    }
    const Eigen::ArrayXf cosine = phase.cos(), sine = phase.sin();
    cos_.assign(cosine.begin(), cosine.end());
    sin_.assign(sine.begin(), sine.end());
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

// Levenberg-Marquardt on the eight parameters, the Jacobian by variable projection (Band::jacobian).
Params fit_parameters(const Band& band, Params p, double period_px, int iterations, double* rms) {
  BorderBandGradient profile_gradient;
  Eigen::VectorXd profile = border_profile(band.samples(), p, &profile_gradient);
  Band::Solution solution = band.solve(profile);
  double cost = solution.residuals.squaredNorm(), damping = 1e-3;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const BorderBandGradient jacobian = band.jacobian(profile, profile_gradient, solution);
    const Eigen::Matrix<double, kParams, kParams> jtj = jacobian.transpose() * jacobian;
    const Params gradient = jacobian.transpose() * solution.residuals;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, kParams, kParams> damped = jtj;
      for (int k = 0; k < kParams; ++k) damped(k, k) += damping * (jtj(k, k) + 1e-12);
      const Params candidate = clamped_profile(p - damped.ldlt().solve(gradient), period_px);
      if (!candidate.allFinite() || candidate(2) <= 2.0 || candidate(3) <= 2.0) {
        damping *= 10.0;
        continue;
      }
      BorderBandGradient candidate_gradient;
      Eigen::VectorXd candidate_profile = border_profile(band.samples(), candidate, &candidate_gradient);
      Band::Solution candidate_solution = band.solve(candidate_profile);
      const double candidate_cost = candidate_solution.residuals.squaredNorm();
      if (candidate_cost < cost) {
        const double gain = cost - candidate_cost;
        p = candidate;
        profile = std::move(candidate_profile);
        profile_gradient = std::move(candidate_gradient);
        solution = std::move(candidate_solution);
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
  *rms = std::sqrt(cost / static_cast<double>(std::max<Eigen::Index>(1, solution.residuals.size())));
  return p;
}

}  // namespace

Eigen::VectorXd border_profile(const std::vector<BorderBandSample>& samples, const BorderBandParams& p,
                               BorderBandGradient* gradient) {
  // Column by column over all samples, a vector register at a time (the fit evaluates this about 20 times a
  // frame on a few thousand samples).
  const double c = std::cos(p(4)), s = std::sin(p(4));
  const double inverse_a = 1.0 / p(2), inverse_b = 1.0 / p(3);
  const double edge = p(5), floor = p(6), fade = p(7);
  const Eigen::Index n = static_cast<Eigen::Index>(samples.size());
  Eigen::ArrayXd dx(n), dy(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    dx(i) = samples[static_cast<std::size_t>(i)].x_px - p(0);
    dy(i) = samples[static_cast<std::size_t>(i)].y_px - p(1);
  }
  const Eigen::ArrayXd u = (c * dx + s * dy) * inverse_a, v = (-s * dx + c * dy) * inverse_b;
  const Eigen::ArrayXd q = (u.square() + v.square()).sqrt().max(1e-9);
  const Eigen::ArrayXd r = (dx.square() + dy.square()).sqrt();
  const Eigen::ArrayXd d = r * (1.0 - q.inverse());
  const Eigen::ArrayXd step = ((d / edge).max(-50.0).min(50.0).exp() + 1.0).inverse();
  const Eigen::ArrayXd t = -d / fade;
  const Eigen::ArrayXd rise = smoothstep5_array(t);
  const Eigen::ArrayXd contrast = floor + (1.0 - floor) * rise;
  Eigen::VectorXd profile = (step * contrast).matrix();
  if (!gradient) return profile;
  gradient->resize(n, kParams);
  // A = L(d) F(d): L the logistic step, F the contrast's rise (smoothstep5' = 30 t^2 (1 - t)^2 inside).
  const Eigen::ArrayXd t_inside = t.max(0.0).min(1.0);
  const Eigen::ArrayXd rise_slope = 30.0 * (t_inside * (1.0 - t_inside)).square();
  const Eigen::ArrayXd step_slope = step * (1.0 - step);  // -dL/d(d / edge)
  const Eigen::ArrayXd da_dd = -step_slope / edge * contrast - step * (1.0 - floor) * rise_slope / fade;
  // d = r (1 - 1/q): dd = (1 - 1/q) dr + (r / q^2) dq, dq = (u du + v dv) / q.
  const Eigen::ArrayXd dd_dr = 1.0 - q.inverse(), dd_dq = r / q.square();
  const Eigen::ArrayXd inverse_r = (r > 1e-12).select(r.inverse(), 0.0);
  const Eigen::ArrayXd da_du = da_dd * dd_dq * u / q, da_dv = da_dd * dd_dq * v / q;
  const Eigen::ArrayXd da_dr = da_dd * dd_dr * inverse_r;
  gradient->col(0) = (-da_dr * dx + da_du * -c * inverse_a + da_dv * s * inverse_b).matrix();
  gradient->col(1) = (-da_dr * dy + da_du * -s * inverse_a + da_dv * -c * inverse_b).matrix();
  gradient->col(2) = (da_du * -u * inverse_a).matrix();
  gradient->col(3) = (da_dv * -v * inverse_b).matrix();
  // du/dtheta = v b / a, dv/dtheta = -u a / b.
  gradient->col(4) = (da_du * v * p(3) * inverse_a - da_dv * u * p(2) * inverse_b).matrix();
  gradient->col(5) = (step_slope * d / (edge * edge) * contrast).matrix();
  gradient->col(6) = (step * (1.0 - rise)).matrix();
  gradient->col(7) = (step * (1.0 - floor) * rise_slope * d / (fade * fade)).matrix();
  return profile;
}

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
  const double level = band.solve(border_profile(band.samples(), p)).coefficients(0);
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
