#pragma once
// The flat field: a smooth background surface fitted around the contact (vignetting, the light's tilt), and
// the frame with its ridges made bright on that flattened background. Without it, grey closing flattens a
// background that rises outward beside the contact and the level edge is placed too far in (docs/contact.md).
#include <opencv2/core.hpp>

#include <array>
#include <optional>

namespace tirstrain::contact {

// A smooth background under the contact: a quadratic surface in x and y (vignetting and the light's tilt),
// with the RMS residual of the pixels it was fitted to.
struct QuadraticSurface {
  std::array<double, 6> c{};  // 1, u, v, u^2, uv, v^2 with u, v the pixel's position scaled to [-1, 1]
  double x0 = 0.0, y0 = 0.0, scale = 1.0;
  double residual_rms = 0.0;
  double operator()(double x, double y) const {
    const double u = (x - x0) * scale, v = (y - y0) * scale;
    return c[0] + c[1] * u + c[2] * v + c[3] * u * u + c[4] * u * v + c[5] * v * v;
  }
};

// The surface least-squares fitted to every 3rd pixel each way of `image` where `exclude` is zero (a smooth
// surface needs no more). Nothing when fewer than `min_pixels` are left, or when the background does not
// surround `centre` (every 45-degree sector around it must hold `min_pixels` / 16 of them): a surface
// extrapolated across the contact from one side or from the frame's corners is no better a background than
// the level measured along each ray.
std::optional<QuadraticSurface> fit_background(const cv::Mat& image, const cv::Mat& exclude,
                                               cv::Point2d centre, int min_pixels);

// Ridges made bright on a flat background. Dividing by the background surface removes the illumination's
// shape from both the background and the ridge contrast it scales; where the background is nearly black
// (bright ridges on a dark field) the division would amplify noise, and the surface is subtracted instead.
// `work` and `bright` are CV_32FC1; `polarity` -1 makes dark ridges bright.
void flatten(const cv::Mat& work, const QuadraticSurface& background, int polarity, cv::Mat& bright);

}  // namespace tirstrain::contact
