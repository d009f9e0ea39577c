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

// Leftovers of an interrupted writer inside the folder (a pre-staging run's partial files).
bool is_leftover(const std::string& name) {
  const auto ends_with = [&](const std::string& tail) {
    return name.size() >= tail.size() && name.compare(name.size() - tail.size(), tail.size(), tail) == 0;
  };
  return ends_with(".partial") || ends_with(".partial.mp4") || name == ".tirstrain-write-probe";
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
  std::error_code ec;
  if (!fs::is_directory(out_dir, ec)) return;
  const auto& known = process_output_names();
  for (const auto& entry : fs::directory_iterator(out_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (std::find(known.begin(), known.end(), name) != known.end() || is_leftover(name)) continue;
    throw Error("the output folder holds '" + name +
                    "', which tirstrain process does not write; the folder is replaced as a whole when the "
                    "run completes, so give a new or empty folder",
                {.file = out_dir, .key = "--out"});
  }
}

}  // namespace tirstrain::pipeline
