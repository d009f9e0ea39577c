#pragma once
// Thin HDF5 reading/writing for tirstrain's result and truth files: N-d numeric datasets addressed by path
// ("/contact/area_mm2"), intermediate groups created on demand, chunked + deflate-compressed when large,
// text and number attributes. A file being written is built in memory and written to "<path>.partial",
// renamed on commit(), so an interrupted run never leaves a file that looks complete and a full disk is a
// plain error.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <H5Cpp.h>

namespace tirstrain {

class AtomicFile;

using H5Shape = std::vector<std::size_t>;

class H5Writer {
 public:
  explicit H5Writer(const std::string& path);
  ~H5Writer();
  H5Writer(const H5Writer&) = delete;
  H5Writer& operator=(const H5Writer&) = delete;

  void write(const std::string& name, std::span<const double> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const float> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int32_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int64_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int8_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::uint8_t> data, const H5Shape& shape);
  // Attribute on a group or dataset ("/" for the file); the object must exist (groups are created).
  void attribute(const std::string& object, const std::string& name, const std::string& value);
  void attribute(const std::string& object, const std::string& name, double value);
  void commit();

  const std::string& path() const { return path_; }

 private:
  template <typename T>
  void write_impl(const std::string& name, std::span<const T> data, const H5Shape& shape,
                  const H5::PredType& type);
  void ensure_parent_groups(const std::string& name);
  H5::H5Object& object(const std::string& name, H5::Group& group_holder, H5::DataSet& set_holder);

  std::string path_;
  std::string partial_path_;
  std::unique_ptr<AtomicFile> out_;  // the file on disk, written at commit()
  H5::H5File file_;
  bool committed_ = false;
};

class H5Reader {
 public:
  explicit H5Reader(const std::string& path);
  bool has(const std::string& name) const;
  H5Shape shape(const std::string& name) const;
  std::vector<double> read_doubles(const std::string& name, H5Shape* shape = nullptr) const;
  std::vector<std::int64_t> read_integers(const std::string& name, H5Shape* shape = nullptr) const;
  // One row along the first axis (one frame of an [N, ...] dataset), without reading the others; `shape`
  // gets the row's own shape (the dataset's without its first axis).
  std::vector<double> read_row_doubles(const std::string& name, std::size_t row,
                                       H5Shape* shape = nullptr) const;
  bool has_attribute(const std::string& object, const std::string& name) const;
  std::string attribute_text(const std::string& object, const std::string& name) const;
  double attribute_number(const std::string& object, const std::string& name) const;
  // Names of the members of a group.
  std::vector<std::string> members(const std::string& group) const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  H5::H5File file_;
};

}  // namespace tirstrain
