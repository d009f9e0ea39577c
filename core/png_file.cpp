#include "core/png_file.hpp"

#include <opencv2/imgcodecs.hpp>

#include <string_view>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/error.hpp"

namespace tirstrain {

void write_png_file(const std::string& path, const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  if (image.empty() || !cv::imencode(".png", image, bytes))
    throw Error("cannot encode the PNG image", {.file = path});
  AtomicFile file(path);
  file.append(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  file.commit();
}

}  // namespace tirstrain
