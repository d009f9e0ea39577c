// The ellipse fitted to where ridges show near the border (contact/ridge_labels.cpp) on the bench renderer
// (tests/contact/tir_render.hpp): from a start 3.6 px and 4 % off, the centre comes back to the rendered
// contact; and inputs it cannot work on give no fit rather than a guess.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <iostream>
#include <numbers>

#include "contact/ridge_labels.hpp"
#include "tests/contact/tir_render.hpp"

namespace tirstrain::contact {
namespace {

Ellipse moved(Ellipse e, double dx_px, double dy_px, double scale) {
  e.cx_px += dx_px;
  e.cy_px += dy_px;
  e.semi_major_px *= scale;
  e.semi_minor_px *= scale;
  return e;
}

// The brackets on the bench renderer's default contact (straight or whorl ridges), started from `start`
// applied to the truth's ellipse; the truth and the fit (which must exist).
struct BracketRun {
  Ellipse truth;
  RidgeLabelFit fit;
  double axis_ratio;  // the fit's semi-axis ratio over the truth's
};

BracketRun run_brackets(bool whorl, const std::function<Ellipse(const Ellipse&)>& start) {
  RidgeLabelOptions options;
  options.method = RidgeLabelMethod::brackets;
  test::TirScene scene;
  scene.whorl = whorl;
  const cv::Mat image = test::render_tir(scene);
  const Ellipse truth = scene.contacts[0];
  const auto fit = fit_ellipse_to_ridge_labels(image, 255.0, start(truth), scene.period_px, -1, options);
  EXPECT_TRUE(fit.has_value()) << (whorl ? "whorl" : "straight");
  RidgeLabelFit none;
  none.ellipse = start(truth);
  BracketRun run{truth, fit.value_or(none), 0.0};
  run.axis_ratio = (run.fit.ellipse.semi_major_px / run.fit.ellipse.semi_minor_px) /
                   (truth.semi_major_px / truth.semi_minor_px);
  return run;
}

TEST(RidgeLabels, CentreComesBackFromAnOffsetStart) {
  for (const bool whorl : {false, true}) {
    test::TirScene scene;
    scene.whorl = whorl;
    const cv::Mat image = test::render_tir(scene);
    const Ellipse truth = scene.contacts[0];
    const auto fit =
        fit_ellipse_to_ridge_labels(image, 255.0, moved(truth, 3.0, -2.0, 0.96), scene.period_px, -1);
    ASSERT_TRUE(fit.has_value()) << (whorl ? "whorl" : "straight");
    const double centre_px = std::hypot(fit->ellipse.cx_px - truth.cx_px, fit->ellipse.cy_px - truth.cy_px);
    std::cout << (whorl ? "  whorl" : "  straight") << ": centre error " << centre_px << " px, axes "
              << fit->ellipse.semi_major_px << " / " << fit->ellipse.semi_minor_px << " px, labels "
              << fit->inside_labels << " in, " << fit->outside_labels << " out, " << fit->sectors_used
              << " sectors\n";
    // Straight ridges cross the border on two sides and end against it there: measured 0.05 px. Ridges
    // concentric about a core near the contact's centre run along the whole border, which leaves the centre
    // loosely held: measured 1.46 px, under half the start's 3.6 px.
    EXPECT_LT(centre_px, whorl ? 1.8 : 0.3);
    // The soft edge's tail counts as inside: the axes come out a little long, never short.
    EXPECT_GT(fit->ellipse.semi_major_px, truth.semi_major_px - 1.0);
    EXPECT_LT(fit->ellipse.semi_major_px, truth.semi_major_px + 4.0);
    EXPECT_GT(fit->ellipse.semi_minor_px, truth.semi_minor_px - 1.0);
    EXPECT_LT(fit->ellipse.semi_minor_px, truth.semi_minor_px + 4.0);
    EXPECT_GE(fit->sectors_used, 20);
  }
}

// Near the border of a sliding contact the skin is stretched or compressed, so the ridges there run at a
// period 10-15 % off the frame's: given a period 12 % off, the wave is still found and the centre still
// comes back (straight ridges; measured 0.29 and 0.12 px, against 0.05 px with the right period).
TEST(RidgeLabels, CentreComesBackWithThePeriodTwelvePercentOff) {
  test::TirScene scene;
  scene.whorl = false;
  const cv::Mat image = test::render_tir(scene);
  const Ellipse truth = scene.contacts[0];
  for (const double factor : {1.0 / 1.12, 1.12}) {
    const auto fit = fit_ellipse_to_ridge_labels(image, 255.0, moved(truth, 3.0, -2.0, 0.96),
                                                 factor * scene.period_px, -1);
    ASSERT_TRUE(fit.has_value()) << factor;
    const double centre_px = std::hypot(fit->ellipse.cx_px - truth.cx_px, fit->ellipse.cy_px - truth.cy_px);
    std::cout << "  period x " << factor << ": centre error " << centre_px << " px\n";
    EXPECT_LT(centre_px, 0.5) << factor;
  }
}

// The brackets (the segmenter's method on large contacts): from 3.6 px off the centre comes back for both
// ridge patterns, the concentric one included, where the logistic fit drifts outward along the arcs where
// valleys run along the border (measured: whorl 0.16 px, straight 0.42 px: where straight ridges run along
// the border on two opposite arcs, the border can lie anywhere in the valley between the last ridge and the
// next; from the level edge's start the segmenter gets 0.14 px on this contact). The start is 2 % small on
// both axes; the size from the sectors where ridges end at the border brings it to the truth's (measured
// 0.997 and 0.998 of it; asserted to 0.5 %, the start's 2 % fails), and the shape, right to begin with,
// stays right (axis ratio to 1 %).
TEST(RidgeLabels, BracketsBringTheCentreBack) {
  for (const bool whorl : {false, true}) {
    const BracketRun run =
        run_brackets(whorl, [](const Ellipse& truth) { return moved(truth, 3.0, -2.0, 0.98); });
    const Ellipse &e = run.fit.ellipse, &truth = run.truth;
    const double centre_px = std::hypot(e.cx_px - truth.cx_px, e.cy_px - truth.cy_px);
    const double size =
        std::sqrt(e.semi_major_px * e.semi_minor_px / (truth.semi_major_px * truth.semi_minor_px));
    std::cout << (whorl ? "  whorl" : "  straight") << ": centre error " << centre_px << " px, size " << size
              << " of the truth's, axis ratio " << run.axis_ratio << " of the truth's\n";
    EXPECT_LT(centre_px, 0.5);
    EXPECT_NEAR(size, 1.0, 0.005);
    EXPECT_NEAR(run.axis_ratio, 1.0, 0.01);
  }
}

// The brackets' shape terms: a start of the right size and centre but 4 % too elongated (major 2 % long,
// minor 2 % short) and turned 3 degrees comes back to the truth's shape: the axis ratio from 1.041 to within
// 1 % and the angle to within 1 degree, for both ridge patterns (measured: see the printed values). The level
// edge's shape errors on the synthetic trials are of this kind (a valley along the top and bottom arcs, a
// ridge end at the sides; BENCHMARKS.md, contact/).
TEST(RidgeLabels, BracketsCorrectTheShape) {
  for (const bool whorl : {false, true}) {
    const BracketRun run = run_brackets(whorl, [](const Ellipse& truth) {
      Ellipse start = truth;
      start.semi_major_px *= 1.02;
      start.semi_minor_px /= 1.02;
      start.angle_rad += 3.0 * std::numbers::pi / 180.0;
      return start;
    });
    const double angle_deg = (run.fit.ellipse.angle_rad - run.truth.angle_rad) * 180.0 / std::numbers::pi;
    std::cout << (whorl ? "  whorl" : "  straight") << ": axis ratio " << run.axis_ratio
              << " of the truth's, angle " << angle_deg << " deg off, shape terms " << run.fit.shape_cos2_px
              << ", " << run.fit.shape_sin2_px << " px\n";
    EXPECT_NEAR(run.axis_ratio, 1.0, 0.01);
    EXPECT_NEAR(angle_deg, 0.0, 1.0);
  }
}

// Normalised radius of (x, y) in `e` (1 on the ellipse).
double normalised_radius(const Ellipse& e, double x, double y) {
  const double dx = x - e.cx_px, dy = y - e.cy_px;
  const double u = (std::cos(e.angle_rad) * dx + std::sin(e.angle_rad) * dy) / e.semi_major_px;
  const double v = (-std::sin(e.angle_rad) * dx + std::cos(e.angle_rad) * dy) / e.semi_minor_px;
  return std::hypot(u, v);
}

// The frame is smoothed and read only in the band about the border (1.5 periods inside to 1.6 outside, plus
// the smoothing's and gradients' few pixels): blanking everything well inside and well outside it leaves the
// fit exactly as it was.
TEST(RidgeLabels, ReadsOnlyTheBandAboutTheBorder) {
  test::TirScene scene;
  scene.whorl = false;
  const cv::Mat image = test::render_tir(scene);
  const Ellipse start = moved(scene.contacts[0], 3.0, -2.0, 0.98);
  const double inner = 1.0 - (1.5 * scene.period_px + 10.0) / start.semi_minor_px;
  const double outer = 1.0 + (1.6 * scene.period_px + 10.0) / start.semi_minor_px;
  cv::Mat blanked = image.clone();
  for (int y = 0; y < blanked.rows; ++y)
    for (int x = 0; x < blanked.cols; ++x) {
      const double q = normalised_radius(start, x, y);
      if (q < inner || q > outer) blanked.at<std::uint8_t>(y, x) = 0;
    }
  for (const RidgeLabelMethod method : {RidgeLabelMethod::brackets, RidgeLabelMethod::logistic}) {
    RidgeLabelOptions options;
    options.method = method;
    const auto fit = fit_ellipse_to_ridge_labels(image, 255.0, start, scene.period_px, -1, options);
    const auto fit_blanked = fit_ellipse_to_ridge_labels(blanked, 255.0, start, scene.period_px, -1, options);
    ASSERT_TRUE(fit.has_value());
    ASSERT_TRUE(fit_blanked.has_value());
    EXPECT_EQ(fit->ellipse.cx_px, fit_blanked->ellipse.cx_px);
    EXPECT_EQ(fit->ellipse.cy_px, fit_blanked->ellipse.cy_px);
    EXPECT_EQ(fit->inside_labels, fit_blanked->inside_labels);
    EXPECT_EQ(fit->outside_labels, fit_blanked->outside_labels);
  }
}

// The same frame as 8-bit, 16-bit and float pixels gives the same centre (to float rounding).
TEST(RidgeLabels, SameCentreFromEightSixteenBitAndFloatFrames) {
  test::TirScene scene;
  const cv::Mat image = test::render_tir(scene);
  cv::Mat image16, image32;
  image.convertTo(image16, CV_16U, 257.0);
  image.convertTo(image32, CV_32F, 1.0 / 255.0);
  RidgeLabelOptions options;
  options.method = RidgeLabelMethod::brackets;
  const Ellipse start = moved(scene.contacts[0], 3.0, -2.0, 0.98);
  const auto fit8 = fit_ellipse_to_ridge_labels(image, 255.0, start, scene.period_px, -1, options);
  const auto fit16 = fit_ellipse_to_ridge_labels(image16, 65535.0, start, scene.period_px, -1, options);
  const auto fit32 = fit_ellipse_to_ridge_labels(image32, 1.0, start, scene.period_px, -1, options);
  ASSERT_TRUE(fit8 && fit16 && fit32);
  for (const auto* other : {&*fit16, &*fit32}) {
    EXPECT_NEAR(other->ellipse.cx_px, fit8->ellipse.cx_px, 1e-3);
    EXPECT_NEAR(other->ellipse.cy_px, fit8->ellipse.cy_px, 1e-3);
  }
}

// Vignetting: a frame lit by a quadratic falloff (to 70 % at the corners), with that falloff given as the
// illumination, gives the evenly lit frame's centre. The illumination is interpolated along each row of the
// band from three points, exact for a quadratic, and the smoothing of the product differs from the product of
// the smoothing too little to move a label: measured 0 px, against 0.55 px without the illumination.
TEST(RidgeLabels, IlluminationUndoesAQuadraticFalloff) {
  test::TirScene scene;
  scene.whorl = false;
  const cv::Mat image = test::render_tir(scene);
  const auto falloff = [&](double x, double y) {
    const double u = (x - 250.0) / scene.size.width, v = (y - 300.0) / scene.size.height;
    return 1.0 - 0.6 * (u * u + v * v) + 0.1 * u * v;
  };
  cv::Mat even, vignetted;
  image.convertTo(even, CV_32F, 1.0 / 255.0);
  vignetted = even.clone();
  for (int y = 0; y < vignetted.rows; ++y)
    for (int x = 0; x < vignetted.cols; ++x) vignetted.at<float>(y, x) *= static_cast<float>(falloff(x, y));
  RidgeLabelOptions options;
  options.method = RidgeLabelMethod::brackets;
  const Ellipse start = moved(scene.contacts[0], 3.0, -2.0, 0.98);
  const auto reference = fit_ellipse_to_ridge_labels(even, 1.0, start, scene.period_px, -1, options);
  const auto corrected =
      fit_ellipse_to_ridge_labels(vignetted, 1.0, start, scene.period_px, -1, options, falloff);
  ASSERT_TRUE(reference && corrected);
  const double difference_px = std::hypot(corrected->ellipse.cx_px - reference->ellipse.cx_px,
                                          corrected->ellipse.cy_px - reference->ellipse.cy_px);
  const auto uncorrected = fit_ellipse_to_ridge_labels(vignetted, 1.0, start, scene.period_px, -1, options);
  ASSERT_TRUE(uncorrected);
  const double uncorrected_px = std::hypot(uncorrected->ellipse.cx_px - reference->ellipse.cx_px,
                                           uncorrected->ellipse.cy_px - reference->ellipse.cy_px);
  std::cout << "  centre moved " << difference_px << " px by the corrected falloff, " << uncorrected_px
            << " px by the uncorrected one\n";
  EXPECT_LT(difference_px, 0.05);
  EXPECT_GT(uncorrected_px, 0.3) << "the falloff must matter for this test to show anything";
}

TEST(RidgeLabels, NoFitWhereThereIsNothingToLabel) {
  test::TirScene scene;
  const Ellipse contact = scene.contacts[0];
  const cv::Mat uniform(scene.size, CV_8UC1, cv::Scalar(190));
  EXPECT_FALSE(fit_ellipse_to_ridge_labels(uniform, 255.0, contact, scene.period_px, -1).has_value());
  const cv::Mat image = test::render_tir(scene);
  EXPECT_FALSE(fit_ellipse_to_ridge_labels(image, 255.0, contact, scene.period_px, 0).has_value())
      << "unknown polarity";
  EXPECT_FALSE(
      fit_ellipse_to_ridge_labels(image, 255.0, moved(contact, -200.0, 0.0, 1.0), scene.period_px, -1)
          .has_value())
      << "ellipse beyond the frame's edge";
  EXPECT_FALSE(fit_ellipse_to_ridge_labels(image, 255.0, contact, 0.0, -1).has_value()) << "no period";
}

}  // namespace
}  // namespace tirstrain::contact
