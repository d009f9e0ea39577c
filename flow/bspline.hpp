#pragma once
// Cubic B-spline interpolation of images. Interpolating the pixel values themselves with a cubic kernel
// (Keys) mistakes part of a sub-pixel shift for blur: on a sprayed speckle it reads a 0.2 px shift about
// 0.01 px short, which a subset match then reports as a bias of that size. The cubic B-spline kernel
// applied to the image's spline coefficients (the pixels filtered once so that the spline passes through
// every one of them) interpolates with an error an order of magnitude smaller, at the same 4×4 cost per
// sample.
#include <opencv2/core.hpp>

#include <cstdint>

namespace tirstrain::flow {

// How a subset match reads the current frame between pixels: Keys' cubic convolution of the pixel values,
// or the cubic B-spline of the image's coefficients (cubic_bspline_coefficients: the caller passes those).
enum class Interpolation : std::uint8_t { kKeys, kCubicBSpline };

// The cubic B-spline coefficients of `image` (CV_32F) over `region` (mirror-symmetric boundaries at the
// region's edges), written into `coefficients` (CV_32F, the image's size; outside the region, the pixel
// values). Interpolating them with the cubic B-spline kernel reproduces every pixel of the region.
void cubic_bspline_coefficients(const cv::Mat& image, cv::Rect region, cv::Mat& coefficients);

}  // namespace tirstrain::flow
