// Checkpoint snapshots read back value by value: a damaged count is refused as an Error before anything is
// allocated for it (a huge count once surfaced as std::bad_alloc from FeatureTracker::restore).
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "core/archive.hpp"
#include "core/error.hpp"

namespace tirstrain {
namespace {

// What is written: a vector of three doubles, a string and a 4 x 5 float image, each after its count or
// header. `patch` overwrites bytes of the snapshot at `at` (counted from the end of the build stamp).
template <typename Patch>
std::string read_back(Patch patch) {
  std::vector<double> numbers = {1.0, 2.0, 3.0};
  std::string text = "tirstrain";
  cv::Mat image(4, 5, CV_32F, cv::Scalar(0.5));
  Archive out = Archive::for_writing();
  const std::size_t start = out.bytes().size();
  out(numbers, text, image);
  std::vector<char> bytes = out.bytes();
  patch(bytes, start);
  try {
    Archive in = Archive::for_reading(bytes);
    std::vector<double> n2;
    std::string t2;
    cv::Mat i2;
    in(n2, t2, i2);
    in.expect_end();
    return n2.size() == 3 && t2 == text && i2.size() == image.size() ? "read" : "misread";
  } catch (const Error& e) {
    return e.what();
  }
}

void put_u64(std::vector<char>& bytes, std::size_t at, std::uint64_t value) {
  std::memcpy(bytes.data() + at, &value, sizeof value);
}

TEST(Archive, ADamagedCountIsAnErrorNotAnAllocation) {
  EXPECT_EQ(read_back([](std::vector<char>&, std::size_t) {}), "read");
  // The vector's count, then the string's (after 8 + 3 x 8 bytes), then the image's rows and columns.
  for (const std::uint64_t count : {std::uint64_t{1} << 60, ~std::uint64_t{0}, std::uint64_t{1} << 40}) {
    EXPECT_NE(read_back([&](std::vector<char>& b, std::size_t s) {
                put_u64(b, s, count);
              }).find("the checkpoint is damaged"),
              std::string::npos)
        << count;
    EXPECT_NE(read_back([&](std::vector<char>& b, std::size_t s) {
                put_u64(b, s + 32, count);
              }).find("the checkpoint is damaged"),
              std::string::npos)
        << count;
  }
  const std::string image = read_back([](std::vector<char>& b, std::size_t s) {
    const std::int32_t header[3] = {CV_32F, 1 << 30, 1 << 30};
    std::memcpy(b.data() + s + 32 + 8 + 9, header, sizeof header);
  });
  EXPECT_NE(image.find("the checkpoint is damaged"), std::string::npos) << image;
}

}  // namespace
}  // namespace tirstrain
