#include <gtest/gtest.h>

#include <Eigen/Core>

#include "core/smoothstep.hpp"

namespace tirstrain {
namespace {

TEST(Smoothstep5, ClampsAndIsSymmetricAboutHalf) {
  EXPECT_EQ(smoothstep5(-3.0), 0.0);
  EXPECT_EQ(smoothstep5(0.0), 0.0);
  EXPECT_EQ(smoothstep5(1.0), 1.0);
  EXPECT_EQ(smoothstep5(7.0), 1.0);
  EXPECT_DOUBLE_EQ(smoothstep5(0.5), 0.5);
  for (double t = 0.0; t <= 1.0; t += 0.0625) EXPECT_NEAR(smoothstep5(t) + smoothstep5(1.0 - t), 1.0, 1e-15);
  // 6t⁵ − 15t⁴ + 10t³ at t = 0.25: 6/1024 − 15/256 + 10/64.
  EXPECT_DOUBLE_EQ(smoothstep5(0.25), 6.0 / 1024.0 - 15.0 / 256.0 + 10.0 / 64.0);
}

TEST(Smoothstep5, FlatAtBothEnds) {
  // First and second derivatives vanish at 0 and 1 (central differences, step h): f(h) = 10h³ + O(h⁴).
  const double h = 1e-4;
  EXPECT_NEAR(smoothstep5(h), 10.0 * h * h * h, 1e-14);
  EXPECT_NEAR(1.0 - smoothstep5(1.0 - h), 10.0 * h * h * h, 1e-14);
}

TEST(Smoothstep5, ArrayFormMatchesTheScalarOne) {
  const Eigen::ArrayXd t = Eigen::ArrayXd::LinSpaced(41, -0.5, 1.5);
  const Eigen::ArrayXd s = smoothstep5_array(t);
  for (Eigen::Index i = 0; i < t.size(); ++i) EXPECT_DOUBLE_EQ(s(i), smoothstep5(t(i))) << t(i);
}

}  // namespace
}  // namespace tirstrain
