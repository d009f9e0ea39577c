#include "contact/texture_regions.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace tirstrain::contact {
namespace {

// Gaussian blur with the kernel truncated at 3 sigma (OpenCV's default for float images is 4 sigma: a third
// more taps for a tail of 0.3 % of the weight).
void gaussian(const cv::Mat& in, cv::Mat& out, double sigma) {
  const int k = 2 * std::max(1, static_cast<int>(std::ceil(3.0 * sigma))) + 1;
  cv::GaussianBlur(in, out, cv::Size(k, k), sigma, sigma, cv::BORDER_REFLECT);
}

// For each label of `labels` (CV_32S, `count` labels, 0 background), the smallest distance in pixels from
// its pixels to those of label `from` (0 for `from` itself; infinity for the background and, with no other
// label, for all).
std::vector<double> gaps_to_region(const cv::Mat& labels, int count, int from) {
  std::vector<double> gap(static_cast<std::size_t>(count), std::numeric_limits<double>::infinity());
  if (from > 0 && from < count) gap[static_cast<std::size_t>(from)] = 0.0;
  if (count <= 2) return gap;
  cv::Mat outside, distance;
  cv::compare(labels, from, outside, cv::CMP_NE);
  cv::distanceTransform(outside, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  for (int y = 0; y < labels.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    const float* d = distance.ptr<float>(y);
    for (int x = 0; x < labels.cols; ++x) {
      if (l[x] == 0) continue;
      double& g = gap[static_cast<std::size_t>(l[x])];
      g = std::min(g, static_cast<double>(d[x]));
    }
  }
  return gap;
}

}  // namespace

int odd_at_least(double size, int minimum) {
  int k = std::max(minimum, static_cast<int>(std::lround(size)));
  return k % 2 == 0 ? k + 1 : k;
}

void close_then_open(const cv::Mat& src, int close_k, int open_k, cv::Mat& scratch, cv::Mat& dst) {
  cv::morphologyEx(src, scratch, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(close_k, close_k)), cv::Point(-1, -1),
                   1, cv::BORDER_REPLICATE);
  cv::morphologyEx(scratch, dst, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_RECT, cv::Size(open_k, open_k)), cv::Point(-1, -1), 1,
                   cv::BORDER_REPLICATE);
}

void ridge_texture_energy(const cv::Mat& work, double period_w, const cv::Rect& excluded_w,
                          TextureImages& images) {
  // Difference of Gaussians centred on the ridge band: sigma_small passes the ridge period with gain
  // exp(-2 pi^2 0.15^2) = 0.64 while cutting pixel noise; sigma_large removes illumination and the
  // contact's mean step (gain 0.007 at the ridge period).
  gaussian(work, images.blur_small, 0.15 * period_w);
  gaussian(work, images.blur_large, 0.5 * period_w);
  cv::subtract(images.blur_small, images.blur_large, images.band);
  cv::absdiff(images.band, cv::Scalar::all(0.0), images.energy);  // |band| into the reused buffer
  if (excluded_w.area() > 0) images.energy(excluded_w).setTo(0.0f);
  // Closing spans half a period (the gap between the rectified peaks of a ridge and the next valley);
  // opening with a full period removes noise specks smaller than a ridge.
  const int close_k = odd_at_least(0.5 * period_w + 1.0, 3);
  const int open_k = odd_at_least(period_w, 3);
  close_then_open(images.energy, close_k, open_k, images.scratch, images.energy);
}

double noise_energy_per_sigma(double period_w) {
  // Wide enough for a few hundred independent closings and openings at the largest period the working
  // resolution gives (about 8 working pixels per period).
  const int side = std::max(128, static_cast<int>(std::ceil(24.0 * period_w)));
  cv::Mat noise(side, side, CV_32F);
  cv::RNG rng(0x7e57);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  TextureImages images;
  ridge_texture_energy(noise, period_w, cv::Rect(), images);
  return cv::mean(images.energy)[0];
}

void label_texture_regions(const cv::Mat& energy, float threshold, TextureRegions& regions) {
  cv::compare(energy, threshold, regions.mask, cv::CMP_GT);
  regions.count = cv::connectedComponentsWithStats(regions.mask, regions.labels, regions.stats,
                                                   regions.centroids, 8, CV_32S);
  regions.largest = 0;
  regions.largest_area = 0;
  for (int i = 1; i < regions.count; ++i) {
    const int area = regions.stats.at<int>(i, cv::CC_STAT_AREA);
    if (area > regions.largest_area) {
      regions.largest_area = area;
      regions.largest = i;
    }
  }
}

JoinedRegions join_to_largest(const TextureRegions& regions, double merge_fraction, double max_gap_w,
                              double mm2_per_working_px, double min_area_mm2) {
  JoinedRegions joined;
  joined.keep.assign(static_cast<std::size_t>(regions.count), 0);
  const std::vector<double> gap_w = gaps_to_region(regions.labels, regions.count, regions.largest);
  for (int i = 1; i < regions.count; ++i) {
    const int area = regions.stats.at<int>(i, cv::CC_STAT_AREA);
    if (i != regions.largest && area * mm2_per_working_px >= min_area_mm2) joined.multiple_blobs = true;
    if (i == regions.largest ||
        (area >= merge_fraction * regions.largest_area && gap_w[static_cast<std::size_t>(i)] <= max_gap_w)) {
      joined.keep[static_cast<std::size_t>(i)] = 1;
      const cv::Rect box(
          regions.stats.at<int>(i, cv::CC_STAT_LEFT), regions.stats.at<int>(i, cv::CC_STAT_TOP),
          regions.stats.at<int>(i, cv::CC_STAT_WIDTH), regions.stats.at<int>(i, cv::CC_STAT_HEIGHT));
      joined.box_w = joined.box_w.area() > 0 ? (joined.box_w | box) : box;
    }
  }
  return joined;
}

std::vector<cv::Point2d> kept_boundary(const cv::Mat& labels, const std::vector<std::uint8_t>& keep) {
  std::vector<cv::Point2d> boundary;
  for (int y = 0; y < labels.rows; ++y) {
    const int* row = labels.ptr<int>(y);
    int first = -1, last = -1;
    for (int x = 0; x < labels.cols; ++x) {
      if (keep[static_cast<std::size_t>(row[x])] != 0) {
        if (first < 0) first = x;
        last = x;
      }
    }
    if (first >= 0) {
      boundary.emplace_back(first, y);
      if (last != first) boundary.emplace_back(last, y);
    }
  }
  return boundary;
}

}  // namespace tirstrain::contact
