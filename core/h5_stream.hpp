#pragma once
// A result file written to disk while it grows, so that a long recording needs memory for one frame's
// results rather than for all of them. Per-frame datasets are extendible along the frame axis (and along
// a second, growing axis: tracks or triangles, which are created as the trial goes), chunked for both
// one-frame reads and one-track-through-time reads, shuffled and deflate-compressed.
//
// The file is written as "<path>.partial" and renamed to <path> by commit(); until then its root attribute
// `complete` is 0, and mark_flushed() makes the frames written so far readable by another process (the file
// is flushed, so a run killed afterwards leaves them). Every HDF5 failure becomes an Error naming the file
// and, where it is the disk (full, file-size limit, read-only), the cause.
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "core/h5_file.hpp"

namespace tirstrain {

// How a per-frame dataset is stored.
enum class H5Precision {
  kNative,  // as given (double stays double)
  kFloat32  // doubles stored as 32-bit floats (7 significant digits): positions, strains, maps
};

class H5Stream {
 public:
  explicit H5Stream(const std::string& path);
  ~H5Stream();
  H5Stream(const H5Stream&) = delete;
  H5Stream& operator=(const H5Stream&) = delete;

  // Frame row `row` of the per-frame dataset `name`, whose rows have shape `row_shape` ({} for one number
  // per frame). Created on first use with `fill` in every cell never written; extended to hold the row,
  // and along the row's first axis when this row is wider than earlier ones (tracks born, triangles added).
  // A row written again is overwritten.
  void write_row(const std::string& name, std::size_t row, std::span<const double> data,
                 const H5Shape& row_shape, double fill, H5Precision precision = H5Precision::kNative);
  void write_row(const std::string& name, std::size_t row, std::span<const float> data,
                 const H5Shape& row_shape, float fill);
  void write_row(const std::string& name, std::size_t row, std::span<const std::int64_t> data,
                 const H5Shape& row_shape, std::int64_t fill);
  void write_row(const std::string& name, std::size_t row, std::span<const std::int32_t> data,
                 const H5Shape& row_shape, std::int32_t fill);
  void write_row(const std::string& name, std::size_t row, std::span<const std::int8_t> data,
                 const H5Shape& row_shape, std::int8_t fill);
  void write_row(const std::string& name, std::size_t row, std::span<const std::uint8_t> data,
                 const H5Shape& row_shape, std::uint8_t fill);

  // The same row given as the values of some columns of its first axis only (`row_shape[0]` wide; the
  // columns in any order, each with product(row_shape[1:]) values), `fill` everywhere else: a trial's live
  // tracks or triangles, among the many more it has created, at a cost that follows the live ones.
  void write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                     std::span<const double> values, const H5Shape& row_shape, double fill,
                     H5Precision precision = H5Precision::kNative);
  void write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                     std::span<const float> values, const H5Shape& row_shape, float fill);
  void write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                     std::span<const std::int8_t> values, const H5Shape& row_shape, std::int8_t fill);
  void write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                     std::span<const std::uint8_t> values, const H5Shape& row_shape, std::uint8_t fill);

  // A box of an existing dataset, as doubles, and written back (no extension): one track through time.
  std::vector<double> read_block(const std::string& name, const H5Shape& offset, const H5Shape& count) const;
  void write_block(const std::string& name, const H5Shape& offset, const H5Shape& count,
                   std::span<const double> data);
  bool has(const std::string& name) const;
  H5Shape shape(const std::string& name) const;

  // A whole dataset written once (not per frame), as H5Writer::write.
  void write(const std::string& name, std::span<const double> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int32_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int8_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const float> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::int64_t> data, const H5Shape& shape);
  void write(const std::string& name, std::span<const std::uint8_t> data, const H5Shape& shape);
  // Attribute on a group or dataset ("/" for the file); replaces an earlier value of the same name.
  void attribute(const std::string& object, const std::string& name, const std::string& value);
  void attribute(const std::string& object, const std::string& name, double value);

  // Rows 0 … rows − 1 of every per-frame dataset of the result file `source` (another run's, interrupted),
  // copied as stored (type, chunks, fill, compression): an interrupted run continues into a fresh file rather
  // than into one whose last writes were cut off. Datasets written once, and the attributes, are not copied.
  void copy_rows_from(const std::string& source, std::size_t rows);

  // Flushes what is written so far to disk, with `frames_written` in the root attribute of that name: a run
  // killed later leaves a file readable up to there.
  void mark_flushed(std::size_t frames_written);
  // Sets `complete` to 1, closes the file and renames it to its final name.
  void commit();

  const std::string& path() const { return path_; }
  const std::string& partial_path() const { return partial_path_; }

 private:
  template <typename T>
  void write_row_impl(const std::string& name, std::size_t row, std::span<const T> data,
                      const H5Shape& row_shape, T fill, std::int64_t memory_type, std::int64_t file_type);
  template <typename T>
  void write_columns_impl(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                          std::span<const T> values, const H5Shape& row_shape, T fill,
                          std::int64_t memory_type, std::int64_t file_type);
  std::int64_t prepare_row(const std::string& name, std::size_t row, const H5Shape& row_shape,
                           const void* fill, std::int64_t memory_type, std::int64_t file_type, H5Shape& dims);
  bool first_write_of(const std::string& name, std::size_t row);
  void write_runs(const std::string& name, std::int64_t set, std::size_t row, const H5Shape& dims,
                  const H5Shape& row_shape, std::span<const std::size_t> run_first,
                  std::span<const std::size_t> run_count, const void* memory, std::int64_t memory_type);
  template <typename T>
  void write_whole(const std::string& name, std::span<const T> data, const H5Shape& shape,
                   std::int64_t memory_type);
  std::int64_t open_or_create(const std::string& name, const H5Shape& row_shape, const void* fill,
                              std::int64_t memory_type, std::int64_t file_type);
  std::int64_t open_with_cache(const std::string& name, std::size_t slots, std::size_t cache_bytes) const;
  std::int64_t fit_cache_to_row(const std::string& name, std::int64_t set, std::size_t columns_written,
                                std::size_t row_width);
  void ensure_parent_groups(const std::string& name);
  void close_sets();
  void discard() const;
  [[noreturn]] void fail(const std::string& what, const std::string& name) const;

  std::string path_;
  std::string partial_path_;
  mutable std::int64_t file_ = -1;  // hid_t; -1 once closed or discarded
  // Per-frame datasets kept open, so their chunk caches fill a chunk before it is compressed and written.
  mutable std::map<std::string, std::int64_t> sets_;
  // What each created dataset's chunk cache must hold: one chunk when a row fills its chunks whole
  // (chunk_width 0), else every chunk across the row, partly filled until their block of frames completes.
  struct ChunkCache {
    std::size_t chunk_bytes = 0;
    std::size_t chunk_width = 0;   // elements of the growing axis per chunk; 0: one frame per chunk
    std::size_t bytes = 0;         // the cache's size now
    std::size_t slots = 0;         // the cache's hash slots now (a prime)
    std::size_t rows_written = 0;  // one past the highest row written: a row below it may be a rewrite
    std::size_t needed(std::size_t row_width) const {
      return chunk_width == 0 ? chunk_bytes : (row_width + chunk_width - 1) / chunk_width * chunk_bytes;
    }
    // Slots for a row `row_width` wide: one per chunk column, so that no chunk of the row evicts another.
    std::size_t slots_needed(std::size_t row_width) const;
  };
  std::map<std::string, ChunkCache> caches_;
  // The last row written by columns, per dataset, at full width (bytes of the memory type); only the
  // columns written then need resetting to the fill for the next row.
  struct RowBuffer {
    std::vector<unsigned char> bytes;
    std::vector<std::size_t> columns;
  };
  std::map<std::string, RowBuffer> row_buffers_;
  bool committed_ = false;
};

}  // namespace tirstrain
