#include "flow/mask_erosion.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace tirstrain::flow {

void erode_ellipse(const cv::Mat& mask, int radius_px, cv::Mat& out) {
  CV_Assert(mask.type() == CV_8U && radius_px >= 0 && radius_px <= 250);
  out.create(mask.size(), CV_8U);
  CV_Assert(out.data != mask.data);
  if (radius_px == 0) {
    mask.copyTo(out);
    return;
  }
  const int r = radius_px, rows = mask.rows, cols = mask.cols;
  // The element's row half-widths, read off OpenCV's own element so that the two agree exactly.
  const cv::Mat element = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
  std::vector<int> half(static_cast<std::size_t>(2 * r + 1), -1);  // −1: an empty element row
  for (int i = 0; i <= 2 * r; ++i) {
    const std::uint8_t* e = element.ptr<std::uint8_t>(i);
    int first = -1, last = -1;
    for (int j = 0; j <= 2 * r; ++j)
      if (e[j]) {
        if (first < 0) first = j;
        last = j;
      }
    if (first >= 0) {
      CV_Assert(r - first == last - r);  // symmetric about the anchor
      half[static_cast<std::size_t>(i)] = r - first;
    }
  }
  // reach(y, x) = min(L, R), L and R the runs of set pixels in row y from x leftwards and rightwards (x
  // included; 0 where x is unset), capped at r + 2: the row's pixels [x − w, x + w] are all set iff
  // reach ≥ w + 1.
  const int cap = r + 1;
  cv::Mat reach(rows, cols, CV_8U);
  std::vector<int> left(static_cast<std::size_t>(cols));
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    std::uint8_t* out_row = reach.ptr<std::uint8_t>(y);
    int run = 0;
    for (int x = 0; x < cols; ++x) {
      run = m[x] ? std::min(run + 1, cap + 1) : 0;
      left[static_cast<std::size_t>(x)] = run;
    }
    run = 0;
    for (int x = cols - 1; x >= 0; --x) {
      run = m[x] ? std::min(run + 1, cap + 1) : 0;
      // Set pixels in [x − (L−1), x + (R−1)]: half-width min(L, R) − 1 fits; stored +1.
      out_row[x] = static_cast<std::uint8_t>(std::min(left[static_cast<std::size_t>(x)], run));
    }
  }
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(cols));
  for (int y = 0; y < rows; ++y) {
    std::fill(keep.begin(), keep.end(), std::uint8_t{1});
    bool any = true;
    for (int i = 0; i <= 2 * r && any; ++i) {
      const int w = half[static_cast<std::size_t>(i)];
      if (w < 0) continue;
      const int yy = y + i - r;
      if (yy < 0 || yy >= rows) {  // the border is 0
        any = false;
        break;
      }
      const std::uint8_t* row = reach.ptr<std::uint8_t>(yy);
      const auto need = static_cast<std::uint8_t>(w + 1);
      std::uint8_t* k = keep.data();
      for (int x = 0; x < cols; ++x) k[x] = static_cast<std::uint8_t>(k[x] & (row[x] >= need ? 1 : 0));
    }
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    if (!any) {
      std::fill(o, o + cols, std::uint8_t{0});
      continue;
    }
    for (int x = 0; x < cols; ++x) o[x] = keep[static_cast<std::size_t>(x)] ? m[x] : std::uint8_t{0};
  }
}

}  // namespace tirstrain::flow
