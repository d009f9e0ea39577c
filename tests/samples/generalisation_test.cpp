// The generalisation benchmark's exact-truth sequences (samples/generalisation.hpp): the rest frame is the
// texture itself, a rigid integer shift moves the reference image by whole pixels, every pixel's inverse map
// satisfies the forward map, and the analytic gradients the inversion relies on are the fields' derivatives.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "samples/generalisation.hpp"

namespace tirstrain::samples {
namespace {

constexpr GeneralisationTexture kTextures[] = {GeneralisationTexture::kSpeckle,
                                               GeneralisationTexture::kFingerprint};

GeneralisationConfig tiny(GeneralisationField field, GeneralisationTexture texture) {
  GeneralisationConfig c = generalisation_config(field, texture, 0.005, true);
  c.width_px = 96;
  c.height_px = 64;
  return c;
}

TEST(GeneralisationSamples, RestFrameIsTheTextureAtEveryPixelCentre) {
  for (const GeneralisationField field : generalisation_fields()) {
    for (const GeneralisationTexture texture : kTextures) {
      const GeneralisationCase sequence(tiny(field, texture));
      double residual_px = 1.0;
      const cv::Mat frame = sequence.render_clean(0, &residual_px);
      EXPECT_EQ(residual_px, 0.0) << sequence.name();
      int different = 0;
      for (int y = 0; y < frame.rows; ++y)
        for (int x = 0; x < frame.cols; ++x)
          different +=
              frame.at<float>(y, x) != static_cast<float>(sequence.texture_level({double(x), double(y)}));
      EXPECT_EQ(different, 0) << sequence.name();
    }
  }
}

TEST(GeneralisationSamples, IntegerShiftMovesTheReferenceByWholePixels) {
  // Frame k shows the reference at x - u: I_k(x, y) = I_0(x - u_x, y - u_y) exactly, the inverse of a rigid
  // integer shift being exact in floating point.
  for (const GeneralisationTexture texture : kTextures) {
    const GeneralisationCase sequence(
        generalisation_config(GeneralisationField::kIntegerShift, texture, 0.0, true));
    const cv::Mat reference = sequence.render_clean(0);
    for (int k = 1; k < sequence.frames(); ++k) {
      const cv::Mat frame = sequence.render_clean(k);
      const Vec2 u = sequence.field({0.0, 0.0}, k).displacement_px;
      const int ux = static_cast<int>(u.x), uy = static_cast<int>(u.y);
      ASSERT_EQ(ux, u.x);
      ASSERT_EQ(uy, u.y);
      double worst = 0.0;
      int compared = 0;
      for (int y = std::max(0, uy); y < std::min(frame.rows, frame.rows + uy); ++y)
        for (int x = std::max(0, ux); x < std::min(frame.cols, frame.cols + ux); ++x) {
          worst =
              std::max(worst, double(std::abs(frame.at<float>(y, x) - reference.at<float>(y - uy, x - ux))));
          ++compared;
        }
      EXPECT_GT(compared, frame.total() / 2);
      EXPECT_EQ(worst, 0.0) << sequence.name() << " frame " << k;
    }
  }
}

TEST(GeneralisationSamples, InverseMapOfEveryPixelSatisfiesTheForwardMap) {
  // Newton on the exact gradient stops at 1e-10 px; every pixel of every frame of every case within 1e-6 px.
  for (const GeneralisationField field : generalisation_fields()) {
    const GeneralisationCase sequence(tiny(field, GeneralisationTexture::kSpeckle));
    double worst_px = 0.0;
    for (int k = 0; k < sequence.frames(); ++k) {
      double residual_px = 0.0;
      sequence.render_clean(k, &residual_px);
      worst_px = std::max(worst_px, residual_px);
    }
    std::printf("[ measured ] %s: max |X + u(X) - x| %.2g px\n", to_string(field).c_str(), worst_px);
    EXPECT_LT(worst_px, 1e-6) << to_string(field);
  }
}

TEST(GeneralisationSamples, AnalyticGradientsAreTheFieldsDerivatives) {
  // Central differences, h = 1e-4 px: truncation ~h^2 |u'''| / 6, below 1e-7 for these fields.
  const double h = 1e-4;
  for (const GeneralisationField field : generalisation_fields()) {
    const GeneralisationCase sequence(tiny(field, GeneralisationTexture::kSpeckle));
    double worst = 0.0;
    for (int k = 1; k < sequence.frames(); ++k) {
      for (double y = 3.0; y < sequence.height(); y += 9.7) {
        for (double x = 2.0; x < sequence.width(); x += 7.3) {
          const Gradient2 g = sequence.field({x, y}, k).gradient;
          const Vec2 px = sequence.field({x + h, y}, k).displacement_px;
          const Vec2 mx = sequence.field({x - h, y}, k).displacement_px;
          const Vec2 py = sequence.field({x, y + h}, k).displacement_px;
          const Vec2 my = sequence.field({x, y - h}, k).displacement_px;
          worst = std::max(
              {worst, std::abs((px.x - mx.x) / (2 * h) - g.xx), std::abs((py.x - my.x) / (2 * h) - g.xy),
               std::abs((px.y - mx.y) / (2 * h) - g.yx), std::abs((py.y - my.y) / (2 * h) - g.yy)});
        }
      }
    }
    EXPECT_LT(worst, 1e-6) << to_string(field);
  }
}

TEST(GeneralisationSamples, ChirpWavelengthFallsGeometricallyAndMatchesItsPhase) {
  const GeneralisationCase sequence(
      generalisation_config(GeneralisationField::kChirp, GeneralisationTexture::kSpeckle, 0.005, true));
  const double last_px = sequence.width() - 1.0;
  EXPECT_NEAR(sequence.chirp_wavelength_px(0.0), 200.0, 1e-9);
  EXPECT_NEAR(sequence.chirp_wavelength_px(last_px), 10.0, 1e-9);
  EXPECT_NEAR(sequence.chirp_wavelength_px(0.5 * last_px), std::sqrt(200.0 * 10.0), 1e-9);
  EXPECT_EQ(sequence.chirp_phase_rad(0.0), 0.0);
  for (double x = 0.0; x <= last_px; x += 37.0) {
    const double h = 1e-4;
    const double derivative = (sequence.chirp_phase_rad(x + h) - sequence.chirp_phase_rad(x - h)) / (2 * h);
    EXPECT_NEAR(derivative, 2.0 * std::numbers::pi / sequence.chirp_wavelength_px(x), 1e-7) << x;
  }
}

TEST(GeneralisationSamples, SpeckleHasDicContrast) {
  // Levels between 0.1 (full ink) and 0.9 (paper), spread over most of that range.
  const Speckle speckle(5.0, 2.5, 11);
  double sum = 0.0, sum2 = 0.0, lo = 1.0, hi = 0.0;
  int n = 0;
  for (double y = 0.0; y < 200.0; y += 0.7)
    for (double x = 0.0; x < 200.0; x += 0.7) {
      const double v = speckle.level({x, y});
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      sum += v;
      sum2 += v * v;
      ++n;
    }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  std::printf("[ measured ] speckle levels %.3f .. %.3f, mean %.3f, sd %.3f\n", lo, hi, mean, sd);
  EXPECT_GE(lo, 0.1);
  EXPECT_LE(hi, 0.9);
  EXPECT_GT(hi - lo, 0.6);
  EXPECT_GT(sd, 0.12);
  EXPECT_NEAR(mean, 0.5, 0.15);
}

TEST(GeneralisationSamples, NoiseHasTheStatedSigmaOfFullScale) {
  const GeneralisationCase sequence(generalisation_config(GeneralisationField::kSubpixelShift,
                                                          GeneralisationTexture::kSpeckle, 0.02, true));
  const cv::Mat clean = sequence.render_clean(1);
  const cv::Mat noisy = sequence.add_noise(clean, 1);
  ASSERT_EQ(noisy.type(), CV_16U);
  cv::Mat difference;
  noisy.convertTo(difference, CV_64F, 1.0 / 65535.0);
  cv::Mat clean64;
  clean.convertTo(clean64, CV_64F);
  difference -= clean64;
  cv::Scalar mean, sd;
  cv::meanStdDev(difference, mean, sd);
  // 24576 samples: the sample sigma is within ~1 % of 0.02, the mean within ~1.3e-4.
  EXPECT_NEAR(sd[0], 0.02, 0.0006);
  EXPECT_NEAR(mean[0], 0.0, 0.0005);
}

}  // namespace
}  // namespace tirstrain::samples
