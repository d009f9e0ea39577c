#pragma once
// A small, exact TIR-like renderer for contact tests and the contact benchmark, independent of samples/:
// an elliptical contact (soft border) filled with a ridge texture of known period and orientation, on a
// smooth background with Gaussian noise. The truth is known in closed form: the mask is every pixel centre
// inside the ellipse, the ridge orientation is the tangent of the ridge lines.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "contact/ellipse.hpp"

namespace tirstrain::test {

struct TirScene {
  cv::Size size{640, 512};
  std::vector<contact::Ellipse> contacts{{320.0, 256.0, 150.0, 110.0, 0.4}};
  double period_px = 23.4;  // 0.45 mm at 52 px/mm
  // Ridges: concentric around (core_x, core_y) when whorl, else straight at `ridge_angle_rad`.
  bool whorl = true;
  double core_x = 300.0, core_y = 230.0;
  double ridge_angle_rad = 0.5;
  double background = 0.75;   // fraction of full scale
  double ridge_depth = 0.45;  // how much darker ridges in contact are (fraction of full scale)
  bool dark_ridges = true;
  double border_px = 3.0;  // width of the soft border
  double noise = 0.02;     // Gaussian sigma, fraction of full scale
  double gain = 1.0;       // > 1 drives the image into saturation
  int depth = CV_8U;
  std::uint64_t seed = 1;
  // Patches of lost ridge contrast (sweat): centre x, y, radius in px.
  std::vector<cv::Vec3d> sweat;
};

inline double ridge_phase(const TirScene& s, double x, double y) {
  if (s.whorl) return 2.0 * std::numbers::pi * std::hypot(x - s.core_x, y - s.core_y) / s.period_px;
  const double nx = -std::sin(s.ridge_angle_rad), ny = std::cos(s.ridge_angle_rad);
  return 2.0 * std::numbers::pi * (nx * x + ny * y) / s.period_px;
}

// Ridge direction from +x towards +y, in [0, pi).
inline double ridge_orientation(const TirScene& s, double x, double y) {
  double a = s.whorl ? std::atan2(y - s.core_y, x - s.core_x) + std::numbers::pi / 2.0 : s.ridge_angle_rad;
  a = std::fmod(a, std::numbers::pi);
  return a < 0.0 ? a + std::numbers::pi : a;
}

// Signed distance-like value: ~px outside (>0) / inside (<0) the nearest contact.
inline double contact_distance(const TirScene& s, double x, double y) {
  double best = 1e30;
  for (const auto& e : s.contacts) {
    const double c = std::cos(e.angle_rad), sn = std::sin(e.angle_rad);
    const double dx = x - e.cx_px, dy = y - e.cy_px;
    const double u = (c * dx + sn * dy) / e.semi_major_px, v = (-sn * dx + c * dy) / e.semi_minor_px;
    const double r = std::hypot(u, v);
    // Distance along the ray, scaled by the local radius: exact for circles, close for mild ellipses.
    const double radius =
        r > 0.0 ? std::hypot(u * e.semi_major_px, v * e.semi_minor_px) / r : e.semi_minor_px;
    best = std::min(best, (r - 1.0) * radius);
  }
  return best;
}

inline cv::Mat render_truth_mask(const TirScene& s) {
  cv::Mat mask(s.size, CV_8UC1);
  for (int y = 0; y < s.size.height; ++y)
    for (int x = 0; x < s.size.width; ++x) {
      bool inside = false;
      for (const auto& e : s.contacts)
        inside = inside || contact::ellipse_level(e, {double(x), double(y)}) < 0.0;
      mask.at<std::uint8_t>(y, x) = inside ? 255 : 0;
    }
  return mask;
}

inline cv::Mat render_tir(const TirScene& s) {
  cv::Mat image(s.size, CV_32FC1);
  for (int y = 0; y < s.size.height; ++y) {
    float* row = image.ptr<float>(y);
    for (int x = 0; x < s.size.width; ++x) {
      const double d = contact_distance(s, x, y);
      double c = 0.5 - d / s.border_px;  // contact weight: 1 inside, 0 outside, linear across the border
      c = std::clamp(c, 0.0, 1.0);
      for (const auto& p : s.sweat) {
        const double r = std::hypot(x - p[0], y - p[1]);
        if (r < p[2]) c *= std::clamp((r - 0.8 * p[2]) / (0.2 * p[2]), 0.0, 1.0);
      }
      const double ridge = 0.5 + 0.5 * std::cos(ridge_phase(s, x, y));
      const double shade = s.ridge_depth * c * ridge;
      row[x] = static_cast<float>(s.background + (s.dark_ridges ? -shade : shade));
    }
  }
  cv::Mat noise(s.size, CV_32FC1);
  cv::RNG rng(s.seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, s.noise);
  image = (image + noise) * s.gain;
  cv::Mat out;
  const double scale = s.depth == CV_16U ? 65535.0 : 255.0;
  image.convertTo(out, s.depth, scale);  // saturates at full scale
  return out;
}

}  // namespace tirstrain::test
