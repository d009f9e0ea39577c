#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "strain/mesh.hpp"

namespace tirstrain::strain {
namespace {

std::vector<Vec2> grid_points(int nx, int ny, double step) {
  std::vector<Vec2> p;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) p.push_back({i * step, j * step});
  return p;
}

TEST(Delaunay, GridGivesTwoTrianglesPerCellAllCounterClockwise) {
  const auto points = grid_points(6, 5, 9.0);
  const auto triangles = delaunay(points);
  EXPECT_EQ(triangles.size(), 2u * 5u * 4u);
  double area = 0.0;
  for (const auto& t : triangles) {
    const double a = signed_area(points[t[0]], points[t[1]], points[t[2]]);
    EXPECT_GT(a, 0.0);
    area += a;
    EXPECT_LT(t[0], t[1]);  // canonical rotation: smallest index first
    EXPECT_LT(t[0], t[2]);
  }
  EXPECT_NEAR(area, 45.0 * 36.0, 1e-9);  // the convex hull is covered exactly once
}

TEST(Delaunay, DegenerateInputsGiveDefinedResults) {
  EXPECT_TRUE(delaunay({}).empty());
  const std::vector<Vec2> one = {{1, 1}};
  EXPECT_TRUE(delaunay(one).empty());
  const std::vector<Vec2> two = {{1, 1}, {2, 3}};
  EXPECT_TRUE(delaunay(two).empty());
  const std::vector<Vec2> three = {{0, 0}, {10, 0}, {0, 10}};
  const auto t3 = delaunay(three);
  ASSERT_EQ(t3.size(), 1u);
  EXPECT_EQ(t3[0], (Triangle{0, 1, 2}));
  const std::vector<Vec2> collinear = {{0, 0}, {1, 1}, {2, 2}, {3, 3}};
  EXPECT_TRUE(delaunay(collinear).empty());
  const std::vector<Vec2> with_nan = {{0, 0}, {NAN, 1}, {10, 0}, {0, 10}};
  const auto tn = delaunay(with_nan);
  ASSERT_EQ(tn.size(), 1u);
  EXPECT_EQ(tn[0], (Triangle{0, 2, 3}));
}

TEST(Delaunay, DuplicatePointsKeepTheFirstIndex) {
  const std::vector<Vec2> points = {{0, 0}, {10, 0}, {0, 10}, {10, 0}, {10, 10}, {0, 0}};
  const auto triangles = delaunay(points);
  ASSERT_EQ(triangles.size(), 2u);
  std::set<int> used;
  for (const auto& t : triangles) used.insert(t.begin(), t.end());
  EXPECT_EQ(used, (std::set<int>{0, 1, 2, 4}));
}

TEST(Delaunay, LargeRandomSetCoversTheHull) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> d(0.0, 500.0);
  std::vector<Vec2> points(3000);
  for (auto& p : points) p = {d(rng), d(rng)};
  const auto triangles = delaunay(points);
  // Euler: T = 2n − 2 − h for n points with h on the hull; h is small compared with n.
  EXPECT_GT(triangles.size(), 2u * 3000u - 2u - 100u);
  EXPECT_LE(triangles.size(), 2u * 3000u - 5u);
}

TEST(Quality, ShapeMeasuresAndCriteria) {
  const Vec2 a{0, 0}, b{10, 0}, c{5, 10.0 * std::sqrt(3.0) / 2.0};
  EXPECT_NEAR(min_angle_deg(a, b, c), 60.0, 1e-12);
  EXPECT_NEAR(aspect_ratio(a, b, c), 2.0 / std::sqrt(3.0), 1e-12);
  const QualityCriteria criteria;
  EXPECT_EQ(check_reference_shape(a, b, c, criteria), TriangleStatus::kValid);
  // A sliver: tiny height, small angle, big aspect ratio.
  const Vec2 far_b{40, 0}, s{20, 1.0};  // area 20 px², angles 2.9°
  EXPECT_NEAR(min_angle_deg(a, far_b, s), std::atan2(1.0, 20.0) * 180.0 / M_PI, 1e-12);
  EXPECT_EQ(check_reference_shape(a, far_b, s, criteria), TriangleStatus::kSmallAngle);
  EXPECT_EQ(check_reference_shape(a, {1, 0}, {0, 1}, criteria), TriangleStatus::kSmallArea);  // 0.5 px²
  EXPECT_EQ(check_reference_shape(a, b, {5, 0}, criteria), TriangleStatus::kSmallArea);       // zero area
  QualityCriteria loose_angle = criteria;
  loose_angle.min_angle_deg = 1.0;
  EXPECT_EQ(check_reference_shape(a, b, {5, 0.6}, loose_angle), TriangleStatus::kHighAspect);
}

}  // namespace
}  // namespace tirstrain::strain
