#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>

#include "core/tensor2.hpp"

namespace tirstrain {
namespace {

TEST(GreenLagrange, RigidRotationOf30DegreesHasZeroStrain) {
  const double t = std::numbers::pi / 6.0;
  const Gradient2 h{std::cos(t) - 1.0, -std::sin(t), std::sin(t), std::cos(t) - 1.0};
  const Strain2 e = green_lagrange(h);
  EXPECT_NEAR(e.xx, 0.0, 1e-15);
  EXPECT_NEAR(e.yy, 0.0, 1e-15);
  EXPECT_NEAR(e.xy, 0.0, 1e-15);
  // Small-strain theory would report cos(30°) - 1 = -0.134 on both axes.
  EXPECT_NEAR(infinitesimal_strain(h).xx, std::cos(t) - 1.0, 1e-15);
  EXPECT_NEAR(infinitesimal_rotation_rad(h), std::sin(t), 1e-15);
}

TEST(GreenLagrange, FiftyPercentUniaxialStretch) {
  const Strain2 e = green_lagrange({0.5, 0.0, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(e.xx, 0.625);
  EXPECT_DOUBLE_EQ(e.yy, 0.0);
  EXPECT_DOUBLE_EQ(e.xy, 0.0);
}

TEST(GreenLagrange, MatchesHalfFtFMinusIdentity) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> d(-0.4, 0.4);
  for (int i = 0; i < 100; ++i) {
    const Gradient2 h{d(rng), d(rng), d(rng), d(rng)};
    Eigen::Matrix2d f;
    f << 1 + h.xx, h.xy, h.yx, 1 + h.yy;
    const Eigen::Matrix2d expected = 0.5 * (f.transpose() * f - Eigen::Matrix2d::Identity());
    const Strain2 e = green_lagrange(h);
    EXPECT_NEAR(e.xx, expected(0, 0), 1e-15);
    EXPECT_NEAR(e.yy, expected(1, 1), 1e-15);
    EXPECT_NEAR(e.xy, expected(0, 1), 1e-15);
  }
}

TEST(PrincipalStrains, AgreeWithEigenDecomposition) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> d(-0.5, 0.5);
  for (int i = 0; i < 200; ++i) {
    const Strain2 e{d(rng), d(rng), d(rng)};
    Eigen::Matrix2d m;
    m << e.xx, e.xy, e.xy, e.yy;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(m);
    const Principal2 p = principal_strains(e);
    EXPECT_NEAR(p.e1, solver.eigenvalues()(1), 1e-14);
    EXPECT_NEAR(p.e2, solver.eigenvalues()(0), 1e-14);
    // The angle's direction is the eigenvector of e1 (up to sign).
    const Eigen::Vector2d v(std::cos(p.angle_rad), std::sin(p.angle_rad));
    EXPECT_NEAR((m * v - p.e1 * v).norm(), 0.0, 1e-14);
    EXPECT_GT(p.angle_rad, -std::numbers::pi / 2 - 1e-15);
    EXPECT_LE(p.angle_rad, std::numbers::pi / 2 + 1e-15);
  }
}

TEST(PrincipalStrains, IsotropicAndPureShearCases) {
  const Principal2 iso = principal_strains({0.1, 0.1, 0.0});
  EXPECT_DOUBLE_EQ(iso.e1, 0.1);
  EXPECT_DOUBLE_EQ(iso.e2, 0.1);
  const Principal2 shear = principal_strains({0.0, 0.0, 0.2});
  EXPECT_DOUBLE_EQ(shear.e1, 0.2);
  EXPECT_DOUBLE_EQ(shear.e2, -0.2);
  EXPECT_NEAR(shear.angle_rad, std::numbers::pi / 4, 1e-15);
}

TEST(EnergyDensity, EqualsDesignDocumentForm) {
  // docs/design.md: u = E(1-ν)/(2(1+ν)(1-2ν))(Exx²+Eyy²) + Eν/((1+ν)(1-2ν)) Exx Eyy + E/(1+ν) Exy².
  const double young = 1.0e6, nu = 0.4;
  const Strain2 e{0.03, -0.02, 0.015};
  const double design = young * (1 - nu) / (2 * (1 + nu) * (1 - 2 * nu)) * (e.xx * e.xx + e.yy * e.yy) +
                        young * nu / ((1 + nu) * (1 - 2 * nu)) * e.xx * e.yy + young / (1 + nu) * e.xy * e.xy;
  EXPECT_NEAR(plane_strain_energy_density_J_m3(e, young, nu), design, 1e-12 * design);
  // Hand value: λ = 0.4e6/0.28 = 1.428571e6 Pa, G = 357142.857 Pa;
  // W = λ/2·(0.01)² + G·(9e-4 + 4e-4 + 4.5e-4) = 71.4285714 + 625.0 J/m³.
  EXPECT_NEAR(plane_strain_energy_density_J_m3(e, young, nu), 71.428571428571 + 625.0, 1e-9);
}

}  // namespace
}  // namespace tirstrain
