// The predicted standard deviation of a triangle's strain (strain/uncertainty.hpp) against Monte Carlo:
// vertices perturbed with their covariances, the exact Green–Lagrange strain of each draw.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/tensor2.hpp"
#include "strain/deformation.hpp"
#include "strain/uncertainty.hpp"

namespace tirstrain::strain {
namespace {

struct Moments {
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  void add(double v) {
    sum += v;
    sum2 += v * v;
    ++n;
  }
  double sd() const { return std::sqrt(sum2 / n - (sum / n) * (sum / n)); }
};

TEST(StrainUncertainty, MatchesMonteCarloOnAStretchedShearedTriangle) {
  const std::array<Vec2, 3> X = {Vec2{0.0, 0.0}, Vec2{8.0, 0.5}, Vec2{3.0, 7.5}};
  // A large strain (F far from I) so that the propagation's F-dependence is exercised: 20 % stretch in x,
  // 10 % compression in y, shear.
  const auto map = [](Vec2 p) { return Vec2{1.2 * p.x + 0.15 * p.y + 40.0, -0.05 * p.x + 0.9 * p.y + 12.0}; };
  const std::array<Vec2, 3> x = {map(X[0]), map(X[1]), map(X[2])};
  // Anisotropic, correlated, different per vertex (px²).
  const std::array<PositionCovariance, 3> C = {PositionCovariance{0.0025, 0.0010, 0.0016},
                                               PositionCovariance{0.0009, -0.0003, 0.0036},
                                               PositionCovariance{0.0016, 0.0, 0.0016}};
  const Strain2 predicted = strain_standard_deviation(X, x, C);

  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  Moments exx, eyy, exy;
  for (int draw = 0; draw < 40000; ++draw) {
    std::array<Vec2, 3> noisy = x;
    for (std::size_t v = 0; v < 3; ++v) {
      // Cholesky of [[a, b], [b, c]].
      const double a = C[v][0], b = C[v][1], c = C[v][2];
      const double l11 = std::sqrt(a), l21 = b / l11, l22 = std::sqrt(c - l21 * l21);
      const double z1 = normal(rng), z2 = normal(rng);
      noisy[v].x += l11 * z1;
      noisy[v].y += l21 * z1 + l22 * z2;
    }
    const Strain2 e = green_lagrange(displacement_gradient(X, noisy));
    exx.add(e.xx);
    eyy.add(e.yy);
    exy.add(e.xy);
  }
  // First-order propagation: exact but for the quadratic term of E, negligible at these noise levels
  // (σ_x / edge ≈ 0.006). Monte Carlo with 40 000 draws: ±0.7 % (1σ) on each SD.
  EXPECT_NEAR(predicted.xx / exx.sd(), 1.0, 0.03);
  EXPECT_NEAR(predicted.yy / eyy.sd(), 1.0, 0.03);
  EXPECT_NEAR(predicted.xy / exy.sd(), 1.0, 0.03);
  EXPECT_GT(predicted.xx, 0.003);  // the scale of the case: 0.05 px on 8 px edges
}

TEST(StrainUncertainty, MissingCovarianceOrDegenerateTriangleGivesNaN) {
  const std::array<Vec2, 3> X = {Vec2{0.0, 0.0}, Vec2{8.0, 0.0}, Vec2{0.0, 8.0}};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::array<PositionCovariance, 3> C{};
  C.fill({0.001, 0.0, 0.001});
  C[1] = {nan, nan, nan};
  EXPECT_TRUE(std::isnan(strain_standard_deviation(X, X, C).xx));
  C[1] = {0.001, 0.0, 0.001};
  const std::array<Vec2, 3> line = {Vec2{0.0, 0.0}, Vec2{4.0, 0.0}, Vec2{8.0, 0.0}};
  EXPECT_TRUE(std::isnan(strain_standard_deviation(line, line, C).yy));
  // Isotropic σ² = 0.001 px² on a right triangle with 8 px legs, at rest: σ(E_xx) = σ·√2/8.
  EXPECT_NEAR(strain_standard_deviation(X, X, C).xx, std::sqrt(0.001) * std::sqrt(2.0) / 8.0, 1e-12);
}

}  // namespace
}  // namespace tirstrain::strain
