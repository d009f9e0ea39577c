#include "flow/shi_tomasi.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>

namespace tirstrain::flow {

void min_eigenvalue_map(const cv::Mat& region, int block_px, cv::Mat& out, cv::Mat& scratch) {
  CV_Assert(block_px >= 1);
  out.create(region.size(), CV_32F);
  // 32 rows keep each call's temporaries (gradients and tensor, 20 bytes a pixel) under 0.5 MB at 640 px.
  constexpr int kBandRows = 32;
  const int half = block_px / 2;
  for (int y0 = 0; y0 < region.rows; y0 += kBandRows) {
    const int y1 = std::min(region.rows, y0 + kBandRows);
    const int a = std::max(0, y0 - half), b = std::min(region.rows, y1 + half);
    cv::cornerMinEigenVal(region.rowRange(a, b), scratch, block_px, 3);
    scratch.rowRange(y0 - a, y1 - a).copyTo(out.rowRange(y0, y1));
  }
}

}  // namespace tirstrain::flow
