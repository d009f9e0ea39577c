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
    // Straight ridges are one-dimensional: the structure tensor's coherence is near 1 at low noise, and
    // well above the ridge threshold at an SNR of ~1 (σ = 0.06 against a ridge RMS of 0.07 in the band).
    EXPECT_GT(q.coherence, noise < 0.03 ? 0.9 : 0.5) << "noise " << noise;
    EXPECT_TRUE(q.ridges);
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

TEST(Texture, TheContactsBoxGivesTheWholeFramesFigures) {
  // measure_texture filters only the mask's bounding box, through views that read the real pixels around
  // it: the figures must be those of filtering the whole frame (computed here the long way).
  const cv::Mat image = ridges(0.2, 0.03);
  cv::Mat mask(image.size(), CV_8U, cv::Scalar(0));
  cv::ellipse(mask, {120, 110}, {70, 55}, 25.0, 0.0, 360.0, cv::Scalar(1), cv::FILLED);
  const TextureQuality q = measure_texture(image, mask, kPeriodPx);
  cv::Mat interior;
  cv::compare(mask, 0, interior, cv::CMP_NE);
  const int reach = static_cast<int>(std::ceil(0.5 * kPeriodPx));
  cv::erode(interior, interior,
            cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * reach + 1, 2 * reach + 1)),
            cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat response, fine, coarse;
  cv::filter2D(image, response, CV_32F, cv::Matx33f(1, -2, 1, -2, 4, -2, 1, -2, 1), cv::Point(-1, -1), 0.0,
               cv::BORDER_REPLICATE);
  const double noise = cv::mean(cv::abs(response), interior)[0] * std::sqrt(0.5 * std::numbers::pi) / 6.0;
  cv::GaussianBlur(image, fine, cv::Size(), kPeriodPx / 8.0, 0.0, cv::BORDER_REPLICATE);
  cv::GaussianBlur(image, coarse, cv::Size(), kPeriodPx / 2.0, 0.0, cv::BORDER_REPLICATE);
  cv::Scalar mean, stddev;
  cv::meanStdDev(fine - coarse, mean, stddev, interior);
  EXPECT_EQ(q.pixels, cv::countNonZero(interior));
  EXPECT_NEAR(q.noise_sigma, noise, 1e-12);
  EXPECT_NEAR(q.ridge_rms, stddev[0], 1e-12);
}

}  // namespace
}  // namespace tirstrain::flow
