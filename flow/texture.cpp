#include "flow/texture.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/image_noise.hpp"
#include "flow/mask_erosion.hpp"

namespace tirstrain::flow {
namespace {

// The structure tensor of `smooth` (already low-passed at the ridge scale), integrated by a Gaussian of
// P/2: over a window of about one period, ridges give one dominant gradient direction, a speckle none.
double ridge_coherence(const cv::Mat& smooth, const cv::Mat& interior, double ridge_period_px) {
  cv::Mat gx, gy;
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Mat jxx = gx.mul(gx), jyy = gy.mul(gy), jxy = gx.mul(gy);
  const double sigma = 0.5 * ridge_period_px;
  for (cv::Mat* j : {&jxx, &jyy, &jxy})
    cv::GaussianBlur(*j, *j, cv::Size(), sigma, 0.0, cv::BORDER_REPLICATE);
  double anisotropy = 0.0, energy = 0.0;
  for (int y = 0; y < smooth.rows; ++y) {
    const auto* in = interior.ptr<std::uint8_t>(y);
    const auto *xx = jxx.ptr<float>(y), *yy = jyy.ptr<float>(y), *xy = jxy.ptr<float>(y);
    for (int x = 0; x < smooth.cols; ++x) {
      if (!in[x]) continue;
      const double d = static_cast<double>(xx[x]) - yy[x];
      anisotropy += std::sqrt(d * d + 4.0 * static_cast<double>(xy[x]) * xy[x]);
      energy += static_cast<double>(xx[x]) + yy[x];
    }
  }
  return energy > 0.0 ? anisotropy / energy : 0.0;
}

}  // namespace

TextureQuality measure_texture(const cv::Mat& image, const cv::Mat& mask, double ridge_period_px) {
  CV_Assert(image.type() == CV_32F &&
            (mask.empty() || (mask.type() == CV_8U && mask.size() == image.size())));
  TextureQuality q;
  if (image.rows < 3 || image.cols < 3 || !(ridge_period_px > 0.0)) return q;
  // Only the mask's bounding box is filtered: the views keep their parent image, so every filter reads the
  // real pixels around the box and each value inside equals the whole frame's (and the frame's outside the
  // contact was fresh memory to fault in, ~5 MB on a 640×512 frame).
  const cv::Rect box = mask.empty() ? cv::Rect(0, 0, image.cols, image.rows) : cv::boundingRect(mask);
  if (box.area() == 0) return q;
  // The interior, on the box alone: the mask is 0 outside it, as the erosion's constant border is.
  cv::Mat interior, contact;
  if (mask.empty())
    contact = cv::Mat(box.size(), CV_8U, cv::Scalar(1));
  else
    cv::compare(mask(box), 0, contact, cv::CMP_NE);
  const int reach = std::max(1, static_cast<int>(std::ceil(0.5 * ridge_period_px)));
  erode_ellipse(contact, reach, interior);
  q.pixels = cv::countNonZero(interior);
  if (q.pixels == 0) return q;

  const cv::Mat view = image(box);
  q.noise_sigma = immerkaer_noise_sigma(view, interior);

  cv::Mat fine, coarse;
  cv::GaussianBlur(view, fine, cv::Size(), ridge_period_px / 8.0, 0.0, cv::BORDER_REPLICATE);
  cv::GaussianBlur(view, coarse, cv::Size(), ridge_period_px / 2.0, 0.0, cv::BORDER_REPLICATE);
  cv::Scalar mean, stddev;
  cv::meanStdDev(fine - coarse, mean, stddev, interior);
  q.ridge_rms = stddev[0];
  q.snr = q.ridge_rms / std::max(q.noise_sigma, 1e-9);
  q.coherence = ridge_coherence(fine, interior, ridge_period_px);
  cv::Mat gx, gy;
  cv::Sobel(view, gx, CV_32F, 1, 0, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(view, gy, CV_32F, 0, 1, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  q.gradient_energy = 0.5 * (cv::mean(gx.mul(gx), interior)[0] + cv::mean(gy.mul(gy), interior)[0]);
  q.ridges = q.coherence >= kMinRidgeCoherence;
  return q;
}

}  // namespace tirstrain::flow
