#pragma once
// What every libFuzzer target here needs: a private scratch folder for the process and a way to put the
// fuzzer's bytes into a file there (the readers under test take paths, as the CLI gives them).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace tirstrain::fuzz {

inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    const char* base = std::getenv("TMPDIR");
    std::string pattern = std::string(base != nullptr ? base : "/tmp") + "/tirstrain-fuzz-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) std::abort();
    return std::filesystem::path(pattern);
  }();
  return dir;
}

inline std::string write_bytes(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path path = scratch() / name;
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path.string();
}

// A small valid 8-bit frame, written once, so that a folder always has a decodable neighbour.
inline void write_valid_frame(const std::string& name) {
  const std::filesystem::path path = scratch() / name;
  if (std::filesystem::exists(path)) return;
  std::filesystem::create_directories(path.parent_path());
  cv::imwrite(path.string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(90)));
}

}  // namespace tirstrain::fuzz
