#pragma once
// A snapshot of in-memory state as bytes (a checkpoint), written and read back value by value in the same
// order by the same build: what `process` needs to continue an interrupted run exactly where it stopped.
// Not a file format: nothing is portable across builds, so a snapshot records the build that wrote it and
// is refused by any other.
//
// A type takes part through a member `void archive(Archive&)` listing its state with `a(x_, y_, ...)`, or
// by being trivially copyable (its bytes are its state). The same member both writes and reads.
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <cstring>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace tirstrain {

class Archive {
 public:
  // An empty snapshot to write into, or one to read back (throws Error if another build wrote it).
  static Archive for_writing();
  static Archive for_reading(std::vector<char> bytes);

  bool reading() const { return reading_; }
  // The snapshot written so far; throws Error if bytes are left unread after reading.
  const std::vector<char>& bytes() const { return bytes_; }
  void expect_end() const;

  // Writes or reads `count` raw bytes (throws Error when a read runs past the end).
  void raw(void* data, std::size_t count);
  // Writes a type's size, or checks it against the one written (throws Error naming `what`): before state
  // copied as raw bytes, so that a snapshot of another layout is refused rather than misread.
  void layout(std::uint64_t size, const char* what);
  // Reading: throws Error when `count` items of at least `bytes_each` bytes cannot fit in what is left, so
  // that a damaged count is refused before anything is allocated for it.
  void expect_items(std::uint64_t count, std::size_t bytes_each) const;

  template <typename... T>
  void operator()(T&... values);

 private:
  Archive() = default;
  bool reading_ = false;
  std::vector<char> bytes_;
  std::size_t cursor_ = 0;
};

template <typename T>
concept ArchivedByMember = requires(T& value, Archive& a) {
  value.archive(a);
};

template <typename T>
void archive(Archive& a, T& value) {
  if constexpr (ArchivedByMember<T>) {
    value.archive(a);
  } else {
    static_assert(std::is_trivially_copyable_v<T>, "give the type an archive(Archive&) member");
    a.raw(&value, sizeof value);
  }
}

void archive(Archive& a, std::string& value);

template <typename T, int M, int N>
void archive(Archive& a, cv::Matx<T, M, N>& value) {
  a.raw(value.val, sizeof value.val);
}
template <typename T, int N>
void archive(Archive& a, cv::Vec<T, N>& value) {
  a.raw(value.val, sizeof value.val);
}
// Type, size and pixels (a continuous copy); an empty Mat stays empty.
void archive(Archive& a, cv::Mat& value);

template <typename T>
void archive(Archive& a, std::vector<T>& values) {
  std::uint64_t n = values.size();
  a.raw(&n, sizeof n);
  if (a.reading()) {
    a.expect_items(n, std::is_trivially_copyable_v<T> && !ArchivedByMember<T> ? sizeof(T) : 1);
    values.resize(n);
  }
  if constexpr (std::is_trivially_copyable_v<T> && !ArchivedByMember<T>) {
    if (n) a.raw(values.data(), n * sizeof(T));
  } else {
    for (T& v : values) archive(a, v);
  }
}

template <typename T>
void archive(Archive& a, std::deque<T>& values) {
  std::uint64_t n = values.size();
  a.raw(&n, sizeof n);
  if (a.reading()) {
    a.expect_items(n, 1);
    values.resize(n);
  }
  for (T& v : values) archive(a, v);
}

template <typename T>
void archive(Archive& a, std::optional<T>& value) {
  bool present = value.has_value();
  a.raw(&present, sizeof present);
  if (a.reading()) {
    value.reset();
    if (present) value.emplace();
  }
  if (present) archive(a, *value);
}

template <typename T>
void archive(Archive& a, std::unique_ptr<T>& value) {
  bool present = value != nullptr;
  a.raw(&present, sizeof present);
  if (a.reading()) value = present ? std::make_unique<T>() : nullptr;
  if (present) archive(a, *value);
}

template <typename K, typename V>
void archive(Archive& a, std::map<K, V>& values) {
  std::uint64_t n = values.size();
  a.raw(&n, sizeof n);
  if (a.reading()) {
    values.clear();
    for (std::uint64_t i = 0; i < n; ++i) {
      K key{};
      V value{};
      archive(a, key);
      archive(a, value);
      values.emplace(std::move(key), std::move(value));
    }
    return;
  }
  for (auto& [key, value] : values) {
    K k = key;
    archive(a, k);
    archive(a, value);
  }
}

template <typename T, std::size_t N>
requires(!std::is_trivially_copyable_v<T>) void archive(Archive& a, std::array<T, N>& values) {
  for (T& v : values) archive(a, v);
}

template <typename... T>
void Archive::operator()(T&... values) {
  (archive(*this, values), ...);
}

}  // namespace tirstrain
