#include "flow/local_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "flow/detail/small_cholesky.hpp"

namespace tirstrain::flow {
namespace {

// A floor on a match's predicted noise (px): the correlation of noise-free frames says nothing finer.
constexpr double kNoiseFloorPx = 1e-3;

// One match as the fits read it: its displacement and its weight (inverse covariance).
struct Sample {
  Vec2 reference_px;
  Eigen::Vector2d displacement_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d weight = Eigen::Matrix2d::Zero();
  bool usable = false;
};

std::vector<Sample> samples_of(const std::vector<OwnMatch>& matches) {
  std::vector<Sample> samples(matches.size());
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const OwnMatch& m = matches[i];
    Sample& s = samples[i];
    s.reference_px = m.reference_px;
    s.displacement_px = {m.position_px.x - m.reference_px.x, m.position_px.y - m.reference_px.y};
    s.covariance_px2 = m.covariance_px2 + kNoiseFloorPx * kNoiseFloorPx * Eigen::Matrix2d::Identity();
    const Eigen::LLT<Eigen::Matrix2d> llt(s.covariance_px2);
    s.usable = s.covariance_px2.allFinite() && s.displacement_px.allFinite() && llt.info() == Eigen::Success;
    if (s.usable) s.weight = llt.solve(Eigen::Matrix2d::Identity());
  }
  return samples;
}

// One thread's buffers for a match's neighbours.
struct NeighbourBuffers {
  std::vector<std::pair<double, int>> near, scratch;  // (squared distance, index)
  std::vector<std::size_t> window, start;             // each scratch entry's window; each window's start
};

// Matches by cell of side `cell_px` over their reference positions, for the neighbours within a radius.
class CellIndex {
 public:
  CellIndex(const std::vector<Sample>& samples, double cell_px) : cell_(cell_px) {
    if (samples.empty()) return;
    min_x_ = max_x_ = samples[0].reference_px.x;
    min_y_ = max_y_ = samples[0].reference_px.y;
    for (const Sample& s : samples) {
      min_x_ = std::min(min_x_, s.reference_px.x);
      min_y_ = std::min(min_y_, s.reference_px.y);
      max_x_ = std::max(max_x_, s.reference_px.x);
      max_y_ = std::max(max_y_, s.reference_px.y);
    }
    cols_ = static_cast<int>((max_x_ - min_x_) / cell_) + 1;
    rows_ = static_cast<int>((max_y_ - min_y_) / cell_) + 1;
    cells_.resize(static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_));
    for (std::size_t i = 0; i < samples.size(); ++i)
      if (samples[i].usable) cells_[cell_of(samples[i].reference_px)].push_back(static_cast<int>(i));
  }

  // (squared distance, index) of every usable match within the largest of `radii_px` (ascending) of `p`,
  // grouped by the smallest radius each lies within, smaller first: a window's fit does not depend on the
  // order of its matches, so no finer order is needed. Into `buffers.near`.
  void within(const std::vector<Sample>& samples, Vec2 p, const std::vector<double>& radii_px,
              NeighbourBuffers& buffers) const {
    std::vector<std::pair<double, int>>& scratch = buffers.scratch;
    std::vector<std::pair<double, int>>& out = buffers.near;
    scratch.clear();
    const int cx = static_cast<int>((p.x - min_x_) / cell_), cy = static_cast<int>((p.y - min_y_) / cell_);
    const double r2 = radii_px.back() * radii_px.back();
    const int reach = static_cast<int>(std::ceil(radii_px.back() / cell_));
    for (int y = std::max(0, cy - reach); y <= std::min(rows_ - 1, cy + reach); ++y)
      for (int x = std::max(0, cx - reach); x <= std::min(cols_ - 1, cx + reach); ++x)
        for (int j : cells_[static_cast<std::size_t>(y * cols_ + x)]) {
          const Vec2 q = samples[static_cast<std::size_t>(j)].reference_px;
          const double d2 = (q.x - p.x) * (q.x - p.x) + (q.y - p.y) * (q.y - p.y);
          if (d2 <= r2) scratch.emplace_back(d2, j);
        }
    // A counting sort by window.
    const std::size_t windows = radii_px.size();
    const auto window_of = [&](double d2) {
      std::size_t w = 0;
      while (w + 1 < windows && d2 > radii_px[w] * radii_px[w]) ++w;
      return w;
    };
    std::vector<std::size_t>& window = buffers.window;
    std::vector<std::size_t>& start = buffers.start;
    window.resize(scratch.size());
    start.assign(windows + 1, 0);
    for (std::size_t k = 0; k < scratch.size(); ++k) ++start[(window[k] = window_of(scratch[k].first)) + 1];
    for (std::size_t w = 0; w < windows; ++w) start[w + 1] += start[w];
    out.resize(scratch.size());
    for (std::size_t k = 0; k < scratch.size(); ++k) out[start[window[k]]++] = scratch[k];
  }

 private:
  std::size_t cell_of(Vec2 p) const {
    const int x = static_cast<int>((p.x - min_x_) / cell_), y = static_cast<int>((p.y - min_y_) / cell_);
    return static_cast<std::size_t>(y * cols_ + x);
  }
  double cell_ = 1.0, min_x_ = 0.0, min_y_ = 0.0, max_x_ = 0.0, max_y_ = 0.0;
  int cols_ = 0, rows_ = 0;
  std::vector<std::vector<int>> cells_;
};

// The weighted least-squares normal equations of a polynomial field in (X − X_i) / scale, built up one
// match at a time (the window grows by adding the next nearest matches). K basis functions per component:
// 3 for an affine field d(X) = c + B (X − X_i) / scale, 6 with the second-order terms as well.
//
// Entry (p, q) of the normal matrix's block for weight element w is Σ w a_p a_q, and the products a_p a_q
// are the monomials of (u, v) up to twice the basis's degree, fewer than the pairs (15 for 21 pairs of the
// second-order basis, 6 for 6 of the affine one). So a match adds its weights times each monomial once, and
// the matrix is assembled from those sums when a window is solved.
template <int K>
class PolynomialAccumulator {
 public:
  static constexpr int kParameters = 2 * K;
  static constexpr int kMonomials = K == 6 ? 15 : 6;
  using Matrix = Eigen::Matrix<double, kParameters, kParameters>;
  using Vector = Eigen::Matrix<double, kParameters, 1>;

  PolynomialAccumulator(Vec2 centre, double scale_px, double correlation_side_px)
      : centre_(centre), scale_(scale_px), side_(correlation_side_px) {}

  void add(const Sample& s) {
    const double dx = s.reference_px.x - centre_.x, dy = s.reference_px.y - centre_.y;
    const double u = dx / scale_, v = dy / scale_;
    const double uu = u * u, uv = u * v, vv = v * v;
    // Monomials in the order of monomial_of(): degree 0–2, then (second order) 3 and 4.
    Eigen::Matrix<double, kMonomials, 1> m;
    m.template head<6>() << 1.0, u, v, uu, uv, vv;
    if constexpr (K == 6)
      m.template tail<9>() << uu * u, uu * v, u * vv, vv * v, uu * uu, uu * uv, uu * vv, uv * vv, vv * vv;
    moments_.col(0) += s.weight(0, 0) * m;
    moments_.col(1) += s.weight(0, 1) * m;
    moments_.col(2) += s.weight(1, 1) * m;
    const Eigen::Vector2d wd = s.weight * s.displacement_px;
    for (int p = 0; p < K; ++p) rhs_.template segment<2>(2 * p) += m[p] * wd;
    energy_ += s.displacement_px.dot(wd);
    ++count_;
    count_overlap(s);
  }

  // Overlapping subsets share noise in proportion to their overlap.
  void count_overlap(const Sample& s) {
    const double dx = s.reference_px.x - centre_.x, dy = s.reference_px.y - centre_.y;
    correlation_ += std::max(0.0, 1.0 - std::abs(dx) / side_) * std::max(0.0, 1.0 - std::abs(dy) / side_);
  }

  int count() const { return count_; }
  // Σ_j of the overlap of match j's subset with the centre's: how many matches' worth of noise it shares.
  double shared_noise() const { return correlation_; }

  // The solved fit: parameters, the inverse normal matrix (the parameters' covariance for independent
  // matches: all of it when asked for, else its top-left 2×2, the value's at the centre) and the residual χ².
  struct Solution {
    Vector theta;
    Matrix inverse;
    Eigen::Matrix2d centre_covariance;
    double rss = 0.0;
    int dof = 0;
  };
  // A window whose normal matrix is not positive definite, or whose reciprocal condition number is not
  // above 1e-10 (as Eigen's LLT estimates it), has no solution.
  bool solve_all(Solution& out, bool full_inverse = false) const {
    const Matrix n = normal();
    // One solve for the parameters and the value's two columns of the inverse.
    Eigen::Matrix<double, kParameters, 3> right = Eigen::Matrix<double, kParameters, 3>::Zero();
    right.col(0) = rhs_;
    right(0, 1) = 1.0;
    right(1, 2) = 1.0;
    detail::SmallCholesky<kParameters> cholesky;
    // The comparison bound is the cheaper test; the explicit L⁻¹ only where it is too loose.
    if (!full_inverse && cholesky.compute(n) &&
        (cholesky.rcond_comparison_bound() > 1e-10 || cholesky.rcond_lower_bound() > 1e-10)) {
      cholesky.solve_in_place(right);
    } else {
      // The full inverse, or a window near the conditioning limit: Eigen's estimate decides.
      const Eigen::LLT<Matrix, Eigen::Lower> llt(n);
      if (llt.info() != Eigen::Success || !(llt.rcond() > 1e-10)) return false;
      if (full_inverse) {
        out.inverse = llt.solve(Matrix::Identity());
        right.col(0) = llt.solve(rhs_);
        right.template rightCols<2>() = out.inverse.template leftCols<2>();
      } else {
        right = llt.solve(right).eval();
      }
    }
    out.theta = right.col(0);
    out.centre_covariance = right.template block<2, 2>(0, 1);
    out.rss = std::max(0.0, energy_ - out.theta.dot(rhs_));
    out.dof = 2 * count_ - kParameters;
    return out.theta.allFinite() && out.centre_covariance.allFinite() &&
           (!full_inverse || out.inverse.allFinite());
  }

 private:
  Vec2 centre_;
  double scale_, side_;
  // Index into the monomials of a_p a_q (basis 1, u, v, u², uv, v²).
  static constexpr int monomial_of(int p, int q) {
    // Exponents of u and v of each basis function, and the monomials' index by (i, j) = exponents.
    constexpr int eu[6] = {0, 1, 0, 2, 1, 0}, ev[6] = {0, 0, 1, 0, 1, 2};
    constexpr int index[5][5] = {
        {0, 2, 5, 9, 14}, {1, 4, 8, 13, -1}, {3, 7, 12, -1, -1}, {6, 11, -1, -1, -1}, {10, -1, -1, -1, -1}};
    return index[eu[p] + eu[q]][ev[p] + ev[q]];
  }
  // The lower triangle of the normal matrix (the solver reads no more; a weight matrix is symmetric).
  Matrix normal() const {
    Matrix n = Matrix::Zero();
    for (int p = 0; p < K; ++p)
      for (int q = 0; q <= p; ++q) {
        const int k = monomial_of(p, q);
        n(2 * p, 2 * q) = moments_(k, 0);
        n(2 * p + 1, 2 * q) = moments_(k, 1);
        n(2 * p + 1, 2 * q + 1) = moments_(k, 2);
        if (q < p) n(2 * p, 2 * q + 1) = moments_(k, 1);
      }
    return n;
  }

  // Column c: Σ w m_k over the matches, w the weight's element 00, 01 or 11.
  Eigen::Matrix<double, kMonomials, 3> moments_ = Eigen::Matrix<double, kMonomials, 3>::Zero();
  Vector rhs_ = Vector::Zero();
  double energy_ = 0.0, correlation_ = 0.0;
  int count_ = 0;
};

// Whether residuals with χ² `rss` over `dof` degrees of freedom are the matches' noise: below the upper
// quantile (z standard deviations, Wilson–Hilferty) of χ²_ν / ν, with ν the independent share of the
// degrees of freedom when each match shares its noise with `shared` others.
bool residuals_are_noise(double rss, int dof, double shared, double z, double& chi2_per_dof) {
  chi2_per_dof = dof > 0 ? rss / dof : 0.0;
  if (dof <= 0) return true;
  const double nu = std::max(1.0, dof / shared);
  const double h = 2.0 / (9.0 * nu);
  return chi2_per_dof <= std::pow(1.0 - h + z * std::sqrt(h), 3);
}

using AffineAccumulator = PolynomialAccumulator<3>;

// The affine fit of every match in the frame: the widest window of all, tried where the local windows
// reached their largest radius.
struct FrameFit {
  bool valid = false;
  Vec2 centre;
  double scale_px = 1.0;
  int count = 0;
  double min_x = 0.0, min_y = 0.0, max_x = 0.0, max_y = 0.0;  // the matches' bounding box
  AffineAccumulator::Solution solution;
  // Each component's own affine fit, weighted by that component's variances alone: where the other
  // component is not affine, the joint fit's correlated weights carry that misfit into this one.
  struct ComponentFit {
    bool valid = false;
    Eigen::Vector3d theta = Eigen::Vector3d::Zero();
    Eigen::Matrix3d inverse = Eigen::Matrix3d::Zero();
    double rss = 0.0;  // residual χ² in the component's own variances
  };
  std::array<ComponentFit, 2> components;

  FrameFit(const std::vector<Sample>& samples, double correlation_side_px) {
    double sx = 0.0, sy = 0.0, extent = 1.0;
    for (const Sample& s : samples)
      if (s.usable) {
        sx += s.reference_px.x;
        sy += s.reference_px.y;
        ++count;
      }
    if (count < 3) return;
    centre = {sx / count, sy / count};
    min_x = max_x = centre.x;
    min_y = max_y = centre.y;
    for (const Sample& s : samples)
      if (s.usable) {
        extent =
            std::max({extent, std::abs(s.reference_px.x - centre.x), std::abs(s.reference_px.y - centre.y)});
        min_x = std::min(min_x, s.reference_px.x);
        max_x = std::max(max_x, s.reference_px.x);
        min_y = std::min(min_y, s.reference_px.y);
        max_y = std::max(max_y, s.reference_px.y);
      }
    scale_px = extent;
    AffineAccumulator all(centre, scale_px, correlation_side_px);
    for (const Sample& s : samples)
      if (s.usable) all.add(s);
    valid = all.solve_all(solution, true);
    if (valid)
      for (int c = 0; c < 2; ++c) components[static_cast<std::size_t>(c)] = component_fit(samples, c);
  }

  Eigen::Vector3d basis(Vec2 X) const {
    return {1.0, (X.x - centre.x) / scale_px, (X.y - centre.y) / scale_px};
  }

  ComponentFit component_fit(const std::vector<Sample>& samples, int c) const {
    ComponentFit fit;
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    double energy = 0.0;
    for (const Sample& s : samples)
      if (s.usable) {
        const Eigen::Vector3d a = basis(s.reference_px);
        const double w = 1.0 / s.covariance_px2(c, c), d = s.displacement_px(c);
        normal += w * a * a.transpose();
        rhs += w * d * a;
        energy += w * d * d;
      }
    const Eigen::LLT<Eigen::Matrix3d> llt(normal);
    if (llt.info() != Eigen::Success || !(llt.rcond() > 1e-10)) return fit;
    fit.theta = llt.solve(rhs);
    fit.inverse = llt.solve(Eigen::Matrix3d::Identity());
    fit.rss = std::max(0.0, energy - fit.theta.dot(rhs));
    fit.valid = fit.theta.allFinite() && fit.inverse.allFinite();
    return fit;
  }

  // Component c's own fit at X and its variance for independent matches.
  bool component_at(Vec2 X, int c, double& value, double& variance) const {
    const ComponentFit& fit = components[static_cast<std::size_t>(c)];
    if (!fit.valid) return false;
    const Eigen::Vector3d a = basis(X);
    value = a.dot(fit.theta);
    variance = a.dot(fit.inverse * a);
    return true;
  }

  // How far from X the frame's matches reach: the window the frame's fit covers, seen from X.
  double reach_px(Vec2 X) const {
    const double dx = std::max(X.x - min_x, max_x - X.x), dy = std::max(X.y - min_y, max_y - X.y);
    return std::hypot(dx, dy);
  }

  // The fit at X and its covariance for independent matches.
  void at(Vec2 X, Eigen::Vector2d& value, Eigen::Matrix2d& covariance) const {
    Eigen::Matrix<double, 2, 6> a;
    a << Eigen::Matrix2d::Identity(), (X.x - centre.x) / scale_px * Eigen::Matrix2d::Identity(),
        (X.y - centre.y) / scale_px * Eigen::Matrix2d::Identity();
    value = a * solution.theta;
    covariance = a * solution.inverse * a.transpose();
  }
};

double mahalanobis2_of(const Eigen::Vector2d& difference, const Eigen::Matrix2d& covariance) {
  const Eigen::LLT<Eigen::Matrix2d> llt(covariance);
  if (llt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return difference.dot(llt.solve(difference));
}

// An estimate a wider window must agree with.
struct Estimate {
  Eigen::Vector2d value;
  Eigen::Matrix2d covariance;
};

// The χ² bound with one degree of freedom that has the same tail probability as `chi2_2` with two
// (9.21 → 6.63): P(χ²₁ > x) = erfc(√(x / 2)), P(χ²₂ > c) = exp(−c / 2).
double one_component_bound(double chi2_2) {
  const double tail = std::exp(-0.5 * chi2_2);
  double low = 0.0, high = 200.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (low + high);
    (std::erfc(std::sqrt(0.5 * mid)) > tail ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

// Where the joint windows stop, each component alone against the frame's fit of that component (see
// local_fit.hpp): kept when that fit's residuals are noise and it agrees with every finer estimate of the
// component, in the component's own variance. `shared`: how many matches' noise the track's shares.
// `bound`: one_component_bound of the options' agreement χ².
void extend_components_to_frame(const FrameFit& frame, const Sample& own, const std::vector<Estimate>& finer,
                                double shared, double bound, const LocalFitOptions& options, LocalFit& out) {
  const LocalFit joint_fit = out;
  const Eigen::Matrix2d joint = out.covariance_px2;
  bool extended = false;
  for (int c = 0; c < 2; ++c) {
    double value = 0.0, variance = 0.0, chi2 = 0.0;
    const FrameFit::ComponentFit& fit = frame.components[static_cast<std::size_t>(c)];
    if (!frame.component_at(own.reference_px, c, value, variance) ||
        !residuals_are_noise(fit.rss, frame.count - 3, shared, options.residual_quantile_z, chi2))
      continue;
    variance *= shared;
    const bool agrees = std::all_of(finer.begin(), finer.end(), [&](const Estimate& e) {
      return (value - e.value(c)) * (value - e.value(c)) <= bound * e.covariance(c, c);
    });
    if (!agrees) continue;
    (c == 0 ? out.displacement_px.x : out.displacement_px.y) = value;
    out.covariance_px2(c, c) = variance;
    out.component_radius_px[static_cast<std::size_t>(c)] = frame.reach_px(own.reference_px);
    extended = true;
  }
  if (!extended) return;
  // The components now come from different fits: their correlation is kept as the joint estimate had it.
  const double correlation = joint(0, 1) / std::sqrt(joint(0, 0) * joint(1, 1));
  out.covariance_px2(0, 1) = out.covariance_px2(1, 0) =
      std::isfinite(correlation)
          ? correlation * std::sqrt(out.covariance_px2(0, 0) * out.covariance_px2(1, 1))
          : 0.0;
  // The two components together still agree with every finer estimate, as a joint window must.
  const Eigen::Vector2d reported(out.displacement_px.x, out.displacement_px.y);
  double worst = 0.0;
  for (const Estimate& e : finer) worst = std::max(worst, mahalanobis2_of(reported - e.value, e.covariance));
  if (!(worst <= options.agreement_chi2)) {
    out = joint_fit;
    return;
  }
  out.agreement_chi2 = worst;
  out.own_mahalanobis2 = mahalanobis2_of(reported - own.displacement_px, own.covariance_px2);
}

// The widest window that agrees with every finer estimate and whose residuals are noise, for match i; the
// local fits have K basis functions per component. Where the joint windows stop, each component is tried
// alone against the frame's fit of it (LocalFitOptions::per_component).
template <int K>
LocalFit fit_one(const std::vector<Sample>& samples, std::size_t i, const CellIndex& index,
                 const FrameFit* frame, double component_bound, const LocalFitOptions& options,
                 NeighbourBuffers& buffers) {
  const Sample& own = samples[i];
  LocalFit out;
  out.displacement_px = {own.displacement_px.x(), own.displacement_px.y()};
  out.covariance_px2 = own.covariance_px2;
  if (!own.usable || options.radii_px.empty()) return out;
  index.within(samples, own.reference_px, options.radii_px, buffers);
  const std::vector<std::pair<double, int>>& near = buffers.near;
  PolynomialAccumulator<K> accumulator(own.reference_px, options.radii_px.back(),
                                       options.correlation_side_px);
  const int min_tracks = std::max(options.min_tracks, PolynomialAccumulator<K>::kParameters);
  std::vector<Estimate> finer{{own.displacement_px, own.covariance_px2}};
  std::size_t next = 0;
  // A wider estimate is kept when it agrees with every finer one (the own match included).
  const auto agrees = [&](const Estimate& fit, double& worst) {
    worst = 0.0;
    for (const Estimate& e : finer)
      worst = std::max(worst, mahalanobis2_of(fit.value - e.value, e.covariance));
    return worst <= options.agreement_chi2;
  };
  const auto take = [&](const Estimate& fit, int window, double radius_px, int tracks, double worst,
                        double chi2) {
    out.window = window;
    out.radius_px = radius_px;
    out.component_radius_px = {radius_px, radius_px};
    out.tracks = tracks;
    out.displacement_px = {fit.value.x(), fit.value.y()};
    out.covariance_px2 = fit.covariance;
    out.agreement_chi2 = worst;
    out.own_mahalanobis2 = mahalanobis2_of(fit.value - own.displacement_px, own.covariance_px2);
    out.residual_chi2_per_dof = chi2;
    finer.push_back(fit);
  };
  const int windows = static_cast<int>(options.radii_px.size());
  bool stopped = false;
  for (int w = 0; w < windows; ++w) {
    const double r2 =
        options.radii_px[static_cast<std::size_t>(w)] * options.radii_px[static_cast<std::size_t>(w)];
    // Once the joint windows have stopped, the wider ones only count the noise the frame's fit shares.
    for (; next < near.size() && near[next].first <= r2; ++next) {
      const Sample& s = samples[static_cast<std::size_t>(near[next].second)];
      if (stopped)
        accumulator.count_overlap(s);
      else
        accumulator.add(s);
    }
    typename PolynomialAccumulator<K>::Solution solution;
    if (stopped || accumulator.count() < min_tracks || !accumulator.solve_all(solution)) continue;
    // A mean over n matches that share noise is quieter than n independent ones by the overlap it counts.
    const double shared =
        std::clamp(accumulator.shared_noise(), 1.0, static_cast<double>(accumulator.count()));
    const Estimate fit{solution.theta.template head<2>(), shared * solution.centre_covariance};
    double chi2 = 0.0, worst = 0.0;
    stopped = !residuals_are_noise(solution.rss, solution.dof, shared, options.residual_quantile_z, chi2) ||
              !agrees(fit, worst);
    if (!stopped)
      take(fit, w, options.radii_px[static_cast<std::size_t>(w)], accumulator.count(), worst, chi2);
  }
  if (frame == nullptr || !frame->valid) return out;
  const double shared = std::clamp(accumulator.shared_noise(), 1.0, static_cast<double>(frame->count));
  if (!stopped && out.window == windows - 1) {
    Estimate fit;
    frame->at(own.reference_px, fit.value, fit.covariance);
    fit.covariance *= shared;
    double chi2 = 0.0, worst = 0.0;
    if (residuals_are_noise(frame->solution.rss, frame->solution.dof, shared, options.residual_quantile_z,
                            chi2) &&
        agrees(fit, worst)) {
      take(fit, windows, frame->reach_px(own.reference_px), frame->count, worst, chi2);
      return out;
    }
  }
  if (options.per_component)
    extend_components_to_frame(*frame, own, finer, shared, component_bound, options, out);
  return out;
}

}  // namespace

std::vector<LocalFit> choose_local_fits(const std::vector<OwnMatch>& matches,
                                        const LocalFitOptions& options) {
  const std::vector<Sample> samples = samples_of(matches);
  std::vector<LocalFit> fits(matches.size());
  if (matches.empty()) return fits;
  const double reach = options.radii_px.empty() ? 1.0 : options.radii_px.back();
  // Cells of half the widest radius: the 5 × 5 cells scanned cover 6.25 r² for a disc of 3.14 r².
  const CellIndex index(samples, std::max(1.0, 0.5 * reach));
  const FrameFit frame(samples, options.correlation_side_px);
  const double component_bound = one_component_bound(options.agreement_chi2);
  const FrameFit* whole_frame = options.whole_frame ? &frame : nullptr;
  cv::parallel_for_(cv::Range(0, static_cast<int>(matches.size())), [&](const cv::Range& range) {
    NeighbourBuffers buffers;
    for (int i = range.start; i < range.end; ++i)
      fits[static_cast<std::size_t>(i)] = options.order == 2
                                              ? fit_one<6>(samples, static_cast<std::size_t>(i), index,
                                                           whole_frame, component_bound, options, buffers)
                                              : fit_one<3>(samples, static_cast<std::size_t>(i), index,
                                                           whole_frame, component_bound, options, buffers);
  });
  return fits;
}

}  // namespace tirstrain::flow
