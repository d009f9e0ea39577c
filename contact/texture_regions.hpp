#pragma once
// The first decision of a frame: is there ridge texture, and where. The working image is band-passed around
// the ridge period and rectified, grey closing fills the zero crossings between ridges and valleys, opening
// removes specks of noise; Otsu's threshold then splits contact from background, and the textured regions
// joined to the largest one make the contact (docs/contact.md, "Regions").
#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace tirstrain::contact {

// The odd kernel size nearest `size`, at least `minimum`.
int odd_at_least(double size, int minimum);

// Grey closing with a `close_k` square, then opening with an `open_k` square (replicated borders), of `src`
// into `dst` through `scratch`.
void close_then_open(const cv::Mat& src, int close_k, int open_k, cv::Mat& scratch, cv::Mat& dst);

// Images the texture step fills, reused from frame to frame.
struct TextureImages {
  cv::Mat blur_small, blur_large;
  cv::Mat band;    // the band-pass image (difference of Gaussians), CV_32FC1
  cv::Mat energy;  // |band| closed then opened: the texture energy, CV_32FC1
  cv::Mat scratch;
};

// The band-pass around a ridge period of `period_w` working pixels and the texture energy of `work`; zero
// energy in `excluded_w` (working pixels; may be empty).
void ridge_texture_energy(const cv::Mat& work, double period_w, const cv::Rect& excluded_w,
                          TextureImages& images);

// The mean texture energy white noise of σ = 1 gives at this period (ridge_texture_energy on a fixed-seed
// noise image): what a frame's own noise contributes, its measured σ times this.
double noise_energy_per_sigma(double period_w);

// The connected regions of energy above a threshold (8-connected), and the largest of them.
struct TextureRegions {
  cv::Mat labels, stats, centroids;  // as cv::connectedComponentsWithStats gives them
  cv::Mat mask;
  int count = 0;         // labels, the background's 0 included
  int largest = 0;       // 0: no region
  int largest_area = 0;  // working pixels
};
void label_texture_regions(const cv::Mat& energy, float threshold, TextureRegions& regions);

// The regions joined to the largest one: those at least `merge_fraction` of its area and within `max_gap_w`
// working pixels of it. `multiple_blobs`: another region of at least `min_area_mm2` exists (joined or not;
// `mm2_per_working_px` is a working pixel's area).
struct JoinedRegions {
  std::vector<std::uint8_t> keep;  // per label: part of the contact
  cv::Rect box_w;                  // the kept regions' bounding box, working pixels
  bool multiple_blobs = false;
};
JoinedRegions join_to_largest(const TextureRegions& regions, double merge_fraction, double max_gap_w,
                              double mm2_per_working_px, double min_area_mm2);

// Outline points of the kept regions: the first and last kept pixel of each row (enough for a convex hull).
std::vector<cv::Point2d> kept_boundary(const cv::Mat& labels, const std::vector<std::uint8_t>& keep);

}  // namespace tirstrain::contact
