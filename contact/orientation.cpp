#include "contact/orientation.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

namespace tirstrain::contact {

namespace {

// The block of each working column (or row), from the full-resolution position of the pixel's centre.
std::vector<int> blocks_of(int pixels, int scale, int block_px, int blocks) {
  std::vector<int> block_of(static_cast<std::size_t>(pixels));
  for (int i = 0; i < pixels; ++i)
    block_of[static_cast<std::size_t>(i)] =
        std::min(blocks - 1, static_cast<int>((i + 0.5) * scale) / block_px);
  return block_of;
}

// Only the blocks that the mask touches can get a value: the whole blocks around its bounding box (empty
// when the mask is).
cv::Rect masked_blocks_roi(const cv::Mat& weight_mask, const std::vector<int>& block_of_x,
                           const std::vector<int>& block_of_y) {
  const cv::Rect box = cv::boundingRect(weight_mask);
  if (box.area() == 0) return {};
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
  return {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
}

// Per block: the summed squared-gradient tensor of its pixels inside the mask, and its pixel counts.
struct BlockTensors {
  std::vector<double> gxx, gyy, gxy, inside, total;
  explicit BlockTensors(std::size_t cells)
      : gxx(cells, 0.0), gyy(cells, 0.0), gxy(cells, 0.0), inside(cells, 0.0), total(cells, 0.0) {}
};

// The ridge direction (perpendicular to the tensor's principal axis) and the coherence of every block at
// least half inside the mask.
void orientation_from_tensors(const BlockTensors& t, OrientationField& field) {
  const int blocks_x = field.orientation_rad.cols;
  for (int by = 0; by < field.orientation_rad.rows; ++by) {
    auto* orientation = field.orientation_rad.ptr<float>(by);
    auto* coherence = field.coherence.ptr<float>(by);
    for (int bx = 0; bx < blocks_x; ++bx) {
      const std::size_t cell =
          static_cast<std::size_t>(by) * static_cast<std::size_t>(blocks_x) + static_cast<std::size_t>(bx);
      if (t.total[cell] <= 0.0 || t.inside[cell] < 0.5 * t.total[cell]) continue;
      const double diff = t.gxx[cell] - t.gyy[cell], sum = t.gxx[cell] + t.gyy[cell];
      if (!(sum > 0.0)) continue;
      const double gradient_angle = 0.5 * std::atan2(2.0 * t.gxy[cell], diff);
      double ridge = gradient_angle + std::numbers::pi / 2.0;
      if (ridge >= std::numbers::pi) ridge -= std::numbers::pi;
      if (ridge < 0.0) ridge += std::numbers::pi;
      orientation[bx] = static_cast<float>(ridge);
      coherence[bx] = static_cast<float>(std::sqrt(diff * diff + 4.0 * t.gxy[cell] * t.gxy[cell]) / sum);
    }
  }
}

}  // namespace

OrientationField block_orientation(const cv::Mat& image, int scale, cv::Size full_size, int block_px,
                                   const cv::Mat& weight_mask) {
  CV_Assert(image.type() == CV_32FC1 && scale >= 1 && block_px >= 1);
  const int blocks_x = (full_size.width + block_px - 1) / block_px;
  const int blocks_y = (full_size.height + block_px - 1) / block_px;
  OrientationField field;
  field.orientation_rad = cv::Mat::zeros(blocks_y, blocks_x, CV_32FC1);
  field.coherence = cv::Mat::zeros(blocks_y, blocks_x, CV_32FC1);
  if (image.empty()) return field;

  const std::vector<int> block_of_x = blocks_of(image.cols, scale, block_px, blocks_x);
  const std::vector<int> block_of_y = blocks_of(image.rows, scale, block_px, blocks_y);
  const bool use_mask = !weight_mask.empty();
  const cv::Rect roi = use_mask ? masked_blocks_roi(weight_mask, block_of_x, block_of_y)
                                : cv::Rect(0, 0, image.cols, image.rows);
  if (roi.area() == 0) return field;
  // Scharr's 3x3 derivative is nearly isotropic even at the 5-6 px ridge period of the working
  // resolution, where Sobel would bend oblique orientations by 1-2 degrees. On a sub-image OpenCV reads the
  // pixels around it, so the gradients equal those of the whole image.
  cv::Mat gx, gy;
  cv::Scharr(image(roi), gx, CV_32F, 1, 0);
  cv::Scharr(image(roi), gy, CV_32F, 0, 1);

  BlockTensors t(static_cast<std::size_t>(blocks_x) * static_cast<std::size_t>(blocks_y));
  for (int y = roi.y; y < roi.y + roi.height; ++y) {
    const int by = block_of_y[static_cast<std::size_t>(y)];
    const float* px = gx.ptr<float>(y - roi.y) - roi.x;
    const float* py = gy.ptr<float>(y - roi.y) - roi.x;
    const std::uint8_t* m = use_mask ? weight_mask.ptr<std::uint8_t>(y) : nullptr;
    const std::size_t row_base = static_cast<std::size_t>(by) * static_cast<std::size_t>(blocks_x);
    for (int x = roi.x; x < roi.x + roi.width; ++x) {
      const std::size_t cell = row_base + static_cast<std::size_t>(block_of_x[static_cast<std::size_t>(x)]);
      t.total[cell] += 1.0;
      if (m != nullptr && m[x] == 0) continue;
      t.inside[cell] += 1.0;
      const double a = px[x], b = py[x];
      t.gxx[cell] += a * a;
      t.gyy[cell] += b * b;
      t.gxy[cell] += a * b;
    }
  }
  orientation_from_tensors(t, field);
  return field;
}

}  // namespace tirstrain::contact
