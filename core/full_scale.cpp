#include "core/full_scale.hpp"

namespace tirstrain {

double full_scale_of(const cv::Mat& image) {
  switch (image.depth()) {
    case CV_8U:
      return 255.0;
    case CV_16U: {
      double max_value = 0.0;
      cv::minMaxLoc(image, nullptr, &max_value);
      for (double scale : {1023.0, 4095.0, 16383.0})
        if (max_value <= scale) return scale;
      return 65535.0;
    }
    default:
      return 1.0;
  }
}

}  // namespace tirstrain
