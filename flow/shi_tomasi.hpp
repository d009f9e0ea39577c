#pragma once
// The Shi–Tomasi score (the smaller eigenvalue of the gradient's structure tensor) over an image region,
// computed band by band. cv::cornerMinEigenVal over the whole contact box allocates its gradient and
// tensor images afresh at each call (≈ 8 MB for a 640×512 trial's contact): on these machines, where a
// fresh page costs ≈ 12 µs, that was a fifth of the seeding's time and most of a birth frame's extra time.
// Band by band the scratch stays small and is reused.
#include <opencv2/core.hpp>

namespace tirstrain::flow {

// cv::cornerMinEigenVal(region, out, block_px, 3) with its default border, for `region` a view into a
// larger image (the Sobel reads the real pixels around the view, as OpenCV's does): the same values, the
// bands overlapping by half a block so that each band's border handling never reaches a row it keeps.
// `out` is (re)allocated to the region's size, CV_32F; `scratch` is reused between calls.
void min_eigenvalue_map(const cv::Mat& region, int block_px, cv::Mat& out, cv::Mat& scratch);

}  // namespace tirstrain::flow
