#include "core/image_noise.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>

namespace tirstrain {

double immerkaer_noise_sigma(const cv::Mat& image, const cv::Mat& mask) {
  CV_Assert(image.type() == CV_32F &&
            (mask.empty() || (mask.type() == CV_8U && mask.size() == image.size())));
  if (image.rows < 3 || image.cols < 3 || (!mask.empty() && cv::countNonZero(mask) == 0)) return 0.0;
  const cv::Matx33f kernel(1, -2, 1, -2, 4, -2, 1, -2, 1);
  cv::Mat response;
  cv::filter2D(image, response, CV_32F, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
  const double mean_abs = cv::mean(cv::abs(response), mask)[0];
  return mean_abs * std::sqrt(0.5 * std::numbers::pi) / 6.0;
}

}  // namespace tirstrain
