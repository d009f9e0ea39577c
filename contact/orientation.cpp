#include "contact/orientation.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

namespace tirstrain::contact {

OrientationField block_orientation(const cv::Mat& image, int scale, cv::Size full_size, int block_px,
                                   const cv::Mat& weight_mask) {
  CV_Assert(image.type() == CV_32FC1 && scale >= 1 && block_px >= 1);
  const int blocks_x = (full_size.width + block_px - 1) / block_px;
  const int blocks_y = (full_size.height + block_px - 1) / block_px;
  OrientationField field;
  field.orientation_rad = cv::Mat::zeros(blocks_y, blocks_x, CV_32FC1);
  field.coherence = cv::Mat::zeros(blocks_y, blocks_x, CV_32FC1);
  if (image.empty()) return field;

  const std::size_t cells = static_cast<std::size_t>(blocks_x) * static_cast<std::size_t>(blocks_y);
  std::vector<double> gxx(cells, 0.0), gyy(cells, 0.0), gxy(cells, 0.0), inside(cells, 0.0),
      total(cells, 0.0);
  // Block of each working column and row, from the full-resolution position of the pixel's centre.
  std::vector<int> block_of_x(static_cast<std::size_t>(image.cols)),
      block_of_y(static_cast<std::size_t>(image.rows));
  for (int x = 0; x < image.cols; ++x)
    block_of_x[static_cast<std::size_t>(x)] =
        std::min(blocks_x - 1, static_cast<int>((x + 0.5) * scale) / block_px);
  for (int y = 0; y < image.rows; ++y)
    block_of_y[static_cast<std::size_t>(y)] =
        std::min(blocks_y - 1, static_cast<int>((y + 0.5) * scale) / block_px);
  const bool use_mask = !weight_mask.empty();
  // Only the blocks that the mask touches can get a value: work on the whole blocks around its bounding box.
  cv::Rect roi(0, 0, image.cols, image.rows);
  if (use_mask) {
    const cv::Rect box = cv::boundingRect(weight_mask);
    if (box.area() == 0) return field;
    const auto whole_blocks = [](const std::vector<int>& block_of, int from, int to) {
      int lo = from, hi = to;
      while (lo > 0 && block_of[static_cast<std::size_t>(lo - 1)] == block_of[static_cast<std::size_t>(from)])
        --lo;
      while (hi + 1 < static_cast<int>(block_of.size()) &&
             block_of[static_cast<std::size_t>(hi + 1)] == block_of[static_cast<std::size_t>(to)])
        ++hi;
      return std::pair<int, int>(lo, hi);
    };
    const auto [x0, x1] = whole_blocks(block_of_x, box.x, box.x + box.width - 1);
    const auto [y0, y1] = whole_blocks(block_of_y, box.y, box.y + box.height - 1);
    roi = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
  }
  // Scharr's 3x3 derivative is nearly isotropic even at the 5-6 px ridge period of the working
  // resolution, where Sobel would bend oblique orientations by 1-2 degrees. On a sub-image OpenCV reads the
  // pixels around it, so the gradients equal those of the whole image.
  cv::Mat gx, gy;
  cv::Scharr(image(roi), gx, CV_32F, 1, 0);
  cv::Scharr(image(roi), gy, CV_32F, 0, 1);

  for (int y = roi.y; y < roi.y + roi.height; ++y) {
    const int by = block_of_y[static_cast<std::size_t>(y)];
    const float* px = gx.ptr<float>(y - roi.y) - roi.x;
    const float* py = gy.ptr<float>(y - roi.y) - roi.x;
    const std::uint8_t* m = use_mask ? weight_mask.ptr<std::uint8_t>(y) : nullptr;
    const std::size_t row_base = static_cast<std::size_t>(by) * static_cast<std::size_t>(blocks_x);
    for (int x = roi.x; x < roi.x + roi.width; ++x) {
      const std::size_t cell = row_base + static_cast<std::size_t>(block_of_x[static_cast<std::size_t>(x)]);
      total[cell] += 1.0;
      if (m != nullptr && m[x] == 0) continue;
      inside[cell] += 1.0;
      const double a = px[x], b = py[x];
      gxx[cell] += a * a;
      gyy[cell] += b * b;
      gxy[cell] += a * b;
    }
  }
  for (int by = 0; by < blocks_y; ++by) {
    auto* orientation = field.orientation_rad.ptr<float>(by);
    auto* coherence = field.coherence.ptr<float>(by);
    for (int bx = 0; bx < blocks_x; ++bx) {
      const std::size_t cell =
          static_cast<std::size_t>(by) * static_cast<std::size_t>(blocks_x) + static_cast<std::size_t>(bx);
      if (total[cell] <= 0.0 || inside[cell] < 0.5 * total[cell]) continue;
      const double diff = gxx[cell] - gyy[cell], sum = gxx[cell] + gyy[cell];
      if (!(sum > 0.0)) continue;
      const double gradient_angle = 0.5 * std::atan2(2.0 * gxy[cell], diff);
      double ridge = gradient_angle + std::numbers::pi / 2.0;
      if (ridge >= std::numbers::pi) ridge -= std::numbers::pi;
      if (ridge < 0.0) ridge += std::numbers::pi;
      orientation[bx] = static_cast<float>(ridge);
      coherence[bx] = static_cast<float>(std::sqrt(diff * diff + 4.0 * gxy[cell] * gxy[cell]) / sum);
    }
  }
  return field;
}

}  // namespace tirstrain::contact
