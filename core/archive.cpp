#include "core/archive.hpp"
#include <algorithm>

#include "core/error.hpp"
#include "core/version.hpp"

namespace tirstrain {
namespace {

// Which build wrote a snapshot: the version and the machine's word size (types written as raw bytes
// record their own sizes where they are read back, Archive::layout).
std::string build_stamp() {
  return std::string("tirstrain ") + kVersion + " " + std::to_string(sizeof(void*) * 8) + "-bit";
}

}  // namespace

Archive Archive::for_writing() {
  Archive a;
  std::string stamp = build_stamp();
  archive(a, stamp);
  return a;
}

Archive Archive::for_reading(std::vector<char> bytes) {
  Archive a;
  a.reading_ = true;
  a.bytes_ = std::move(bytes);
  std::string stamp;
  archive(a, stamp);
  if (stamp != build_stamp())
    throw Error("the checkpoint was written by another build (" + stamp + "), not this one (" +
                build_stamp() + ")");
  return a;
}

void Archive::expect_end() const {
  if (reading_ && cursor_ != bytes_.size())
    throw Error("the checkpoint holds " + std::to_string(bytes_.size() - cursor_) +
                " bytes more than was read back");
}

void Archive::raw(void* data, std::size_t count) {
  if (!reading_) {
    const char* p = static_cast<const char*>(data);
    bytes_.insert(bytes_.end(), p, p + count);
    return;
  }
  if (count > bytes_.size() - cursor_)
    throw Error("the checkpoint ends early: " + std::to_string(count) + " bytes asked for, " +
                std::to_string(bytes_.size() - cursor_) + " left");
  if (count) std::memcpy(data, bytes_.data() + cursor_, count);
  cursor_ += count;
}

void Archive::expect_items(std::uint64_t count, std::size_t bytes_each) const {
  if (!reading_) return;
  const std::size_t left = bytes_.size() - cursor_;
  if (count > left / std::max<std::size_t>(1, bytes_each))
    throw Error("the checkpoint is damaged: it counts " + std::to_string(count) + " items of at least " +
                std::to_string(std::max<std::size_t>(1, bytes_each)) + " bytes where " +
                std::to_string(left) + " bytes are left");
}

void Archive::layout(std::uint64_t size, const char* what) {
  std::uint64_t written = size;
  raw(&written, sizeof written);
  if (written != size)
    throw Error(std::string("the checkpoint's ") + what + " has another layout (" + std::to_string(written) +
                " bytes, this build " + std::to_string(size) + ")");
}

void archive(Archive& a, std::string& value) {
  std::uint64_t n = value.size();
  a.raw(&n, sizeof n);
  if (a.reading()) {
    a.expect_items(n, 1);
    value.resize(n);
  }
  if (n) a.raw(value.data(), n);
}

void archive(Archive& a, cv::Mat& value) {
  std::int32_t header[3] = {value.type(), value.rows, value.cols};
  if (value.dims > 2) throw Error("a checkpoint holds 2-D images only");
  a.raw(header, sizeof header);
  if (a.reading()) {
    value.release();
    if (header[1] > 0 && header[2] > 0) {
      if (header[0] < 0 || CV_MAT_DEPTH(header[0]) > CV_16F)
        throw Error("the checkpoint is damaged: an image of unknown type " + std::to_string(header[0]));
      a.expect_items(static_cast<std::uint64_t>(header[1]) * static_cast<std::uint64_t>(header[2]),
                     CV_ELEM_SIZE(header[0]));
      value.create(header[1], header[2], header[0]);
    }
  }
  if (value.empty()) return;
  const std::size_t row_bytes = value.cols * value.elemSize();
  for (int r = 0; r < value.rows; ++r) a.raw(value.ptr(r), row_bytes);
}

}  // namespace tirstrain
