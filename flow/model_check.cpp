#include "flow/model_check.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace tirstrain::flow {
namespace {

// A floor on a match's predicted noise (px): the correlation of noise-free frames says nothing finer.
constexpr double kNoiseFloorPx = 1e-3;
// The variance of a direction no match measured, px² (a position anywhere within a thousand pixels).
constexpr double kUndetermined_px2 = 1e6;
// A translation direction whose information is below this share of the other's is taken as undetermined:
// the subset match leaves such directions at their start (flow/subset.cpp's eigenvalue floor, 2e-3 of the
// strongest on the scaled Hessian).
constexpr double kUndeterminedInformationRatio = 2e-3;

// Whitened residuals w = L⁻¹ r with C = L Lᵀ: independent, unit variance under the model.
std::vector<Eigen::Vector2d> whitened_residuals(const std::vector<OwnMatch>& matches, const RestTest& fit) {
  std::vector<Eigen::Vector2d> w(matches.size(), Eigen::Vector2d::Zero());
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const OwnMatch& m = matches[i];
    const Vec2 d = fit.displacement_px(m.reference_px);
    const Eigen::Vector2d r(m.position_px.x - m.reference_px.x - d.x,
                            m.position_px.y - m.reference_px.y - d.y);
    const Eigen::LLT<Eigen::Matrix2d> llt(m.covariance_px2);
    if (llt.info() == Eigen::Success) w[i] = llt.matrixL().solve(r);
  }
  return w;
}

// The correlation of whitened residuals over the pairs of independent neighbours, and its z-score: the
// products wᵢ·wⱼ of independent unit 2-vectors have mean 0 and variance 2, and are uncorrelated with each
// other, so the normalised sum is standard normal when the residuals carry no spatial structure.
void correlation_test(const std::vector<OwnMatch>& matches, const std::vector<Eigen::Vector2d>& w,
                      const RestTestOptions& options, RestTest& test) {
  const double near = options.independence_px, far = options.independence_px + options.pair_band_px;
  // Cells of side `far`: a pair lies in the same or a neighbouring cell.
  double min_x = matches[0].reference_px.x, min_y = matches[0].reference_px.y;
  double max_x = min_x, max_y = min_y;
  for (const OwnMatch& m : matches) {
    min_x = std::min(min_x, m.reference_px.x);
    min_y = std::min(min_y, m.reference_px.y);
    max_x = std::max(max_x, m.reference_px.x);
    max_y = std::max(max_y, m.reference_px.y);
  }
  const int cols = static_cast<int>((max_x - min_x) / far) + 1,
            rows = static_cast<int>((max_y - min_y) / far) + 1;
  std::vector<std::vector<int>> cells(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows));
  const auto cell_of = [&](const Vec2& p) {
    return std::pair{static_cast<int>((p.x - min_x) / far), static_cast<int>((p.y - min_y) / far)};
  };
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const auto [cx, cy] = cell_of(matches[i].reference_px);
    cells[static_cast<std::size_t>(cy * cols + cx)].push_back(static_cast<int>(i));
  }
  double products = 0.0, energy = 0.0;
  int pairs = 0;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const Vec2 p = matches[i].reference_px;
    const auto [cx, cy] = cell_of(p);
    for (int y = std::max(0, cy - 1); y <= std::min(rows - 1, cy + 1); ++y)
      for (int x = std::max(0, cx - 1); x <= std::min(cols - 1, cx + 1); ++x)
        for (int j : cells[static_cast<std::size_t>(y * cols + x)]) {
          if (static_cast<std::size_t>(j) <= i) continue;
          const Vec2 q = matches[static_cast<std::size_t>(j)].reference_px;
          const double d = std::hypot(p.x - q.x, p.y - q.y);
          if (d < near || d > far) continue;
          products += w[i].dot(w[static_cast<std::size_t>(j)]);
          energy += 0.5 * (w[i].squaredNorm() + w[static_cast<std::size_t>(j)].squaredNorm());
          ++pairs;
        }
  }
  test.pairs = pairs;
  if (pairs == 0 || !(energy > 0.0)) return;
  test.correlation = products / energy;
  test.correlation_z = test.correlation * std::sqrt(2.0 * pairs);
}

}  // namespace

const char* to_string(TrackModel model) {
  switch (model) {
    case TrackModel::kOwnMatch:
      return "own_match";
    case TrackModel::kFused:
      return "fused";
    case TrackModel::kRestFit:
      return "rest_fit";
    case TrackModel::kSmoothedInTime:
      return "smoothed_in_time";
    case TrackModel::kLocalFit:
      return "local_fit";
    case TrackModel::kAffineFit:
      return "affine_fit";
  }
  return "?";
}

double correlated_pixels(double prefilter_sigma_px, int stride) {
  const double s = std::max(1, stride);
  return std::max(1.0, 4.0 * std::numbers::pi * prefilter_sigma_px * prefilter_sigma_px / (s * s));
}

Eigen::Matrix2d predicted_match_covariance(double zncc, std::size_t pixel_count,
                                           const Eigen::Matrix2d& information, double correlated) {
  const double floor2 = kNoiseFloorPx * kNoiseFloorPx;
  const Eigen::Matrix2d floor = floor2 * Eigen::Matrix2d::Identity();
  if (pixel_count == 0 || !(information.determinant() > 0.0))
    return kUndetermined_px2 * Eigen::Matrix2d::Identity();
  const double difference = 2.0 * std::max(1.0 - zncc, 0.0);  // Σ (f − g)² / Σ f²
  const double per_pixel = difference / static_cast<double>(pixel_count) * std::max(1.0, correlated);
  // A direction the texture barely determines (straight ridges: along them) is one the match does not solve
  // for (Subset's eigenvalue floor) and keeps from its start: its noise formula would promise a precision
  // the match never had there, so the direction counts as not measured.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(information);
  const Eigen::Vector2d lambda = eig.eigenvalues();
  if (!(lambda(0) >= kUndeterminedInformationRatio * lambda(1))) {
    const Eigen::Vector2d weak = eig.eigenvectors().col(0), strong = eig.eigenvectors().col(1);
    return per_pixel / lambda(1) * strong * strong.transpose() +
           kUnmeasuredVariance_px2 * weak * weak.transpose() + floor;
  }
  return per_pixel * information.inverse() + floor;
}

bool has_unmeasured_direction(const Eigen::Matrix2d& covariance_px2) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(covariance_px2);
  return eig.eigenvalues()(1) >= 0.5 * kUnmeasuredVariance_px2;
}

double mahalanobis2(Vec2 shift_px, const Eigen::Matrix2d& covariance_px2) {
  const Eigen::Vector2d s(shift_px.x, shift_px.y);
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(covariance_px2);
  if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return s.dot(ldlt.solve(s));
}

Vec2 RestTest::displacement_px(Vec2 reference_px) const {
  const Eigen::Vector3d b(1.0, reference_px.x - origin_px.x, reference_px.y - origin_px.y);
  const Eigen::Vector2d d = coefficients.transpose() * b;
  return {d.x(), d.y()};
}

Gradient2 RestTest::gradient() const {
  return {coefficients(1, 0), coefficients(2, 0), coefficients(1, 1), coefficients(2, 1)};
}

RestTest test_affine_model(const std::vector<OwnMatch>& matches, const RestTestOptions& options) {
  RestTest test;
  test.tracks = static_cast<int>(matches.size());
  if (test.tracks < options.min_tracks) return test;
  for (const OwnMatch& m : matches) {
    test.origin_px.x += m.reference_px.x / test.tracks;
    test.origin_px.y += m.reference_px.y / test.tracks;
  }
  // Generalised least squares d = a + B (X − X0), each match weighted by its inverse covariance: a
  // subset's along-ridge noise then does not enter the fit, its neighbours' other ridge directions decide.
  // θ = (a_x, B_xx, B_xy, a_y, B_yx, B_yy).
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  Matrix6 normal = Matrix6::Zero();
  Vector6 rhs = Vector6::Zero();
  for (const OwnMatch& m : matches) {
    const double dx = m.reference_px.x - test.origin_px.x, dy = m.reference_px.y - test.origin_px.y;
    Eigen::Matrix<double, 2, 6> b = Eigen::Matrix<double, 2, 6>::Zero();
    b.row(0) << 1.0, dx, dy, 0.0, 0.0, 0.0;
    b.row(1) << 0.0, 0.0, 0.0, 1.0, dx, dy;
    const Eigen::Matrix2d weight = m.covariance_px2.inverse();
    if (!weight.allFinite()) continue;
    const Eigen::Vector2d d(m.position_px.x - m.reference_px.x, m.position_px.y - m.reference_px.y);
    normal += b.transpose() * weight * b;
    rhs += b.transpose() * weight * d;
  }
  const Eigen::LDLT<Matrix6> solver(normal);
  if (solver.info() != Eigen::Success || !solver.isPositive()) return test;
  const Vector6 theta = solver.solve(rhs);
  if (!theta.allFinite()) return test;
  test.coefficients << theta(0), theta(3), theta(1), theta(4), theta(2), theta(5);

  const std::vector<Eigen::Vector2d> w = whitened_residuals(matches, test);
  double chi2 = 0.0;
  for (const Eigen::Vector2d& v : w) chi2 += v.squaredNorm();
  test.chi2_per_dof = chi2 / static_cast<double>(2 * test.tracks - 6);
  correlation_test(matches, w, options, test);
  const bool structured =
      test.correlation_z > options.max_correlation_z && test.correlation > options.max_correlation;
  test.affine =
      test.chi2_per_dof <= options.max_chi2_per_dof && test.pairs >= options.min_pairs && !structured;
  // Nil motion: θ against zero in its covariance, the inverse normal matrix times the tracks that share
  // their noise (overlapping subsets); χ² with 6 degrees of freedom when nothing moved.
  double motion2 = 0.0;
  for (const OwnMatch& m : matches) {
    const Vec2 d = test.displacement_px(m.reference_px);
    motion2 += d.x * d.x + d.y * d.y;
  }
  test.motion_rms_px = std::sqrt(motion2 / test.tracks);
  test.motion_chi2 = theta.dot(normal * theta) / std::max(1.0, options.correlated_tracks);
  test.accepted = test.affine &&
                  (test.motion_rms_px <= options.tolerance_px || test.motion_chi2 <= options.max_motion_chi2);
  return test;
}

}  // namespace tirstrain::flow
