// Global (mesh) correlation on a smooth ridge texture warped by exactly known maps, rendered by evaluating
// the texture at the inverse-mapped position of every pixel, so the only error is the correlation's.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <functional>
#include <numbers>

#include "bench/studies/mesh_correlation.hpp"
#include "core/error.hpp"
#include "tests/flow/ridge_texture.hpp"

namespace tirstrain::studies {
namespace {

using flow::testing::ridge_texture;

// Renders the current frame for the forward map x = X + u(X), inverted per pixel by fixed-point iteration.
cv::Mat render(int size, const std::function<Vec2(Vec2)>& u, double gain = 1.0, double offset = 0.0) {
  cv::Mat img(size, size, CV_32F);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      Vec2 X{static_cast<double>(x), static_cast<double>(y)};
      for (int k = 0; k < 30; ++k) {  // fixed point X = x − u(X): u is a contraction here
        const Vec2 d = u(X);
        X = {x - d.x, y - d.y};
      }
      img.at<float>(y, x) = static_cast<float>(gain * ridge_texture(X.x, X.y) + offset);
    }
  return img;
}

struct Outcome {
  double rms_px = 0.0, max_px = 0.0;
  MeshCorrelationResult result;
};

// Correlates the disc of radius 70 px around the centre of a 192 px frame and scores the field on a 3 px
// grid of the disc (less 12 px) against `u`.
Outcome correlate(const std::function<Vec2(Vec2)>& u, MeshCorrelationOptions options, double gain = 1.0,
                  double offset = 0.0, Vec2 start_error = {0.0, 0.0}) {
  const int size = 192;
  const cv::Mat ref = render(size, [](Vec2) { return Vec2{0.0, 0.0}; });
  const cv::Mat cur = render(size, u, gain, offset);
  cv::Mat region = cv::Mat::zeros(size, size, CV_8U);
  cv::circle(region, {96, 96}, 70, cv::Scalar(1), cv::FILLED);
  MeshCorrelation mesh(ref, region, options);
  std::vector<Vec2> nodal(static_cast<std::size_t>(mesh.node_count()));
  for (int n = 0; n < mesh.node_count(); ++n) {
    const Vec2 d = u(mesh.node_px(n));
    nodal[static_cast<std::size_t>(n)] = {d.x + start_error.x, d.y + start_error.y};
  }
  Outcome o;
  o.result = mesh.solve(cur, cv::Mat(), nodal);
  double sum2 = 0.0;
  int n = 0;
  for (int y = 0; y < size; y += 3)
    for (int x = 0; x < size; x += 3) {
      if (std::hypot(x - 96.0, y - 96.0) > 58.0) continue;
      Vec2 d;
      if (!mesh.displacement_at(nodal, {static_cast<double>(x), static_cast<double>(y)}, d)) continue;
      const Vec2 t = u({static_cast<double>(x), static_cast<double>(y)});
      const double e = std::hypot(d.x - t.x, d.y - t.y);
      sum2 += e * e;
      o.max_px = std::max(o.max_px, e);
      ++n;
    }
  EXPECT_GT(n, 1000);
  o.rms_px = std::sqrt(sum2 / n);
  return o;
}

TEST(MeshCorrelation, RecoversASubpixelTranslation) {
  const auto u = [](Vec2) { return Vec2{0.37, -0.21}; };
  const Outcome o = correlate(u, {}, 1.0, 0.0, {1.2, -0.9});
  EXPECT_TRUE(o.result.converged);
  EXPECT_LT(o.rms_px, 0.01);
  EXPECT_LT(o.max_px, 0.03);
}

TEST(MeshCorrelation, FollowsAnAffineFieldWithLargeStrain) {
  // 20 % stretch along x, 10 % shear: a linear field is free of the smoothness penalty.
  const auto u = [](Vec2 X) {
    return Vec2{0.2 * (X.x - 96.0) + 0.1 * (X.y - 96.0) + 0.4, -0.05 * (X.y - 96.0)};
  };
  const Outcome o = correlate(u, {});
  EXPECT_TRUE(o.result.converged);
  EXPECT_LT(o.rms_px, 0.02);
  // Full Gauss–Newton (the gradient carried by each element's F) reaches the same field, started 1 px off.
  MeshCorrelationOptions full;
  full.update_gradient = true;
  const Outcome f = correlate(u, full, 1.0, 0.0, {1.0, 0.0});
  EXPECT_TRUE(f.result.converged);
  EXPECT_LT(f.rms_px, 0.02);
  EXPECT_EQ(f.result.refactorisations, f.result.iterations);
}

TEST(MeshCorrelation, AbsorbsAGainAndOffsetChange) {
  const auto u = [](Vec2) { return Vec2{-0.6, 0.45}; };
  MeshCorrelationOptions with;
  const Outcome o = correlate(u, with, 0.8, 0.05);
  EXPECT_LT(o.rms_px, 0.01);
  MeshCorrelationOptions without;
  without.brightness = false;
  const Outcome p = correlate(u, without, 0.8, 0.05);
  EXPECT_GT(p.rms_px, 2.0 * o.rms_px);  // the test can fail: brightness matters
}

TEST(MeshCorrelation, PixelsOutsideTheCurrentMaskDoNotPullTheField) {
  // The current frame is background (uniform) right of x = 120: those pixels must leave the sums.
  const int size = 192;
  const Vec2 shift{1.3, 0.4};
  const cv::Mat ref = render(size, [](Vec2) { return Vec2{0.0, 0.0}; });
  cv::Mat cur = render(size, [&](Vec2) { return shift; });
  cur.colRange(120, size).setTo(0.5);
  cv::Mat region = cv::Mat::zeros(size, size, CV_8U), mask = cv::Mat::zeros(size, size, CV_8U);
  cv::circle(region, {96, 96}, 70, cv::Scalar(1), cv::FILLED);
  mask.colRange(0, 118).setTo(1);
  MeshCorrelation mesh(ref, region, {});
  std::vector<Vec2> nodal(static_cast<std::size_t>(mesh.node_count()));
  const MeshCorrelationResult r = mesh.solve(cur, mask, nodal);
  EXPECT_TRUE(r.converged);
  // Largest error of the field next to the cut, at x = 110.
  const auto worst = [&](const MeshCorrelation& m, const std::vector<Vec2>& field) {
    double largest = 0.0;
    for (int y = 40; y < 150; y += 5) {
      Vec2 d;
      if (!m.displacement_at(field, {110.0, static_cast<double>(y)}, d)) return 1e9;
      largest = std::max(largest, std::hypot(d.x - shift.x, d.y - shift.y));
    }
    return largest;
  };
  EXPECT_LT(worst(mesh, nodal), 0.02);
  // The test can fail: without the mask the background pulls the same points off.
  MeshCorrelation unmasked(ref, region, {});
  std::vector<Vec2> pulled(static_cast<std::size_t>(unmasked.node_count()));
  unmasked.solve(cur, cv::Mat(), pulled);
  EXPECT_GT(worst(unmasked, pulled), 0.1);
  EXPECT_LT(worst(unmasked, pulled), 1e9);
}

TEST(MeshCorrelation, RejectsAnEmptyRegionAndMismatchedInput) {
  const cv::Mat ref(64, 64, CV_32F, cv::Scalar(0.5));
  EXPECT_THROW(MeshCorrelation(ref, cv::Mat::zeros(64, 64, CV_8U), {}), Error);
  EXPECT_THROW(MeshCorrelation(ref, cv::Mat::ones(32, 32, CV_8U), {}), Error);
  MeshCorrelation mesh(ref, cv::Mat::ones(64, 64, CV_8U), {});
  std::vector<Vec2> wrong_size(3);
  EXPECT_THROW(mesh.solve(ref, cv::Mat(), wrong_size), Error);
}

}  // namespace
}  // namespace tirstrain::studies
