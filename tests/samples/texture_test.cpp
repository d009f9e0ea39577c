// The fingerprint's ridge orientation truth (Fingerprint::ridge_orientation_rad, Trial::ridge_orientation_rad
// and the blocks written to truth.h5 as /texture/orientation_rad) against the rendered images.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "samples/trial.hpp"
#include "test_support.hpp"

namespace tirstrain::samples {
namespace {

using testing::clean_scene;
using testing::config_of;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = 180.0 / kPi;

// |a - b| between two orientations modulo pi, in [0, pi/2].
double orientation_difference(double a, double b) {
  double d = std::fmod(std::abs(a - b), kPi);
  return std::min(d, kPi - d);
}

// Image gradient by the 5-point central difference (error ~(k h)^4 / 30 of the derivative: 2e-4 at the 23 px
// ridge period).
Vec2 gradient5(const cv::Mat& image, int x, int y) {
  const auto at = [&](int xx, int yy) { return static_cast<double>(image.at<float>(yy, xx)); };
  return {(-at(x + 2, y) + 8.0 * at(x + 1, y) - 8.0 * at(x - 1, y) + at(x - 2, y)) / 12.0,
          (-at(x, y + 2) + 8.0 * at(x, y + 1) - 8.0 * at(x, y - 1) + at(x, y - 2)) / 12.0};
}

// Distance inside the contact beyond which the image is the warped texture alone: the soft border and the
// contrast fade, both fixed in the image, multiply the texture and add their own gradient.
double full_contrast_depth_px(const Trial& trial) {
  const SynthConfig& c = trial.config();
  return 3.0 * c.contact.border_softness_px + c.contact.fade_mm * c.scene.px_per_mm + 3.0;
}

TEST(SamplesTexture, RidgeOrientationIsPerpendicularToTheRenderedGradient) {
  // Without minutiae and pores the rendered value is background + contrast (1 + cos phase) / 2, so its
  // gradient is parallel to the image-plane phase gradient wherever sin(phase) is not small. Checked in frame
  // 0 and in a general affine field (stretch, shear and rotation turn ridges by up to ~25 degrees), which
  // exercises the transport of the reference direction by F = I + H:
  //  - exactly, against central differences (h = 0.01 px) of the renderer's value at x, i.e. the
  //    fingerprint's ridge() at the inverted reference point of x +- h;
  //  - statistically, against the 5-point central difference of the rendered pixels. Its error is ~1e-3 deg
  //    on straight ridges but reaches ~2 deg within 2 px of the lines through the core and the end of the
  //    loop's axis, where the distance-to-segment phase is only C1 (the ridge curvature jumps), hence the
  //    rms and 99th-percentile bounds.
  YAML::Node scene = clean_scene(256, 256, 2, 10.0);
  scene["synthesis"]["fingerprint"]["pore_depth"] = 0.0;
  scene["synthesis"]["fingerprint"]["minutiae_per_mm2"] = 0.0;
  scene["synthesis"]["loading"] = YAML::Load("{field: affine, gradient: [0.4, 0.25, -0.1, -0.2]}");
  const Trial trial(config_of(scene));
  const SynthConfig& c = trial.config();
  const double plane_wave_gradient = 0.5 * c.fingerprint.ridge_contrast * 2.0 * kPi /
                                     (c.ridge_period_mm * c.scene.px_per_mm);  // |d value / dx| at sin = 1
  double largest_turn = 0.0;
  for (int frame = 0; frame < trial.frames(); ++frame) {
    const cv::Mat image = trial.render_clean(frame);
    const FrameField field = trial.field(frame);
    const auto value = [&](double x, double y) {
      return trial.fingerprint().ridge(field.invert({x, y}).reference_px);
    };
    std::vector<double> pixel_errors;
    double exact_worst = 0.0;
    for (int y = 3; y < trial.height() - 3; ++y) {
      for (int x = 3; x < trial.width() - 3; ++x) {
        if (trial.contact_signed_distance_px({double(x), double(y)}) > -full_contrast_depth_px(trial))
          continue;
        const Vec2 g = gradient5(image, x, y);
        // |sin(phase)| >= ~0.35 (0.35 of the plane-wave slope, divided by the largest stretch 1.5).
        if (std::hypot(g.x, g.y) < 0.35 * plane_wave_gradient / 1.5) continue;
        const double truth = trial.ridge_orientation_rad(field, {double(x), double(y)});
        const double at_reference =
            trial.fingerprint().ridge_orientation_rad(field.invert({double(x), double(y)}).reference_px);
        largest_turn = std::max(largest_turn, orientation_difference(truth, at_reference));
        constexpr double h = 0.01;
        const double vx = value(x + h, y) - value(x - h, y), vy = value(x, y + h) - value(x, y - h);
        exact_worst = std::max(exact_worst, orientation_difference(std::atan2(vx, -vy), truth));
        pixel_errors.push_back(orientation_difference(std::atan2(g.x, -g.y), truth));
      }
    }
    ASSERT_GE(pixel_errors.size(), 5000u) << "frame " << frame;
    double sum2 = 0.0;
    for (double e : pixel_errors) sum2 += e * e;
    const double rms = std::sqrt(sum2 / static_cast<double>(pixel_errors.size()));
    std::sort(pixel_errors.begin(), pixel_errors.end());
    const double p99 = pixel_errors[pixel_errors.size() * 99 / 100];
    std::printf(
        "[ measured ] frame %d, %zu pixels: vs the renderer's value max %.5f deg; vs the pixels' 5-point "
        "gradient rms %.4f deg, 99th percentile %.4f deg, max %.3f deg\n",
        frame, pixel_errors.size(), exact_worst * kDeg, rms * kDeg, p99 * kDeg, pixel_errors.back() * kDeg);
    EXPECT_LE(exact_worst * kDeg, 0.005) << "frame " << frame;
    EXPECT_LE(rms * kDeg, 0.2) << "frame " << frame;
    EXPECT_LE(p99 * kDeg, 1.0) << "frame " << frame;
  }
  std::printf("[ measured ] the field turns ridges by up to %.1f deg\n", largest_turn * kDeg);
  EXPECT_GE(largest_turn * kDeg, 10.0);  // the transport by F is exercised, not just frame 0's texture
}

TEST(SamplesTexture, OrientationBlocksMatchTheRenderedImagesStructureTensor) {
  // The truth's block orientation against the orientation of the rendered image's squared-gradient tensor
  // summed over the same 32 x 32 blocks (Bazen & Gerez, as contact/ computes it), in blocks entirely in the
  // full-contrast part of the contact whose truth coherence is >= 0.9 (one direction across the block), in
  // frame 0 and a CM frame in full slip. Minutiae on, pores off: the pores are texture, not ridge flow, and
  // move the tensor's orientation by up to ~8 deg in such blocks (measured), which says more about the
  // estimator than about the truth. The remaining difference (~1 deg) is the tensor's |gradient|^2
  // weighting against the truth's uniform doubled-angle mean where the direction varies within a block.
  YAML::Node scene = clean_scene(384, 384, 8, 50.0);
  scene["synthesis"]["fingerprint"]["pore_depth"] = 0.0;
  scene["synthesis"]["contact"]["normal_N"] = 2.0;  // a = 152 px
  scene["synthesis"]["contact"]["radius_m"] = 0.02;
  const Trial trial(config_of(scene));
  ASSERT_TRUE(trial.load(trial.frames() - 1).full_slip);
  constexpr int kBlock = 32;
  for (int frame : {0, trial.frames() - 1}) {
    const cv::Mat image = trial.render_clean(frame);
    const Trial::OrientationBlocks truth = trial.ridge_orientation_blocks(frame, kBlock);
    ASSERT_EQ(truth.orientation_rad.rows, 12);
    ASSERT_EQ(truth.orientation_rad.cols, 12);
    int blocks = 0;
    double worst = 0.0;
    for (int by = 0; by < truth.orientation_rad.rows; ++by) {
      for (int bx = 0; bx < truth.orientation_rad.cols; ++bx) {
        bool inside = true;
        for (int corner = 0; corner < 4 && inside; ++corner) {
          const Vec2 p{bx * kBlock - 3.0 + (corner % 2) * (kBlock + 5.0),
                       by * kBlock - 3.0 + (corner / 2) * (kBlock + 5.0)};
          inside = trial.contact_signed_distance_px(p) < -full_contrast_depth_px(trial);
        }
        if (!inside || truth.coherence.at<double>(by, bx) < 0.9) continue;
        double gxx = 0.0, gyy = 0.0, gxy = 0.0;
        for (int y = by * kBlock; y < (by + 1) * kBlock; ++y) {
          for (int x = bx * kBlock; x < (bx + 1) * kBlock; ++x) {
            const Vec2 g = gradient5(image, x, y);
            gxx += g.x * g.x;
            gyy += g.y * g.y;
            gxy += g.x * g.y;
          }
        }
        double measured = 0.5 * std::atan2(2.0 * gxy, gxx - gyy) + 0.5 * kPi;  // ridges across the gradient
        if (measured >= kPi) measured -= kPi;
        worst = std::max(worst, orientation_difference(measured, truth.orientation_rad.at<double>(by, bx)));
        ++blocks;
      }
    }
    std::printf("[ measured ] frame %d: %d blocks (coherence >= 0.9), block orientation error max %.2f deg\n",
                frame, blocks, worst * kDeg);
    EXPECT_GE(blocks, 15) << "frame " << frame;
    EXPECT_LE(worst * kDeg, 2.0) << "frame " << frame;
  }
}

}  // namespace
}  // namespace tirstrain::samples
