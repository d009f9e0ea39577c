// Known limit of the subset match: a contrast that varies across the subset and is fixed in the image while
// the texture moves through it (as the ridge contrast fades towards a TIR contact's border). The
// zero-normalised SSD models one gain and one offset per subset, so a gain ramp biases the match. Frames are
// rendered by evaluating an analytic texture at the inverse-mapped position of every pixel, so the only
// error is the matcher's.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <vector>

#include "flow/settings.hpp"
#include "flow/subset.hpp"
#include "ridge_texture.hpp"

namespace tirstrain::flow {
namespace {

// A random "speckle": a sum of cosines of random direction, wavelength 7-16 px and phase (analytic, so it
// can be evaluated at any warped position).
struct Speckle {
  std::vector<double> kx, ky, phase;
  explicit Speckle(unsigned seed) {
    cv::RNG rng(seed);
    for (int i = 0; i < 40; ++i) {
      const double angle = rng.uniform(0.0, std::numbers::pi), wavelength = rng.uniform(7.0, 16.0);
      kx.push_back(2.0 * std::numbers::pi * std::cos(angle) / wavelength);
      ky.push_back(2.0 * std::numbers::pi * std::sin(angle) / wavelength);
      phase.push_back(rng.uniform(0.0, 2.0 * std::numbers::pi));
    }
  }
  double operator()(double x, double y) const {
    double v = 0.0;
    for (std::size_t i = 0; i < kx.size(); ++i) v += std::cos(kx[i] * x + ky[i] * y + phase[i]);
    return 0.5 + 0.05 * v;
  }
};

using Texture = std::function<double(double, double)>;
using Gain = std::function<double(double, double)>;  // contrast at an image position, fixed in the image

constexpr int kSize = 96;
const Vec2 kCentre{47.0, 47.0};

// x = c + A (X − c) + t; the texture's contrast about its mean 0.5 scaled by gain(x) at the image position.
cv::Mat render(const Texture& texture, const Gain& gain, const Eigen::Matrix2d& a, Vec2 t) {
  const Eigen::Matrix2d inv = a.inverse();
  cv::Mat img(kSize, kSize, CV_32F);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const Eigen::Vector2d X = inv * Eigen::Vector2d(x - kCentre.x - t.x, y - kCentre.y - t.y);
      const double v = texture(X.x() + kCentre.x, X.y() + kCentre.y);
      img.at<float>(y, x) = static_cast<float>(0.5 + gain(x, y) * (v - 0.5));
    }
  return img;
}

// The displacement error at the subset centre after matching `current` to `reference`.
double match_error(const cv::Mat& reference, const cv::Mat& current, Vec2 t, ShapeFunction shape) {
  AnchorImage anchor;
  anchor.assign(reference, cv::Mat());
  Subset s;
  EXPECT_TRUE(s.build(anchor, cv::Point(47, 47), 14, 1, shape, 100));
  Warp w;
  w.p[0] = t.x + 0.4;
  w.p[1] = t.y - 0.3;
  const MatchResult m = s.match(current, cv::Mat(), w, MatchOptions{});
  EXPECT_TRUE(m.converged);
  // The centre pixel X = c moves to c + t.
  const Vec2 u = w.displacement_px(0, 0);
  return std::hypot(u.x - t.x, u.y - t.y);
}

// Contrast falling linearly from 1 to 0.3 across the subset (x from 33 to 61) and on beyond it (the clamp
// lies outside the subset and its interpolation reach), fixed in the image.
double ramp(double x, double) {
  return std::clamp(1.0 - 0.7 * (x - 33.0) / 28.0, 0.1, 1.2);
}
double flat(double, double) {
  return 1.0;
}

// A contrast ramp from 1 to 0.3 across the subset in the current frame biases the match by a quarter of a
// pixel on ridges and a tenth on speckle; the same ramp in both frames (the texture moved 2.7 px through
// it) by 0.01-0.05 px; without the ramp the error is within 0.01 px (bicubic interpolation of the speckle). A
// matcher that models a gain varying across the subset, fixed in the image, should bring the first two to the
// last.
TEST(SubsetKnownLimits, ContrastRampFixedInTheImageBiasesTheMatch) {
  const double angle = 0.5 * std::numbers::pi / 180.0;
  Eigen::Matrix2d rot;
  rot << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  const Eigen::Matrix2d a = rot * Eigen::Vector2d(1.01, 0.995).asDiagonal();
  const Vec2 t{2.3, -1.4};
  const Speckle speckle(7);
  const std::vector<std::pair<const char*, Texture>> textures = {
      {"ridges", [](double x, double y) { return testing::ridge_texture(x, y); }},
      {"speckle", [&](double x, double y) { return speckle(x, y); }}};
  for (const auto& [name, texture] : textures)
    for (const ShapeFunction shape : {ShapeFunction::kAffine, ShapeFunction::kQuadratic}) {
      const cv::Mat flat_reference = render(texture, flat, Eigen::Matrix2d::Identity(), {0.0, 0.0});
      const cv::Mat ramped_reference = render(texture, ramp, Eigen::Matrix2d::Identity(), {0.0, 0.0});
      const cv::Mat ramped_current = render(texture, ramp, a, t);
      const double none = match_error(flat_reference, render(texture, flat, a, t), t, shape);
      const double current_only = match_error(flat_reference, ramped_current, t, shape);
      const double both = match_error(ramped_reference, ramped_current, t, shape);
      std::printf(
          "%-7s %-9s error without a ramp %.4f px, ramp in the current frame %.4f px, in both %.4f px\n",
          name, to_string(shape).c_str(), none, current_only, both);
      EXPECT_LT(none, 0.01) << name << " " << to_string(shape);
      // Measured: 0.25-0.28 px on ridges, 0.11-0.13 px on speckle. The bias is the limit recorded here
      // (regression bounds either side).
      EXPECT_GT(current_only, 0.05) << name << " " << to_string(shape);
      EXPECT_LT(current_only, 0.4) << name << " " << to_string(shape);
      EXPECT_LT(both, 0.1) << name << " " << to_string(shape);
    }
}

}  // namespace
}  // namespace tirstrain::flow
