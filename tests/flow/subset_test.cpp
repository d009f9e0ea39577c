// IC-GN subset matching on a smooth ridge texture warped by exactly known maps (rendered by evaluating the
// texture at the inverse-mapped position of every pixel, so the only error is the matcher's).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>

#include "flow/bicubic.hpp"
#include "flow/settings.hpp"
#include "flow/subset.hpp"
#include "ridge_texture.hpp"

namespace tirstrain::flow {
namespace {

using testing::ridge_texture;

cv::Mat render(int size, const std::function<Vec2(double, double)>& inverse) {
  cv::Mat img(size, size, CV_32F);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const Vec2 X = inverse(x, y);
      img.at<float>(y, x) = static_cast<float>(ridge_texture(X.x, X.y));
    }
  return img;
}

struct Case {
  ShapeFunction shape;
  double tolerance_px;
};

// Affine map about the image centre: x = c + A (X − c) + t.
Vec2 match_affine(ShapeFunction shape, const Eigen::Matrix2d& a, Vec2 t, Vec2 start_error,
                  MatchResult* out = nullptr) {
  const int size = 96;
  const Vec2 c{47.0, 47.0};
  const cv::Mat ref = render(size, [](double x, double y) { return Vec2{x, y}; });
  const Eigen::Matrix2d inv = a.inverse();
  const cv::Mat cur = render(size, [&](double x, double y) {
    const Eigen::Vector2d X = inv * Eigen::Vector2d(x - c.x - t.x, y - c.y - t.y);
    return Vec2{X.x() + c.x, X.y() + c.y};
  });
  AnchorImage anchor;
  anchor.assign(ref, cv::Mat());
  Subset s;
  EXPECT_TRUE(s.build(anchor, cv::Point(47, 47), 14, 1, shape, 100));
  Warp w;
  w.p[0] = t.x + start_error.x;
  w.p[1] = t.y + start_error.y;
  const MatchResult m = s.match(cur, cv::Mat(), w, MatchOptions{});
  if (out) *out = m;
  EXPECT_TRUE(m.converged);
  return {w.p[0] - t.x, w.p[1] - t.y};
}

TEST(Subset, TranslationByHalfPixelIsExact) {
  for (const Case c : {Case{ShapeFunction::kTranslation, 0.01}, Case{ShapeFunction::kAffine, 0.01},
                       Case{ShapeFunction::kQuadratic, 0.01}}) {
    MatchResult m;
    const Vec2 e = match_affine(c.shape, Eigen::Matrix2d::Identity(), {3.5, -2.5}, {1.2, -1.0}, &m);
    EXPECT_LT(std::hypot(e.x, e.y), c.tolerance_px) << to_string(c.shape);
    EXPECT_GT(m.zncc, 0.999);
  }
}

TEST(Subset, AffineStretchAndRotation) {
  // 8 % stretch along x, −4 % along y, 5° rotation: a translation-only subset is biased by the warp of its
  // own window; first and second order follow it exactly.
  const double angle = 5.0 * std::numbers::pi / 180.0;
  Eigen::Matrix2d rot;
  rot << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  const Eigen::Matrix2d a = rot * Eigen::Vector2d(1.08, 0.96).asDiagonal();
  for (ShapeFunction shape : {ShapeFunction::kAffine, ShapeFunction::kQuadratic}) {
    const Vec2 e = match_affine(shape, a, {2.3, 1.7}, {0.8, 0.6});
    EXPECT_LT(std::hypot(e.x, e.y), 0.01) << to_string(shape);
  }
}

// x = X + u(X) with a strongly curved u: u = 0.004 (X − c)² along x. A first-order subset sees the
// curvature as a bias of about ⅙·0.004·2·r² ≈ 0.27 px·(r/14)²; the second-order one removes it.
TEST(Subset, SecondOrderRemovesCurvatureBias) {
  const int size = 96;
  const double k = 0.004, cx = 47.0;
  const cv::Mat ref = render(size, [](double x, double y) { return Vec2{x, y}; });
  const cv::Mat cur = render(size, [&](double x, double y) {
    // Invert x = X + 1.5 + k (X − c)² by Newton (monotone where 1 + 2k(X − c) > 0).
    double X = x;
    for (int i = 0; i < 30; ++i) X -= (X + 1.5 + k * (X - cx) * (X - cx) - x) / (1.0 + 2.0 * k * (X - cx));
    return Vec2{X, y};
  });
  AnchorImage anchor;
  anchor.assign(ref, cv::Mat());
  double error[2] = {0, 0};
  int idx = 0;
  for (ShapeFunction shape : {ShapeFunction::kAffine, ShapeFunction::kQuadratic}) {
    Subset s;
    ASSERT_TRUE(s.build(anchor, cv::Point(47, 47), 14, 1, shape, 100));
    Warp w;
    w.p[0] = 1.0;
    ASSERT_TRUE(s.match(cur, cv::Mat(), w, MatchOptions{}).converged);
    error[idx++] = std::abs(w.p[0] - 1.5);
  }
  EXPECT_GT(error[0], 0.1);   // first order: biased by the curvature
  EXPECT_LT(error[1], 0.01);  // second order: exact
}

// A subset straddling a fixed border: the background does not move; the masked match ignores it.
TEST(Subset, MaskKeepsFixedBackgroundFromPullingTowardsZero) {
  const int size = 96;
  const cv::Mat ref = render(size, [](double x, double y) { return Vec2{x, y}; });
  cv::Mat cur = render(size, [](double x, double y) { return Vec2{x - 2.5, y + 1.25}; });
  cv::Mat mask(size, size, CV_8U, cv::Scalar(1));
  mask.colRange(52, size).setTo(0);
  cv::Mat ref_masked = ref.clone(), cur_masked = cur.clone();
  // The background (right of x = 52) is flat and fixed in both frames, with a fixed edge.
  ref_masked.colRange(52, size).setTo(0.9);
  cur_masked.colRange(52, size).setTo(0.9);
  AnchorImage anchor;
  anchor.assign(ref_masked, mask);
  Subset s;
  ASSERT_TRUE(s.build(anchor, cv::Point(47, 47), 14, 1, ShapeFunction::kQuadratic, 100));
  // Started 0.3 px from the truth: directions the masked texture leaves undetermined keep their start.
  Warp w;
  w.p[0] = 2.3;
  w.p[1] = -1.05;
  cv::Mat match_mask;
  erode_for_matching(mask, match_mask);
  const MatchResult m = s.match(cur_masked, match_mask, w, MatchOptions{});
  ASSERT_TRUE(m.converged);
  EXPECT_LT(m.valid_fraction, 0.95);
  EXPECT_NEAR(w.displacement_px(0, 0).x, 2.5, 0.02);
  EXPECT_NEAR(w.displacement_px(0, 0).y, -1.25, 0.02);
}

// Known limit. A subset crossing the contact's border uses its pixels inside the contact only (and says
// how many); that alone is exact (above). Near a TIR contact's border the ridges' contrast also fades, over
// about a ridge period, and that fade is fixed in the image while the skin moves through it: the match is
// pulled towards zero motion. The same subset, the same 2.5 px motion, with and without the fade.
TEST(SubsetKnownLimits, ContrastFadeFixedInTheImageBiasesAnEdgeSubset) {
  const int size = 96;
  const double border_x = 52.0, fade_px = 21.0, floor = 0.35;
  const auto fade = [&](double x) {
    const double t = std::clamp((border_x - x) / fade_px, 0.0, 1.0);
    return floor + (1.0 - floor) * t * t * (3.0 - 2.0 * t);
  };
  const auto frame = [&](Vec2 shift, bool faded) {
    cv::Mat img = render(size, [&](double x, double y) { return Vec2{x - shift.x, y - shift.y}; });
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) {
        float& v = img.at<float>(y, x);
        v = x >= border_x ? 0.5f : static_cast<float>(0.5 + (faded ? fade(x) : 1.0) * (v - 0.5));
      }
    return img;
  };
  cv::Mat mask(size, size, CV_8U, cv::Scalar(1));
  mask.colRange(static_cast<int>(border_x), size).setTo(0);
  cv::Mat match_mask;
  erode_for_matching(mask, match_mask);
  const Vec2 truth{2.5, -1.25};
  double error_px[2] = {0.0, 0.0};
  double inside[2] = {0.0, 0.0};
  for (const bool faded : {false, true}) {
    AnchorImage anchor;
    anchor.assign(frame({0.0, 0.0}, faded), mask);
    Subset s;
    // Centred 12 px inside the border: its right-hand side reaches beyond it.
    ASSERT_TRUE(s.build(anchor, cv::Point(40, 47), 14, 1, ShapeFunction::kAffine, 100));
    Warp w;
    w.p[0] = truth.x - 0.3;
    w.p[1] = truth.y + 0.2;
    const MatchResult m = s.match(frame(truth, faded), match_mask, w, MatchOptions{});
    ASSERT_TRUE(m.converged);
    const Vec2 u = w.displacement_px(0, 0);
    error_px[faded] = std::hypot(u.x - truth.x, u.y - truth.y);
    inside[faded] = m.valid_fraction;
  }
  std::printf("edge subset: %.0f %% of its pixels inside; error without the fade %.4f px, with it %.4f px\n",
              100.0 * inside[1], error_px[0], error_px[1]);
  EXPECT_LT(inside[1], 0.95);
  EXPECT_LT(error_px[0], 0.02);
  // Measured: 0.0009 px without the fade, 0.141 px with it (88 % of the pixels inside). The bias is the
  // limit recorded here (regression bound); a matcher that models the fade should bring it to the first.
  EXPECT_LT(error_px[1], 0.2);
}

TEST(Subset, FlatPatchIsDegenerate) {
  AnchorImage anchor;
  anchor.assign(cv::Mat(64, 64, CV_32F, cv::Scalar(0.5)), cv::Mat());
  Subset s;
  EXPECT_FALSE(s.build(anchor, cv::Point(32, 32), 10, 1, ShapeFunction::kAffine, 50));
  EXPECT_TRUE(s.empty());
}

TEST(Subset, BicubicReproducesSmoothSignal) {
  cv::Mat img(32, 32, CV_32F);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) img.at<float>(y, x) = static_cast<float>(ridge_texture(x, y));
  float v = 0;
  ASSERT_TRUE(sample_bicubic(img, 10.3, 12.7, v));
  EXPECT_NEAR(v, ridge_texture(10.3, 12.7), 2e-3);
  EXPECT_FALSE(sample_bicubic(img, 0.5, 10.0, v));
  EXPECT_FALSE(sample_bicubic(img, 10.0, 30.2, v));
  // A runaway warp's coordinates are outside, not an int overflow into a wild read.
  EXPECT_FALSE(sample_bicubic(img, 1e12, 10.0, v));
  EXPECT_FALSE(sample_bicubic(img, 10.0, 3e9, v));
  EXPECT_FALSE(sample_bicubic(img, std::nan(""), 10.0, v));
  EXPECT_FALSE(sample_bicubic(img, -1e12, 10.0, v));
}

// Under a pure translation every pixel is sampled at the same fraction of a pixel (the plate's subsets and
// mosaic): the separable sampler must give the per-pixel sampler's values and refusals, at the image's
// edges, under a mask (its nearest pixel), and for shifts either side of half a pixel.
TEST(Subset, TranslatedSamplerEqualsThePerPixelSampler) {
  cv::Mat img(40, 50, CV_32F);
  cv::randu(img, 0.0, 1.0);
  cv::Mat mask(img.size(), CV_8U, cv::Scalar(1));
  cv::circle(mask, cv::Point(20, 18), 6, cv::Scalar(0), cv::FILLED);
  for (const cv::Mat& m : {cv::Mat(), mask})
    for (const Vec2 shift : {Vec2{0.25, 0.75}, Vec2{-3.6, 2.49}, Vec2{7.5, -0.5}, Vec2{-12.0, 15.0}}) {
      const detail::Sampler each(img, m);
      // Offsets −25…25 around (24, 19): many land outside the image on one side or the other.
      detail::TranslatedSampler shifted(img, m, 24.0 + shift.x, 19.0 + shift.y, -25, 25);
      ASSERT_TRUE(shifted.ok());
      int compared = 0, refused = 0;
      for (int dy = -25; dy <= 25; ++dy)
        for (int dx = -25; dx <= 25; ++dx) {
          float a = 0.0f, b = 0.0f;
          const bool in_each = each.sample(24.0 + dx + shift.x, 19.0 + dy + shift.y, a);
          const bool in_shifted = shifted.sample(dx, dy, b);
          ASSERT_EQ(in_each, in_shifted) << "offset " << dx << ", " << dy;
          if (!in_each) {
            ++refused;
            continue;
          }
          EXPECT_NEAR(a, b, 1e-6f);
          ++compared;
        }
      EXPECT_GT(compared, 500);
      EXPECT_GT(refused, 100);
    }
  EXPECT_FALSE(detail::TranslatedSampler(img, cv::Mat(), std::nan(""), 3.0, 0, 4).ok());
  EXPECT_FALSE(detail::TranslatedSampler(img, cv::Mat(), 3.0, 1e12, 0, 4).ok());
}

// A translation subset takes the separable path; an affine one matched for the translation alone takes the
// per-pixel path on the same pixels: the two must end at the same place with the same score, also where
// part of the subset falls outside the frame's mask.
TEST(Subset, TranslationSubsetMatchesAsThePerPixelPath) {
  const cv::Mat ref = render(96, [](double x, double y) { return Vec2{x, y}; });
  const Vec2 t{2.37, -1.61};
  const cv::Mat cur = render(96, [&](double x, double y) { return Vec2{x - t.x, y - t.y}; });
  cv::Mat mask(cur.size(), CV_8U, cv::Scalar(1));
  mask.colRange(58, 96).setTo(0);
  AnchorImage anchor;
  anchor.assign(ref, cv::Mat());
  Subset translation, affine;
  ASSERT_TRUE(translation.build(anchor, cv::Point(47, 47), 14, 1, ShapeFunction::kTranslation, 100));
  ASSERT_TRUE(affine.build(anchor, cv::Point(47, 47), 14, 1, ShapeFunction::kAffine, 100));
  MatchOptions translation_only;
  translation_only.translation_only = true;
  for (const cv::Mat& m : {cv::Mat(), mask}) {
    Warp a, b;
    a.p[0] = b.p[0] = t.x + 0.8;
    a.p[1] = b.p[1] = t.y - 0.6;
    const MatchResult ma = translation.match(cur, m, a, MatchOptions{});
    const MatchResult mb = affine.match(cur, m, b, translation_only);
    ASSERT_TRUE(ma.converged);
    ASSERT_TRUE(mb.converged);
    EXPECT_EQ(ma.iterations, mb.iterations);
    EXPECT_NEAR(a.p[0], b.p[0], 1e-6);
    EXPECT_NEAR(a.p[1], b.p[1], 1e-6);
    EXPECT_NEAR(ma.zncc, mb.zncc, 1e-9);
    EXPECT_NEAR(ma.valid_fraction, mb.valid_fraction, 1e-12);
    EXPECT_NEAR(a.p[0], t.x, 0.01);
    EXPECT_NEAR(a.p[1], t.y, 0.01);
    if (!m.empty()) {
      EXPECT_LT(ma.valid_fraction, 0.9);
    }
  }
}

}  // namespace
}  // namespace tirstrain::flow
