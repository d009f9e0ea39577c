#pragma once
// Erosion of a binary mask by OpenCV's elliptic structuring element, without OpenCV's per-element pass.
// cv::erode with a (2r+1)² MORPH_ELLIPSE visits every element point per pixel: at the automatic preset's
// border exclusion (r = 0.6 P ≈ 14 px) that was 8 % of the tracker's instructions per 640×512 frame. Here
// each row first records, run by run, how far its run of set pixels extends to both sides of each pixel; a
// pixel then survives when, for every row of the element, that reach covers the element row's half-width:
// 2r + 1 byte comparisons per pixel, which vectorise. Only the band along the contact's edge is tested:
// outside every element row's extent a pixel is background, and inside every row's run of full reach it
// survives (on the goal trial 94 → 43 M instructions over 10 frames).
#include <opencv2/core.hpp>

namespace tirstrain::flow {

// Exactly cv::erode(mask, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2r+1, 2r+1}), {-1, -1}, 1,
// cv::BORDER_CONSTANT, 0) for a CV_8U mask whose pixels are 0 or one nonzero value (kept where the pixel
// survives). `out` may be a view (e.g. of a larger mask) of the mask's size; it must not share the mask's
// pixels. radius_px 0 copies.
void erode_ellipse(const cv::Mat& mask, int radius_px, cv::Mat& out);

// Where subsets may read pixels: the contact `mask` (CV_8U, 0 or one nonzero value) eroded by the border
// exclusion's ellipse of `exclusion_px` and by the interpolation kernel's reach (erode_for_matching), within
// `box` (the contact's bounding box grown past both, clipped to the image); written into `out`, a view of
// `box`'s size. The contact's border bounds both erosions. The image's edge bounds only the kernel's: a
// contact running off the frame has no border there (no fading partial contact), and outside the image
// there are simply no pixels, so the exclusion there would only throw away half of every edge subset.
// `scratch`: reused buffers.
struct MatchMaskScratch {
  cv::Mat padded, eroded;
};
void erode_contact_for_matching(const cv::Mat& mask, cv::Rect box, int exclusion_px,
                                MatchMaskScratch& scratch, cv::Mat& out);

}  // namespace tirstrain::flow
