// measure_texture against images of known ridge amplitude and noise.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>

#include "flow/texture.hpp"

namespace tirstrain::flow {
namespace {

constexpr double kPeriodPx = 23.4;

// Straight ridges at 30° of amplitude `amplitude` around 0.5, plus white Gaussian noise of σ `noise`.
cv::Mat ridges(double amplitude, double noise, int seed = 3) {
  cv::Mat image(240, 260, CV_32F);
  const double kx = 2 * std::numbers::pi / kPeriodPx * std::cos(0.52),
               ky = 2 * std::numbers::pi / kPeriodPx * std::sin(0.52);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x)
      image.at<float>(y, x) = static_cast<float>(0.5 + amplitude * std::sin(kx * x + ky * y));
  if (noise > 0) {
    cv::Mat n(image.size(), CV_32F);
    cv::RNG rng(static_cast<std::uint64_t>(seed));
    rng.fill(n, cv::RNG::NORMAL, 0.0, noise);
    image += n;
  }
  return image;
}

cv::Mat disc(cv::Size size, int radius) {
  cv::Mat mask(size, CV_8U, cv::Scalar(0));
  cv::circle(mask, {size.width / 2, size.height / 2}, radius, cv::Scalar(255), cv::FILLED);
  return mask;
}

// The difference of Gaussians at σ = P/8 and P/2 passes a ridge of period P with gain
// exp(−2π²/64) − exp(−2π²/4).
double dog_gain() {
  const double pi2 = std::numbers::pi * std::numbers::pi;
  return std::exp(-2 * pi2 / 64) - std::exp(-2 * pi2 / 4);
}

TEST(Texture, NoiseAndRidgeLevelsOfAKnownImage) {
  const cv::Mat mask = disc({260, 240}, 100);
  for (const double noise : {0.01, 0.06}) {
    const TextureQuality q = measure_texture(ridges(0.2, noise), mask, kPeriodPx);
    // Noise: Immerkær's estimator, within 5 %; the ridges leak into its kernel by well under that.
    EXPECT_NEAR(q.noise_sigma, noise, 0.05 * noise) << "noise " << noise;
    // Ridges: amplitude/√2 through the band's gain, within 5 % (the passed noise adds a little).
    EXPECT_NEAR(q.ridge_rms, 0.2 / std::sqrt(2.0) * dog_gain(), 0.05 * 0.2 / std::sqrt(2.0))
        << "noise " << noise;
    EXPECT_NEAR(q.snr, q.ridge_rms / q.noise_sigma, 1e-12);
    EXPECT_GT(q.pixels, 20000);
  }
}

TEST(Texture, SeparatesTheSceneClasses) {
  const cv::Mat mask = disc({260, 240}, 100);
  // Noise-free ridges: the estimator's floor is the ridges' own (tiny) leak, far above any threshold.
  EXPECT_GT(measure_texture(ridges(0.2, 0.0), mask, kPeriodPx).snr, 100.0);
  // The synthetic scenes' classes: default ≈ 10.8, low contrast ≈ 1.8, heavy noise ≈ 1.9 (measured).
  EXPECT_GT(measure_texture(ridges(0.2, 0.012), mask, kPeriodPx).snr, 4.0);
  EXPECT_LT(measure_texture(ridges(0.04, 0.012), mask, kPeriodPx).snr, 4.0);
}

TEST(Texture, DegenerateInputsGiveDefinedResults) {
  const cv::Mat uniform(120, 120, CV_32F, cv::Scalar(0.4));
  const TextureQuality flat = measure_texture(uniform, disc({120, 120}, 50), kPeriodPx);
  EXPECT_EQ(flat.noise_sigma, 0.0);
  EXPECT_EQ(flat.ridge_rms, 0.0);
  EXPECT_EQ(flat.snr, 0.0);
  EXPECT_GT(flat.pixels, 0);
  // A contact smaller than the border margin: nothing measured, no NaN.
  const TextureQuality tiny = measure_texture(ridges(0.2, 0.01), disc({260, 240}, 8), kPeriodPx);
  EXPECT_EQ(tiny.pixels, 0);
  EXPECT_EQ(tiny.snr, 0.0);
  EXPECT_EQ(measure_texture(ridges(0.2, 0.01), cv::Mat(240, 260, CV_8U, cv::Scalar(0)), kPeriodPx).pixels, 0);
  // No mask: the whole frame (less the margin) is measured.
  EXPECT_GT(measure_texture(ridges(0.2, 0.01), cv::Mat(), kPeriodPx).pixels, 30000);
  EXPECT_EQ(measure_texture(ridges(0.2, 0.01), cv::Mat(), 0.0).pixels, 0);
}

}  // namespace
}  // namespace tirstrain::flow
