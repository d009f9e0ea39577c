// The resampled fixed-shape machinery against exactly known fields: the node fits of ShapeField, the frame
// resampled through a field (resample_through), and one translation step of a subset on it
// (Subset::translation_step). Frames are rendered by evaluating the analytic ridge texture at the
// inverse-mapped position of every pixel, so the only errors are the interpolation's and the method's.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>

#include "flow/shape_field.hpp"
#include "flow/subset.hpp"
#include "ridge_texture.hpp"

namespace tirstrain::flow {
namespace {

using testing::ridge_texture;
using Field = std::function<Vec2(Vec2)>;

// A smooth field with strain of a few per cent and curvature, like the slip annulus of a loaded contact.
Vec2 quadratic_field(Vec2 X) {
  const double x = X.x - 100.0, y = X.y - 100.0;
  return {1.7 + 0.03 * x - 0.02 * y + 1.5e-4 * x * x - 1e-4 * x * y + 0.8e-4 * y * y,
          -0.6 + 0.01 * x + 0.04 * y - 0.7e-4 * x * x + 1.2e-4 * x * y - 0.5e-4 * y * y};
}

// Tracks on an 8 px grid, each moved off its lattice point by up to ±2 px (as births and retirements leave
// them), over [lo, hi]².
std::vector<Vec2> scattered_points(double lo, double hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-2.0, 2.0);
  std::vector<Vec2> points;
  for (double y = lo; y <= hi; y += 8.0)
    for (double x = lo; x <= hi; x += 8.0) points.push_back({x + jitter(rng), y + jitter(rng)});
  return points;
}

std::vector<Vec2> displacements(const std::vector<Vec2>& points, const Field& u) {
  std::vector<Vec2> out;
  for (const Vec2& p : points) out.push_back(u(p));
  return out;
}

cv::Mat render(int size, const Field& u) {
  cv::Mat img(size, size, CV_32F);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      Vec2 X{static_cast<double>(x), static_cast<double>(y)};
      for (int k = 0; k < 40; ++k) {  // fixed point X = x − u(X)
        const Vec2 d = u(X);
        X = {x - d.x, y - d.y};
      }
      img.at<float>(y, x) = static_cast<float>(ridge_texture(X.x, X.y));
    }
  return img;
}

// A 200 px frame pair, the texture at rest and warped by quadratic_field; the anchor on the first (with
// `mask`, if any) and a field fitted to the warp at scattered samples (`seed`), shifted by `offset`.
struct WarpedPair {
  static constexpr int size = 200;
  cv::Mat reference, current;
  AnchorImage anchor;
  ShapeField field;
};

WarpedPair warped_pair(unsigned seed, Vec2 offset = {}, const cv::Mat& mask = cv::Mat()) {
  WarpedPair w;
  w.reference = render(WarpedPair::size, [](Vec2) { return Vec2{}; });
  w.current = render(WarpedPair::size, quadratic_field);
  w.anchor.assign(w.reference, mask);
  const std::vector<Vec2> points = scattered_points(0.0, 200.0, seed);
  std::vector<Vec2> shifted = displacements(points, quadratic_field);
  for (Vec2& d : shifted) d = {d.x + offset.x, d.y + offset.y};
  w.field.fit(points, shifted, cv::Rect(0, 0, WarpedPair::size, WarpedPair::size), 8.0, 20.0);
  return w;
}

TEST(ShapeField, RecoversAQuadraticFieldAndItsGradientExactly) {
  const std::vector<Vec2> points = scattered_points(0.0, 200.0, 1);
  ShapeField field;
  field.fit(points, displacements(points, quadratic_field), cv::Rect(0, 0, 201, 201), 8.0, 20.0);
  EXPECT_GT(field.fitted_nodes(), 600);
  double worst = 0.0, worst_gradient = 0.0;
  for (double y = 30.5; y < 170.0; y += 3.7)
    for (double x = 30.25; x < 170.0; x += 4.1) {
      Vec2 u;
      Eigen::Matrix2d g;
      ASSERT_TRUE(field.displacement(x, y, u, &g));
      const Vec2 t = quadratic_field({x, y});
      worst = std::max(worst, std::hypot(u.x - t.x, u.y - t.y));
      const double dx = x - 100.0, dy = y - 100.0;
      Eigen::Matrix2d exact;
      exact << 0.03 + 3e-4 * dx - 1e-4 * dy, -0.02 - 1e-4 * dx + 1.6e-4 * dy,
          0.01 - 1.4e-4 * dx + 1.2e-4 * dy, 0.04 + 1.2e-4 * dx - 1e-4 * dy;
      worst_gradient = std::max(worst_gradient, (g - exact).cwiseAbs().maxCoeff());
    }
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT(worst_gradient, 1e-10);
}

TEST(ShapeField, FallsBackToAffineOnTwoRowsAndLeavesUnsampledAreasUndefined) {
  // Two rows of samples: the quadratic terms in y are not determined, the affine fit is.
  std::vector<Vec2> points;
  for (double x = 0.0; x <= 200.0; x += 8.0) points.push_back({x, 100.0}), points.push_back({x + 4.0, 108.0});
  const auto affine = [](Vec2 X) { return Vec2{0.5 + 0.02 * X.x - 0.01 * X.y, -1.0 + 0.03 * X.y}; };
  ShapeField field;
  field.fit(points, displacements(points, affine), cv::Rect(0, 0, 201, 201), 8.0, 20.0);
  EXPECT_GT(field.fitted_nodes(), 0);
  for (double x = 40.0; x < 160.0; x += 5.3) {
    Vec2 u;
    ASSERT_TRUE(field.displacement(x, 104.0, u));
    const Vec2 t = affine({x, 104.0});
    EXPECT_NEAR(u.x, t.x, 1e-9);
    EXPECT_NEAR(u.y, t.y, 1e-9);
  }
  Vec2 u;
  EXPECT_FALSE(field.displacement(100.0, 190.0, u));  // 80 px from any sample: no node there has a fit
  EXPECT_FALSE(field.displacement(-5.0, 100.0, u));   // outside the region
}

TEST(ShapeField, ARefitOnTheSamePositionsEqualsAFreshFit) {
  // The second call reuses the node operators built by the first (same positions): it must give what a
  // new field fitted from scratch gives.
  const std::vector<Vec2> points = scattered_points(0.0, 160.0, 2);
  const auto other = [](Vec2 X) { return Vec2{std::sin(X.x / 30.0), std::cos(X.y / 25.0) + 0.01 * X.x}; };
  ShapeField reused, fresh;
  reused.fit(points, displacements(points, quadratic_field), cv::Rect(0, 0, 161, 161), 8.0, 12.0);
  reused.fit(points, displacements(points, other), cv::Rect(0, 0, 161, 161), 8.0, 12.0);
  fresh.fit(points, displacements(points, other), cv::Rect(0, 0, 161, 161), 8.0, 12.0);
  ASSERT_EQ(reused.fitted_nodes(), fresh.fitted_nodes());
  for (double y = 10.0; y < 150.0; y += 7.0)
    for (double x = 10.0; x < 150.0; x += 7.0) {
      Vec2 a, b;
      ASSERT_EQ(reused.displacement(x, y, a), fresh.displacement(x, y, b));
      EXPECT_NEAR(a.x, b.x, 1e-12);
      EXPECT_NEAR(a.y, b.y, 1e-12);
    }
}

TEST(ShapeField, ANodeWhoseSamplesDidNotChangeKeepsItsOperator) {
  // Between frames tracks retire and are born in places, the list's order changes and the region moves by
  // whole grid steps; the nodes out of reach of every change keep their operators. The field must be the
  // one a fresh fit gives, to the last bit (the samples are taken in a fixed order either way).
  std::vector<Vec2> points = scattered_points(0.0, 200.0, 3);
  ShapeField reused, fresh;
  reused.fit(points, displacements(points, quadratic_field), cv::Rect(0, 0, 201, 201), 8.0, 12.0);
  EXPECT_EQ(reused.reused_nodes(), 0);
  // Retire the tracks in one corner, add two, reverse the order.
  std::erase_if(points, [](Vec2 p) { return p.x < 40.0 && p.y < 40.0; });
  points.push_back({150.5, 20.25});
  points.push_back({30.0, 170.0});
  std::reverse(points.begin(), points.end());
  const cv::Rect moved(8, 0, 193, 201);
  const auto other = [](Vec2 X) { return Vec2{std::sin(X.x / 30.0), std::cos(X.y / 25.0) + 0.01 * X.x}; };
  reused.fit(points, displacements(points, other), moved, 8.0, 12.0);
  fresh.fit(points, displacements(points, other), moved, 8.0, 12.0);
  ASSERT_EQ(reused.fitted_nodes(), fresh.fitted_nodes());
  std::cout << "nodes fitted " << reused.fitted_nodes() << ", operators kept " << reused.reused_nodes()
            << "\n";
  // Those within the fit radius (24 px) of a change are built again (measured: 590 of 689 kept).
  EXPECT_GT(reused.reused_nodes(), reused.fitted_nodes() / 2);
  EXPECT_LT(reused.reused_nodes(), reused.fitted_nodes());
  EXPECT_EQ(fresh.reused_nodes(), 0);
  for (double y = 2.0; y < 200.0; y += 3.0)
    for (double x = 10.0; x < 200.0; x += 3.0) {
      Vec2 a, b;
      Eigen::Matrix2d ga, gb;
      const bool defined = reused.displacement(x, y, a, &ga);
      ASSERT_EQ(defined, fresh.displacement(x, y, b, &gb));
      if (!defined) continue;
      EXPECT_EQ(a.x, b.x);
      EXPECT_EQ(a.y, b.y);
      EXPECT_EQ(ga, gb);
    }
}

// The region follows the contact: tracks that retired beyond this frame's region are among the changes, and
// must neither reach outside the node grid (a negative fill once crashed `process`) nor change the field.
TEST(ShapeField, ChangesBeyondTheNewRegionAreHarmless) {
  std::vector<Vec2> points = scattered_points(0.0, 200.0, 3);
  ShapeField reused, fresh;
  reused.fit(points, displacements(points, quadratic_field), cv::Rect(0, 0, 201, 201), 8.0, 12.0);
  // Keep the upper-left quarter; the region shrinks to it, so the retired positions lie far beyond it.
  std::erase_if(points, [](Vec2 p) { return p.x > 90.0 || p.y > 90.0; });
  const cv::Rect shrunk(0, 0, 91, 91);
  const auto other = [](Vec2 X) { return Vec2{std::sin(X.x / 30.0), std::cos(X.y / 25.0) + 0.01 * X.x}; };
  reused.fit(points, displacements(points, other), shrunk, 8.0, 12.0);
  fresh.fit(points, displacements(points, other), shrunk, 8.0, 12.0);
  ASSERT_EQ(reused.fitted_nodes(), fresh.fitted_nodes());
  EXPECT_GT(fresh.fitted_nodes(), 50);
  for (double y = 2.0; y < 90.0; y += 3.0)
    for (double x = 2.0; x < 90.0; x += 3.0) {
      Vec2 a, b;
      const bool defined = reused.displacement(x, y, a);
      ASSERT_EQ(defined, fresh.displacement(x, y, b));
      if (!defined) continue;
      EXPECT_EQ(a.x, b.x);
      EXPECT_EQ(a.y, b.y);
    }
}

TEST(ShapeField, RowEvaluationEqualsPointEvaluation) {
  // A field with holes (no samples in a disc) and a ragged edge, on a spacing that is not a whole number
  // of pixels: the row evaluation the resampling uses must give displacement()'s values and definedness.
  std::vector<Vec2> points;
  for (const Vec2& p : scattered_points(0.0, 160.0, 5))
    if (std::hypot(p.x - 90.0, p.y - 70.0) > 35.0 && p.x + 0.3 * p.y < 170.0) points.push_back(p);
  const auto other = [](Vec2 X) { return Vec2{std::sin(X.x / 30.0), std::cos(X.y / 25.0) + 0.01 * X.x}; };
  ShapeField field;
  field.fit(points, displacements(points, other), cv::Rect(3, 5, 150, 150), 7.3, 10.0);
  std::vector<Vec2> row(200);
  std::vector<std::uint8_t> ok(200);
  int defined = 0, undefined = 0;
  for (int y = 0; y < 165; ++y) {
    field.displacement_row(y, -10, 190, row.data(), ok.data());
    for (int x = -10; x < 190; ++x) {
      Vec2 u;
      const bool expected = field.displacement(x, y, u);
      const std::size_t k = static_cast<std::size_t>(x + 10);
      ASSERT_EQ(ok[k] != 0, expected) << x << "," << y;
      if (!expected) {
        ++undefined;
        continue;
      }
      ++defined;
      EXPECT_NEAR(row[k].x, u.x, 1e-12);
      EXPECT_NEAR(row[k].y, u.y, 1e-12);
    }
  }
  EXPECT_GT(defined, 10000);
  EXPECT_GT(undefined, 5000);
  // One column class only (every 3rd column from x ≡ 1): the same values there, nothing elsewhere.
  std::vector<Vec2> full(200);
  std::vector<std::uint8_t> full_ok(200);
  int compared = 0;
  for (int y = 0; y < 165; y += 2) {
    field.displacement_row(y, -10, 190, full.data(), full_ok.data());
    field.displacement_row(y, -10, 190, row.data(), ok.data(), 3, 1);
    for (int x = -10; x < 190; ++x) {
      const std::size_t k = static_cast<std::size_t>(x + 10);
      if (((x % 3) + 3) % 3 != 1) {
        ASSERT_EQ(ok[k], 0) << x << "," << y;
        continue;
      }
      ASSERT_EQ(ok[k], full_ok[k]) << x << "," << y;
      if (!ok[k]) continue;
      ++compared;
      EXPECT_EQ(row[k].x, full[k].x);
      EXPECT_EQ(row[k].y, full[k].y);
    }
  }
  EXPECT_GT(compared, 1500);
}

TEST(ResampleThrough, UndoesAKnownWarpToTheInterpolationError) {
  const int size = 200;
  const cv::Mat current = render(size, quadratic_field);
  const std::vector<Vec2> points = scattered_points(0.0, 200.0, 3);
  ShapeField field;
  field.fit(points, displacements(points, quadratic_field), cv::Rect(0, 0, size, size), 8.0, 20.0);
  cv::Mat anchor_mask = cv::Mat::zeros(size, size, CV_8U);
  cv::circle(anchor_mask, {100, 100}, 80, cv::Scalar(1), cv::FILLED);
  // The current frame's contact leaves out a strip: those anchor pixels land there and have no value.
  cv::Mat current_mask(size, size, CV_8U, cv::Scalar(1));
  current_mask(cv::Rect(150, 0, 50, size)).setTo(0);
  cv::Mat out, valid;
  resample_through(current, current_mask, field, anchor_mask, cv::Rect(0, 0, size, size), out, valid);
  double worst = 0.0;
  int checked = 0, dropped = 0;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const Vec2 u = quadratic_field({static_cast<double>(x), static_cast<double>(y)});
      const bool lands_inside = x + u.x < 149.0 && anchor_mask.at<std::uint8_t>(y, x);
      if (!anchor_mask.at<std::uint8_t>(y, x)) {
        EXPECT_EQ(valid.at<std::uint8_t>(y, x), 0);
        continue;
      }
      if (x + u.x > 150.5) {
        EXPECT_EQ(valid.at<std::uint8_t>(y, x), 0) << x << "," << y;
        ++dropped;
        continue;
      }
      if (!lands_inside) continue;
      ASSERT_EQ(valid.at<std::uint8_t>(y, x), 1) << x << "," << y;
      worst = std::max(worst, std::abs(out.at<float>(y, x) - ridge_texture(x, y)));
      ++checked;
    }
  EXPECT_GT(checked, 10000);
  EXPECT_GT(dropped, 1000);
  // Keys bicubic on ridges of 17-23 px period (amplitude 0.25 + 0.12): measured 1.4e-4.
  EXPECT_LT(worst, 1e-3);
}

// One translation step of a subset on the frame resampled through a field that is off by a constant
// δ: the step must take the track point to the truth, x = (X − Δ) + W(X − Δ).
TEST(SubsetTranslationStep, MovesATrackOntoTheTruthFromAnOffsetField) {
  const int size = WarpedPair::size;
  const WarpedPair pair = warped_pair(4, {0.4, -0.3});
  const AnchorImage& anchor = pair.anchor;
  const ShapeField& field = pair.field;
  const cv::Mat& current = pair.current;
  cv::Mat out, valid;
  resample_through(current, cv::Mat(), field, anchor.mask(), cv::Rect(0, 0, size, size), out, valid);
  double worst = 0.0;
  for (int cy = 70; cy <= 130; cy += 20)
    for (int cx = 70; cx <= 130; cx += 20) {
      Subset subset;
      ASSERT_TRUE(subset.build(anchor, {cx, cy}, 20, 1, ShapeFunction::kTranslation, 100));
      Vec2 step;
      const MatchResult m = subset.translation_step(anchor, out, valid, 0.5, step);
      ASSERT_TRUE(m.converged);
      EXPECT_GT(m.zncc, 0.9);
      EXPECT_DOUBLE_EQ(m.valid_fraction, 1.0);
      const Vec2 q{cx - step.x, cy - step.y};
      Vec2 u;
      ASSERT_TRUE(field.displacement(q.x, q.y, u));
      const Vec2 truth = quadratic_field({static_cast<double>(cx), static_cast<double>(cy)});
      worst = std::max(worst, std::hypot(q.x + u.x - (cx + truth.x), q.y + u.y - (cy + truth.y)));
    }
  // One Gauss–Newton step from 0.5 px off lands second-order close: measured 0.012 px.
  EXPECT_LT(worst, 0.025);
}

TEST(SubsetTranslationStep, ASubsetWithoutItsPixelCopyStepsTheSameAndRefusesToMatch) {
  // The tracker drops the per-pixel copy of frame-0 tracks' wide subsets (Subset::release_pixels): the
  // translation steps, from the pixel pass and from the box sums, must not change, and a full match must
  // report a degenerate subset rather than match nothing.
  const int size = WarpedPair::size;
  const WarpedPair pair = warped_pair(4);
  const AnchorImage& anchor = pair.anchor;
  const ShapeField& field = pair.field;
  const cv::Mat& current = pair.current;
  cv::Mat out, valid;
  resample_through(current, cv::Mat(), field, anchor.mask(), cv::Rect(0, 0, size, size), out, valid);
  valid(cv::Rect(0, 0, size, 75)).setTo(0);  // the row of subsets at y = 80 takes the pixel pass
  WindowSums sums;
  sums.build(anchor, out, valid, cv::Rect(0, 0, size, size), 2);
  int compared = 0;
  for (int cy = 60; cy <= 140; cy += 20)
    for (int cx = 60; cx <= 140; cx += 20) {
      Subset subset;
      ASSERT_TRUE(
          subset.build(anchor, {cx, cy}, 20, 2, ShapeFunction::kTranslation, 100, Subset::Lattice::kImage));
      Vec2 pass_before, sums_before, pass_after, sums_after;
      const MatchResult a = subset.translation_step(anchor, out, valid, 0.3, pass_before);
      const MatchResult b = subset.translation_step(sums, anchor, out, valid, 0.3, sums_before);
      const std::size_t pixels = subset.pixel_count();
      subset.release_pixels();
      EXPECT_FALSE(subset.has_pixels());
      EXPECT_FALSE(subset.empty());
      EXPECT_EQ(subset.pixel_count(), pixels);
      const MatchResult c = subset.translation_step(anchor, out, valid, 0.3, pass_after);
      const MatchResult d = subset.translation_step(sums, anchor, out, valid, 0.3, sums_after);
      ASSERT_EQ(a.converged, c.converged);
      ASSERT_EQ(b.converged, d.converged);
      EXPECT_EQ(pass_before.x, pass_after.x);
      EXPECT_EQ(pass_before.y, pass_after.y);
      EXPECT_EQ(sums_before.x, sums_after.x);
      EXPECT_EQ(sums_before.y, sums_after.y);
      EXPECT_EQ(a.zncc, c.zncc);
      EXPECT_EQ(b.zncc, d.zncc);
      compared += a.converged ? 1 : 0;
      Warp w;
      EXPECT_TRUE(subset.match(current, cv::Mat(), w, MatchOptions{}).degenerate);
    }
  EXPECT_EQ(compared, 20);  // all but the row at y = 60, which lies wholly outside
}

TEST(SubsetTranslationStep, ReportsTooFewValidPixels) {
  const int size = 120;
  const cv::Mat reference = render(size, [](Vec2) { return Vec2{}; });
  AnchorImage anchor;
  anchor.assign(reference, cv::Mat());
  Subset subset;
  ASSERT_TRUE(subset.build(anchor, {60, 60}, 20, 1, ShapeFunction::kTranslation, 100));
  cv::Mat valid(size, size, CV_8U, cv::Scalar(0));
  valid(cv::Rect(0, 0, 55, size)).setTo(1);  // the left 15 of the subset's 41 columns (40-54)
  Vec2 step{1.0, 1.0};
  const MatchResult m = subset.translation_step(anchor, reference, valid, 0.5, step);
  EXPECT_FALSE(m.converged);
  EXPECT_NEAR(m.valid_fraction, 15.0 / 41.0, 1e-9);
  EXPECT_EQ(step.x, 0.0);
  // With the same pixels and no motion, a permissive threshold gives a zero step.
  const MatchResult ok = subset.translation_step(anchor, reference, valid, 0.3, step);
  ASSERT_TRUE(ok.converged);
  EXPECT_NEAR(ok.zncc, 1.0, 1e-5);
  EXPECT_LT(std::hypot(step.x, step.y), 1e-6);
  // An anchor other than the subset's own (here: its mask differs) is refused, not read.
  cv::Mat half(size, size, CV_8U, cv::Scalar(1));
  half(cv::Rect(0, 0, size, 60)).setTo(0);
  AnchorImage other;
  other.assign(reference, half);
  EXPECT_TRUE(subset.translation_step(other, reference, valid, 0.3, step).degenerate);
}

// The translation step from a window's box sums (WindowSums, one table per round) against the pass over the
// subset's own pixels: the same sums to rounding, on strides 1 and 2, near the image's edges, beside the
// table region's inner sides (where the table must refuse) and where part of a window has no resampled value
// (where the step falls back to the pass).
TEST(WindowSums, StepFromTheSumsEqualsThePassOverTheWindow) {
  const int size = WarpedPair::size;
  cv::Mat mask = cv::Mat::zeros(size, size, CV_8U);
  cv::ellipse(mask, {100, 100}, {97, 88}, 20.0, 0.0, 360.0, cv::Scalar(1), cv::FILLED);
  const WarpedPair pair = warped_pair(5, {0.3, -0.2}, mask);
  const AnchorImage& anchor = pair.anchor;
  const ShapeField& field = pair.field;
  const cv::Mat& current = pair.current;
  cv::Mat current_mask(size, size, CV_8U, cv::Scalar(1));
  current_mask(cv::Rect(0, 150, size, 50)).setTo(0);  // the lower rows' pixels get no resampled value
  cv::Mat out, valid;
  resample_through(current, current_mask, field, anchor.mask(), cv::Rect(0, 0, size, size), out, valid);
  // The table's region touches the image's left and top sides and ends inside it on the right and bottom.
  const cv::Rect region(0, 0, 160, 190);
  // One table for both strides: the second build finds the first one's sums in its cells (only the zero row
  // and column are cleared).
  WindowSums sums;
  for (int stride : {1, 2}) {
    sums.build(anchor, out, valid, region, stride);
    int from_sums = 0, refused = 0, partly_invalid = 0;
    double worst_step = 0.0, worst_zncc = 0.0;
    for (int cy = 3; cy < size; cy += 7)
      for (int cx = 3; cx < size; cx += 7) {
        const int radius = stride == 1 ? 20 : 21;
        Subset subset;
        if (!subset.build(anchor, {cx, cy}, radius, stride, ShapeFunction::kTranslation, 40)) continue;
        WindowSums::Window w;
        const bool inside = cx + radius < region.x + region.width && cy + radius < region.y + region.height;
        ASSERT_EQ(sums.window({cx, cy}, radius, w), inside) << cx << "," << cy;
        if (!inside) {
          ++refused;
          continue;
        }
        EXPECT_EQ(w.mask, static_cast<double>(subset.pixel_count())) << cx << "," << cy;
        if (w.outside > 0)
          ++partly_invalid;
        else
          ++from_sums;
        Vec2 pass_step, sums_step;
        const MatchResult pass = subset.translation_step(anchor, out, valid, 0.3, pass_step);
        const MatchResult boxed = subset.translation_step(sums, anchor, out, valid, 0.3, sums_step);
        ASSERT_EQ(pass.converged, boxed.converged) << cx << "," << cy;
        EXPECT_EQ(pass.valid_fraction, boxed.valid_fraction);
        worst_step = std::max(worst_step, std::hypot(pass_step.x - sums_step.x, pass_step.y - sums_step.y));
        worst_zncc = std::max(worst_zncc, std::abs(pass.zncc - boxed.zncc));
      }
    // Float row sums in the pass against double products in the table: measured below 1e-6 px.
    EXPECT_LT(worst_step, 1e-5) << "stride " << stride;
    EXPECT_LT(worst_zncc, 1e-6) << "stride " << stride;
    EXPECT_GT(from_sums, 200) << "stride " << stride;
    EXPECT_GT(refused, 100) << "stride " << stride;
    EXPECT_GT(partly_invalid, 20) << "stride " << stride;
    std::cout << "  stride " << stride << ": " << from_sums << " from the sums, " << partly_invalid
              << " partly invalid, " << refused << " refused; worst step difference " << worst_step
              << " px, zncc " << worst_zncc << "\n";
  }
}

// At stride 2 the rounds resample and sum only the lattices their subsets read (PixelClasses): on those
// pixels the frame and every step are the same as with all pixels; the other lattices stay invalid and
// their windows find no pixels.
TEST(WindowSums, OnlyTheSubsetsLatticesAreResampledAndSummed) {
  const int size = WarpedPair::size;
  const WarpedPair pair = warped_pair(6);
  const AnchorImage& anchor = pair.anchor;
  const ShapeField& field = pair.field;
  const cv::Mat& current = pair.current;
  const cv::Rect region(0, 0, size, size);
  cv::Mat all_out, all_valid, out, valid;
  resample_through(current, cv::Mat(), field, anchor.mask(), region, all_out, all_valid);
  PixelClasses lattices(2);
  lattices.add(40 - 20, 60 - 20);  // the (even, even) lattice
  resample_through(current, cv::Mat(), field, anchor.mask(), region, out, valid, lattices);
  int resampled = 0, left_out = 0;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      if (x % 2 == 0 && y % 2 == 0) {
        ASSERT_EQ(valid.at<std::uint8_t>(y, x), all_valid.at<std::uint8_t>(y, x)) << x << "," << y;
        if (!valid.at<std::uint8_t>(y, x)) continue;
        ASSERT_EQ(out.at<float>(y, x), all_out.at<float>(y, x)) << x << "," << y;
        ++resampled;
      } else {
        ASSERT_EQ(valid.at<std::uint8_t>(y, x), 0) << x << "," << y;
        ++left_out;
      }
    }
  EXPECT_GT(resampled, 9000);
  EXPECT_EQ(left_out, size * size * 3 / 4);
  WindowSums all_sums, sums;
  all_sums.build(anchor, all_out, all_valid, region, 2);
  sums.build(anchor, out, valid, region, 2, lattices);
  int compared = 0;
  // Centres of either parity, their samples on the image's lattice (the (even, even) class).
  for (int cy = 24; cy < 176; cy += 8)
    for (int cx = 25; cx < 176; cx += 8) {
      Subset subset;
      ASSERT_TRUE(subset.build(anchor, {cx, cy + (cx / 8) % 2}, 20, 2, ShapeFunction::kTranslation, 40,
                               Subset::Lattice::kImage));
      const cv::Point first = subset.first_offset();
      ASSERT_EQ((cx + first.x) % 2, 0);
      ASSERT_EQ((cy + (cx / 8) % 2 + first.y) % 2, 0);
      // Odd sides: 20 samples from −19 to 19; even sides: 21 from −20 to 20.
      EXPECT_EQ(subset.pixel_count(),
                static_cast<std::size_t>((first.x == -20 ? 21 : 20) * (first.y == -20 ? 21 : 20)));
      Vec2 step_all, step;
      const MatchResult a = subset.translation_step(all_sums, anchor, all_out, all_valid, 0.6, step_all);
      const MatchResult b = subset.translation_step(sums, anchor, out, valid, 0.6, step);
      ASSERT_TRUE(a.converged && b.converged) << cx << "," << cy;
      EXPECT_EQ(step.x, step_all.x);
      EXPECT_EQ(step.y, step_all.y);
      ++compared;
    }
  EXPECT_EQ(compared, 361);
  // A window on another lattice (odd centre) finds none of its pixels in the table.
  WindowSums::Window w;
  ASSERT_TRUE(sums.window({101, 100}, 20, w));
  EXPECT_EQ(w.mask, 0.0);
}

}  // namespace
}  // namespace tirstrain::flow
