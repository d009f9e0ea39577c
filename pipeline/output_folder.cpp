#include "pipeline/output_folder.hpp"

#include <algorithm>
#include <filesystem>

#include "core/atomic_output.hpp"
#include "core/error.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

bool is_camera_uri(const std::string& input) {
  for (const char* scheme : {"aravis:", "v4l2:", "libcamera:"})
    if (input.rfind(scheme, 0) == 0) return true;
  return false;
}

}  // namespace

const std::vector<std::string>& process_output_names() {
  static const std::vector<std::string> names = {"result.h5", "frames.csv", "summary.json", "overlay.mp4",
                                                 "overlay"};
  return names;
}

std::vector<std::string> input_locations(const std::string& input) {
  if (input.empty() || is_camera_uri(input)) return {};
  const std::string path = input.rfind("file:", 0) == 0 ? input.substr(5) : input;
  if (path.find_first_of("%*?[") != std::string::npos) {
    const fs::path parent = fs::path(path).parent_path();
    return {parent.empty() ? std::string(".") : parent.string()};
  }
  return {path};
}

void check_output_folder(const std::string& out_dir, const std::vector<std::string>& inputs) {
  for (const std::string& input : inputs)
    if (path_is_within(input, out_dir))
      throw Error("the output folder " + std::string(path_is_within(out_dir, input) ? "is" : "contains") +
                      " the input " + input +
                      "; it is replaced as a whole when the run completes, so give a folder of its own",
                  {.file = out_dir, .key = "--out"});
  check_replaceable_output(out_dir, process_output_names(), "process");
}

}  // namespace tirstrain::pipeline
