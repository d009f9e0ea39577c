#include "core/h5_stream.hpp"

#include <hdf5.h>
#include <unistd.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <numeric>
#include <type_traits>

#include "core/atomic_output.hpp"
#include "core/error.hpp"

namespace tirstrain {
namespace {

static_assert(std::is_same_v<hid_t, std::int64_t>, "hid_t is a 64-bit id in the HDF5 versions supported");

// One chunk holds at most this many bytes of a per-frame dataset: large enough that deflate works well,
// small enough that the chunks being filled (one per 64 tracks or triangles: 74 for 4700 triangles) all stay
// in the chunk cache, so none is written half full and read back.
constexpr std::size_t kChunkBytes = 16 * 1024;
// Deflate's level after the shuffle filter: with the bytes of each significance grouped, the fastest level
// leaves result.h5 about 2 % larger than level 4 while the compression, a tenth of `process`'s instructions
// at level 4, takes a third fewer.
constexpr unsigned kDeflateLevel = 1;
constexpr std::size_t kChunkWidth = 64;
constexpr std::size_t kMaxFramesPerChunk = 1024;
// Chunk cache per open dataset: room for the partly filled chunks of one block of frames across the row
// (ChunkCache), so each chunk is compressed and written once, when its block of frames is complete. A
// fixed large cache would also keep finished chunks until it is full: about 2 MB per dataset, 90 MB for a
// result's 45 per-frame datasets, for nothing.
//
// The cache finds a chunk by its index modulo the number of hash slots, and a chunk whose slot is taken
// evicts the one there. A row's chunks in one block of frames have consecutive indices, so with at least
// as many slots as the row has chunk columns none of them evicts another; with fewer (a long trial's
// triangles outgrow 521 chunk columns after a few thousand frames) chunks still being filled are written
// half full, read back and compressed again, at a cost that grows with the recording.
constexpr std::size_t kMinChunkCacheSlots = 521;
// A dataset opened to be read back (temporal smoothing reads one track through time).
constexpr std::size_t kReadCacheBytes = 1u << 20;

std::size_t product(const H5Shape& shape, std::size_t from = 0) {
  std::size_t n = 1;
  for (std::size_t i = from; i < shape.size(); ++i) n *= shape[i];
  return n;
}

// Errors that say the disk (or the process's file-size limit) refused the write, as errno left them.
bool is_storage_errno(int code) {
  return code == ENOSPC || code == EFBIG || code == EDQUOT || code == EROFS || code == EIO;
}

// Elements [first, first + count) of a row's first axis.
struct ColumnRun {
  std::size_t first = 0, count = 0;
};

// Whether v equals the fill value; NaN counts as equal to a NaN fill.
template <typename T>
bool same_value(T v, T fill) {
  if constexpr (std::is_floating_point_v<T>)
    if (std::isnan(fill)) return std::isnan(v);
  return v == fill;
}

// Runs of whole chunk columns (chunk_width elements of the row's first axis, with all their trailing
// values) in which some value differs from `fill`; NaN counts as equal to a NaN fill.
template <typename T>
std::vector<ColumnRun> columns_not_fill(std::span<const T> data, std::size_t width, std::size_t chunk_width,
                                        T fill) {
  const std::size_t per_element = width == 0 ? 0 : data.size() / width;
  const auto is_fill = [fill](T v) { return same_value(v, fill); };
  std::vector<ColumnRun> runs;
  for (std::size_t first = 0; first < width; first += chunk_width) {
    const std::size_t end = std::min(width, first + chunk_width);
    if (std::all_of(data.begin() + static_cast<std::ptrdiff_t>(first * per_element),
                    data.begin() + static_cast<std::ptrdiff_t>(end * per_element), is_fill))
      continue;
    if (!runs.empty() && runs.back().first + runs.back().count == first)
      runs.back().count += end - first;
    else
      runs.push_back({first, end - first});
  }
  return runs;
}

// How many columns the runs cover.
std::size_t columns_in(const std::vector<ColumnRun>& runs) {
  std::size_t columns = 0;
  for (const ColumnRun& r : runs) columns += r.count;
  return columns;
}

// The runs of whole chunk columns covering the blocks (chunk column numbers, in any order, repeated).
std::vector<ColumnRun> runs_of_blocks(std::vector<std::size_t> blocks, std::size_t chunk_width,
                                      std::size_t row_width) {
  std::sort(blocks.begin(), blocks.end());
  blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
  std::vector<ColumnRun> runs;
  for (const std::size_t block : blocks) {
    const std::size_t first = block * chunk_width, count = std::min(chunk_width, row_width - first);
    if (!runs.empty() && runs.back().first + runs.back().count == first)
      runs.back().count += count;
    else
      runs.push_back({first, count});
  }
  return runs;
}

// Runs as the first columns and the counts apart (H5Stream::write_runs).
struct RunSpans {
  std::vector<std::size_t> first, count;
  explicit RunSpans(const std::vector<ColumnRun>& runs) {
    for (const ColumnRun& r : runs) {
      first.push_back(r.first);
      count.push_back(r.count);
    }
  }
};

// Room for a fifth more than what a row needs now before the cache must grow with it: tracks and triangles
// are created steadily, and each reopening writes the chunks being filled half full (read back later). A
// larger margin only holds finished chunks longer.
std::size_t with_room(std::size_t count) {
  return count + count / 4 + 1;
}

// The smallest prime at least n (hash slots: HDF5 advises a prime).
std::size_t prime_at_least(std::size_t n) {
  const auto is_prime = [](std::size_t v) {
    if (v < 2) return false;
    for (std::size_t d = 2; d * d <= v; ++d)
      if (v % d == 0) return false;
    return true;
  };
  while (!is_prime(n)) ++n;
  return n;
}

// The dataset's chunk: a block of frames by kChunkWidth along the growing axis by the whole trailing axes.
std::vector<hsize_t> chunk_for(const H5Shape& row_shape, std::size_t element_size) {
  std::vector<hsize_t> chunk(row_shape.size() + 1);
  std::size_t frame_bytes = element_size;
  for (std::size_t i = 0; i < row_shape.size(); ++i) {
    const std::size_t extent =
        i == 0 ? std::min(kChunkWidth, row_shape[0] == 0 ? kChunkWidth : row_shape[0]) : row_shape[i];
    chunk[i + 1] = std::max<hsize_t>(1, extent);
    frame_bytes *= static_cast<std::size_t>(chunk[i + 1]);
  }
  chunk[0] =
      std::clamp<std::size_t>(kChunkBytes / std::max<std::size_t>(1, frame_bytes), 1, kMaxFramesPerChunk);
  return chunk;
}

// Closes an HDF5 id at scope exit (property lists, spaces, attributes).
struct Id {
  hid_t id = -1;
  explicit Id(hid_t value) : id(value) {}
  Id(const Id&) = delete;
  Id& operator=(const Id&) = delete;
  ~Id() {
    if (id < 0) return;
    const H5I_type_t type = H5Iget_type(id);
    if (type == H5I_GENPROP_LST)
      H5Pclose(id);
    else if (type == H5I_DATASPACE)
      H5Sclose(id);
    else if (type == H5I_ATTR)
      H5Aclose(id);
    else if (type == H5I_GROUP || type == H5I_DATASET)
      H5Oclose(id);
    else if (type == H5I_DATATYPE)
      H5Tclose(id);
  }
  operator hid_t() const { return id; }
};

}  // namespace

H5Stream::H5Stream(const std::string& path) : path_(path), partial_path_(path + ".partial") {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  // A write past RLIMIT_FSIZE must come back as EFBIG (an error with a message), not kill the process.
  std::signal(SIGXFSZ, SIG_IGN);
  file_ = H5Fcreate(partial_path_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (file_ < 0) fail("cannot create HDF5 file", "");
  attribute("/", "complete", 0.0);
  attribute("/", "frames_written", 0.0);
}

void H5Stream::close_sets() {
  for (auto& [name, set] : sets_) H5Dclose(set);
  sets_.clear();
}

H5Stream::~H5Stream() {
  if (file_ < 0) return;
  // Uncommitted (an error elsewhere, perhaps a full disk): thrown away with its staging folder. Its last
  // writes go to an anonymous memory file, which also takes the final truncation, so the close succeeds.
  void* handle = nullptr;
  const int sink = ::memfd_create("tirstrain-discarded-h5", MFD_CLOEXEC);
  if (sink < 0 || H5Fget_vfd_handle(file_, H5P_DEFAULT, &handle) < 0 || handle == nullptr) {
    if (sink >= 0) ::close(sink);
    discard();
    return;
  }
  ::dup2(sink, *static_cast<int*>(handle));
  ::close(sink);
  close_sets();
  H5Fclose(file_);
}

// A file the disk refused is thrown away (its staging folder goes with it): its writes go to /dev/null from
// here on, so that flushing its datasets cannot fail again, and the file itself is left to the library's
// clean-up at exit. A close that fails (on the full disk, or on /dev/null refusing the final truncation)
// would leave HDF5 with a half-closed file that crashes that clean-up, after the error was reported.
void H5Stream::discard() const {
  if (file_ < 0) return;
  void* handle = nullptr;
  if (H5Fget_vfd_handle(file_, H5P_DEFAULT, &handle) >= 0 && handle != nullptr) {
    const int sink = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (sink >= 0) {
      ::dup2(sink, *static_cast<int*>(handle));
      ::close(sink);
    }
  }
  for (auto& [name, set] : sets_) H5Dclose(set);
  sets_.clear();
  file_ = -1;
}

void H5Stream::fail(const std::string& what, const std::string& name) const {
  const int cause = errno;
  discard();
  if (is_storage_errno(cause))
    throw Error(std::string("cannot write: ") + std::strerror(cause),
                {.file = partial_path_, .column = name});
  check_complete_write(partial_path_);
  check_writable(std::filesystem::path(partial_path_).parent_path().string());
  throw Error(what, {.file = partial_path_, .column = name});
}

void H5Stream::ensure_parent_groups(const std::string& name) {
  std::size_t pos = 1;
  while ((pos = name.find('/', pos)) != std::string::npos) {
    const std::string group = name.substr(0, pos);
    if (H5Lexists(file_, group.c_str(), H5P_DEFAULT) <= 0) {
      Id made(H5Gcreate2(file_, group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
      if (made < 0) fail("cannot create group", group);
    }
    ++pos;
  }
}

bool H5Stream::has(const std::string& name) const {
  std::size_t pos = 1;
  while (true) {
    pos = name.find('/', pos);
    const std::string part = pos == std::string::npos ? name : name.substr(0, pos);
    if (H5Lexists(file_, part.c_str(), H5P_DEFAULT) <= 0) return false;
    if (pos == std::string::npos) return true;
    ++pos;
  }
}

std::int64_t H5Stream::open_or_create(const std::string& name, const H5Shape& row_shape, const void* fill,
                                      std::int64_t memory_type, std::int64_t file_type) {
  auto& sets = sets_;
  if (const auto it = sets.find(name); it != sets.end()) return it->second;
  hid_t set = -1;
  if (has(name)) {
    set = open_with_cache(name, kMinChunkCacheSlots, kReadCacheBytes);
  } else {
    ensure_parent_groups(name);
    const std::size_t rank = row_shape.size() + 1;
    std::vector<hsize_t> dims(rank, 0), max_dims(rank, H5S_UNLIMITED);
    for (std::size_t i = 1; i < row_shape.size(); ++i) dims[i + 1] = max_dims[i + 1] = row_shape[i];
    Id space(H5Screate_simple(static_cast<int>(rank), dims.data(), max_dims.data()));
    Id create(H5Pcreate(H5P_DATASET_CREATE));
    const std::vector<hsize_t> chunk = chunk_for(row_shape, H5Tget_size(file_type));
    H5Pset_chunk(create, static_cast<int>(rank), chunk.data());
    H5Pset_fill_value(create, memory_type, fill);
    H5Pset_shuffle(create);
    H5Pset_deflate(create, kDeflateLevel);
    ChunkCache& cache = caches_[name];
    cache.chunk_bytes = H5Tget_size(file_type);
    for (const hsize_t c : chunk) cache.chunk_bytes *= static_cast<std::size_t>(c);
    cache.chunk_width = rank > 1 && chunk[0] > 1 ? static_cast<std::size_t>(chunk[1]) : 0;
    cache.bytes = cache.needed(row_shape.empty() ? 1 : with_room(row_shape[0]));
    cache.slots = cache.slots_needed(row_shape.empty() ? 1 : row_shape[0]);
    Id access(H5Pcreate(H5P_DATASET_ACCESS));
    H5Pset_chunk_cache(access, cache.slots, cache.bytes, 1.0);
    set = H5Dcreate2(file_, name.c_str(), file_type, space, H5P_DEFAULT, create, access);
  }
  if (set < 0) fail("cannot create per-frame dataset", name);
  sets[name] = set;
  return set;
}

namespace {

herr_t collect_dataset(hid_t, const char* name, const H5O_info_t* info, void* names) {
  if (info->type == H5O_TYPE_DATASET)
    static_cast<std::vector<std::string>*>(names)->push_back(std::string("/") + name);
  return 0;
}

}  // namespace

void H5Stream::copy_rows_from(const std::string& source, std::size_t rows) {
  const hid_t from = H5Fopen(source.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (from < 0) throw Error("cannot open the interrupted run's result file", {.file = source});
  struct Closer {
    hid_t file;
    ~Closer() { H5Fclose(file); }
  } closer{from};
  std::vector<std::string> names;
  if (H5Ovisit2(from, H5_INDEX_NAME, H5_ITER_INC, collect_dataset, &names, H5O_INFO_BASIC) < 0)
    throw Error("cannot list the interrupted run's result file", {.file = source});
  for (const std::string& name : names) {
    Id set(H5Dopen2(from, name.c_str(), H5P_DEFAULT));
    Id space(H5Dget_space(set));
    const int rank = H5Sget_simple_extent_ndims(space);
    if (rank < 1) continue;
    std::vector<hsize_t> dims(static_cast<std::size_t>(rank)), max_dims(dims.size());
    H5Sget_simple_extent_dims(space, dims.data(), max_dims.data());
    if (max_dims[0] != H5S_UNLIMITED) continue;  // written once, at the end
    Id type(H5Dget_type(set));
    Id create(H5Dget_create_plist(set));
    std::vector<hsize_t> chunk(dims.size());
    if (H5Pget_chunk(create, rank, chunk.data()) != rank)
      throw Error("internal: a per-frame dataset without chunks", {.file = source, .column = name});
    std::vector<hsize_t> copied = dims;
    copied[0] = std::min<hsize_t>(rows, dims[0]);
    ChunkCache& cache = caches_[name];
    cache.chunk_bytes = H5Tget_size(type);
    for (const hsize_t c : chunk) cache.chunk_bytes *= static_cast<std::size_t>(c);
    cache.chunk_width = rank > 1 && chunk[0] > 1 ? static_cast<std::size_t>(chunk[1]) : 0;
    const std::size_t width = rank > 1 ? static_cast<std::size_t>(dims[1]) : 1;
    cache.bytes = cache.needed(rank > 1 ? with_room(width) : 1);
    cache.slots = cache.slots_needed(width);
    cache.rows_written = static_cast<std::size_t>(copied[0]);
    ensure_parent_groups(name);
    Id to_space(H5Screate_simple(rank, copied.data(), max_dims.data()));
    Id access(H5Pcreate(H5P_DATASET_ACCESS));
    H5Pset_chunk_cache(access, cache.slots, cache.bytes, 1.0);
    const hid_t to = H5Dcreate2(file_, name.c_str(), type, to_space, H5P_DEFAULT, create, access);
    if (to < 0) fail("cannot create per-frame dataset", name);
    sets_[name] = to;
    // A block of frames at a time, as stored.
    std::size_t row_elements = 1;
    for (std::size_t i = 1; i < dims.size(); ++i) row_elements *= static_cast<std::size_t>(dims[i]);
    const hsize_t block = std::max<hsize_t>(1, chunk[0]);
    std::vector<unsigned char> buffer;
    for (hsize_t first = 0; first < copied[0]; first += block) {
      std::vector<hsize_t> start(dims.size(), 0), count = copied;
      start[0] = first;
      count[0] = std::min(block, copied[0] - first);
      buffer.resize(static_cast<std::size_t>(count[0]) * row_elements * H5Tget_size(type));
      Id memory(H5Screate_simple(rank, count.data(), nullptr));
      Id in(H5Dget_space(set));
      H5Sselect_hyperslab(in, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
      if (H5Dread(set, type, memory, in, H5P_DEFAULT, buffer.data()) < 0)
        throw Error("cannot read the interrupted run's rows", {.file = source, .column = name});
      Id out(H5Dget_space(to));
      H5Sselect_hyperslab(out, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
      if (H5Dwrite(to, type, memory, out, H5P_DEFAULT, buffer.data()) < 0)
        fail("cannot write dataset row", name);
    }
  }
}

std::size_t H5Stream::ChunkCache::slots_needed(std::size_t row_width) const {
  const std::size_t columns = chunk_width == 0 ? 1 : (row_width + chunk_width - 1) / chunk_width;
  return prime_at_least(std::max(kMinChunkCacheSlots, columns));
}

std::int64_t H5Stream::open_with_cache(const std::string& name, std::size_t slots,
                                       std::size_t cache_bytes) const {
  Id access(H5Pcreate(H5P_DATASET_ACCESS));
  H5Pset_chunk_cache(access, slots, cache_bytes, 1.0);
  return H5Dopen2(file_, name.c_str(), access);
}

// A row that needs more chunks than the cache holds, or spans more chunk columns than it has slots for
// (tracks or triangles created), would have chunks being filled written half full and read back: the
// dataset is reopened with room to grow (with_room), which writes out the cache once.
std::int64_t H5Stream::fit_cache_to_row(const std::string& name, std::int64_t set,
                                        std::size_t columns_written, std::size_t row_width) {
  const auto it = caches_.find(name);
  if (it == caches_.end()) return set;
  ChunkCache& cache = it->second;
  if (cache.needed(columns_written) <= cache.bytes && cache.slots_needed(row_width) <= cache.slots)
    return set;
  cache.bytes = std::max(cache.bytes, cache.needed(with_room(columns_written)));
  cache.slots = std::max(cache.slots, cache.slots_needed(with_room(row_width)));
  if (H5Dclose(set) < 0) fail("cannot write dataset", name);
  sets_.erase(name);
  const hid_t reopened = open_with_cache(name, cache.slots, cache.bytes);
  if (reopened < 0) fail("cannot reopen per-frame dataset", name);
  sets_[name] = reopened;
  return reopened;
}

H5Shape H5Stream::shape(const std::string& name) const {
  if (!has(name)) throw Error("no such dataset", {.file = partial_path_, .column = name});
  const auto& sets = sets_;
  const auto it = sets.find(name);
  Id opened(it == sets.end() ? H5Dopen2(file_, name.c_str(), H5P_DEFAULT) : -1);
  const hid_t set = it == sets.end() ? opened.id : it->second;
  Id space(H5Dget_space(set));
  std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(0, H5Sget_simple_extent_ndims(space))));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  return H5Shape(dims.begin(), dims.end());
}

// Opens (or creates) `name` and extends it to hold row `row` of shape `row_shape`; returns the dataset and,
// in `dims`, its extent after the extension.
std::int64_t H5Stream::prepare_row(const std::string& name, std::size_t row, const H5Shape& row_shape,
                                   const void* fill, std::int64_t memory_type, std::int64_t file_type,
                                   H5Shape& dims) {
  const hid_t set = open_or_create(name, row_shape, fill, memory_type, file_type);
  std::vector<hsize_t> now(row_shape.size() + 1, 0);
  {
    Id space(H5Dget_space(set));
    if (H5Sget_simple_extent_ndims(space) != static_cast<int>(now.size()))
      throw Error("internal: row rank differs from the dataset's", {.file = partial_path_, .column = name});
    H5Sget_simple_extent_dims(space, now.data(), nullptr);
  }
  std::vector<hsize_t> wanted = now;
  wanted[0] = std::max<hsize_t>(now[0], row + 1);
  if (!row_shape.empty()) wanted[1] = std::max<hsize_t>(now[1], row_shape[0]);
  for (std::size_t i = 1; i < row_shape.size(); ++i)
    if (wanted[i + 1] != row_shape[i])
      throw Error("internal: row shape differs from the dataset's", {.file = partial_path_, .column = name});
  if (wanted != now && H5Dset_extent(set, wanted.data()) < 0) fail("cannot extend dataset", name);
  dims.assign(wanted.begin(), wanted.end());
  return set;
}

// Whether row `row` of `name` may be written in part: its first write, to a dataset chunked in columns (a
// row written again must replace the whole of the earlier one). Notes that the row is written now.
bool H5Stream::first_write_of(const std::string& name, std::size_t row) {
  const auto it = caches_.find(name);
  if (it == caches_.end()) return false;
  const bool first = row >= it->second.rows_written;
  it->second.rows_written = std::max(it->second.rows_written, row + 1);
  return first && it->second.chunk_width > 0;
}

// Writes the runs of columns (first, count) of row `row` from `memory`, which holds the whole row: the runs
// are selected in it as in the file.
void H5Stream::write_runs(const std::string& name, std::int64_t set, std::size_t row, const H5Shape& dims,
                          const H5Shape& row_shape, std::span<const std::size_t> run_first,
                          std::span<const std::size_t> run_count, const void* memory,
                          std::int64_t memory_type) {
  if (run_first.empty()) return;
  std::vector<hsize_t> count(dims.size(), 1);
  for (std::size_t i = 0; i < row_shape.size(); ++i) count[i + 1] = row_shape[i];
  const auto select_runs = [&](hid_t space, std::size_t at_row) {
    hsize_t selected = 0;
    for (std::size_t k = 0; k < run_first.size(); ++k) {
      std::vector<hsize_t> start(dims.size(), 0), extent = count;
      if (!row_shape.empty()) {
        start[1] = run_first[k];
        extent[1] = run_count[k];
      }
      start[0] = at_row;
      H5Sselect_hyperslab(space, k == 0 ? H5S_SELECT_SET : H5S_SELECT_OR, start.data(), nullptr,
                          extent.data(), nullptr);
      hsize_t n = 1;
      for (const hsize_t e : extent) n *= e;
      selected += n;
    }
    return selected;
  };
  Id file_space(H5Dget_space(set));
  const hsize_t selected = select_runs(file_space, row);
  Id memory_space(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr));
  if (select_runs(memory_space, 0) != selected)
    throw Error("internal: row selections differ", {.file = partial_path_, .column = name});
  if (H5Dwrite(set, memory_type, memory_space, file_space, H5P_DEFAULT, memory) < 0)
    fail("cannot write dataset row", name);
}

template <typename T>
void H5Stream::write_row_impl(const std::string& name, std::size_t row, std::span<const T> data,
                              const H5Shape& row_shape, T fill, std::int64_t memory_type,
                              std::int64_t file_type) {
  if (product(row_shape) != data.size())
    throw Error("internal: row size does not match its shape", {.file = partial_path_, .column = name});
  H5Shape dims;
  hid_t set = prepare_row(name, row, row_shape, &fill, memory_type, file_type, dims);
  if (data.empty()) return;
  // The whole row, or only the chunk columns holding something other than the fill value: a long trial
  // creates several times more tracks and triangles than are alive at once, and writing the retired ones'
  // fill would touch every chunk across the row at every frame, a cost that grows with the recording.
  // A row written again (a stage revised and run again) is written whole, so that nothing of the earlier
  // row survives where the new one holds the fill.
  std::vector<ColumnRun> runs{{0, row_shape.empty() ? 1 : row_shape[0]}};
  if (first_write_of(name, row) && !row_shape.empty()) {
    runs = columns_not_fill(data, row_shape[0], caches_.at(name).chunk_width, fill);
    set = fit_cache_to_row(name, set, columns_in(runs), dims[1]);
  }
  const RunSpans spans(runs);
  write_runs(name, set, row, dims, row_shape, spans.first, spans.count, data.data(), memory_type);
}

template <typename T>
void H5Stream::write_columns_impl(const std::string& name, std::size_t row,
                                  std::span<const std::size_t> columns, std::span<const T> values,
                                  const H5Shape& row_shape, T fill, std::int64_t memory_type,
                                  std::int64_t file_type) {
  const std::size_t per_column = row_shape.empty() ? 0 : product(row_shape, 1);
  if (row_shape.empty() || values.size() != columns.size() * per_column)
    throw Error("internal: column values do not match their shape", {.file = partial_path_, .column = name});
  for (const std::size_t c : columns)
    if (c >= row_shape[0])
      throw Error("internal: column beyond the row's width", {.file = partial_path_, .column = name});
  if (!caches_.contains(name) || row < caches_.at(name).rows_written || caches_.at(name).chunk_width == 0) {
    // Created now, written again, or not chunked in columns: the row in full.
    std::vector<T> row_data(product(row_shape), fill);
    for (std::size_t i = 0; i < columns.size(); ++i)
      std::copy_n(values.begin() + static_cast<std::ptrdiff_t>(i * per_column), per_column,
                  row_data.begin() + static_cast<std::ptrdiff_t>(columns[i] * per_column));
    write_row_impl(name, row, std::span<const T>(row_data), row_shape, fill, memory_type, file_type);
    return;
  }
  H5Shape dims;
  hid_t set = prepare_row(name, row, row_shape, &fill, memory_type, file_type, dims);
  first_write_of(name, row);
  // The row at full width in this dataset's buffer: the columns written last time back to the fill, this
  // row's columns set. HDF5 then reads the row through a selection shaped as the file's (a compact buffer
  // would make it map the elements one by one), and the cost follows the columns written, not the width.
  RowBuffer& buffer = row_buffers_[name];
  const std::size_t column_bytes = per_column * sizeof(T);
  const std::size_t old_width = buffer.bytes.size() / column_bytes;
  const auto put = [&](std::size_t column, const T* from) {
    std::memcpy(buffer.bytes.data() + column * column_bytes, from, column_bytes);
  };
  const std::vector<T> fill_column(per_column, fill);
  if (row_shape[0] > old_width) {
    buffer.bytes.resize(row_shape[0] * column_bytes);
    for (std::size_t c = old_width; c < row_shape[0]; ++c) put(c, fill_column.data());
  }
  for (const std::size_t c : buffer.columns) put(c, fill_column.data());
  // Columns holding only the fill (a retired track's values, a triangle without strain) are left out, so
  // that a block of them creates no chunk.
  const std::size_t width = caches_.at(name).chunk_width;
  buffer.columns.clear();
  std::vector<std::size_t> blocks;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const T* column = values.data() + i * per_column;
    if (std::all_of(column, column + per_column, [fill](T v) { return same_value(v, fill); })) continue;
    put(columns[i], column);
    buffer.columns.push_back(columns[i]);
    blocks.push_back(columns[i] / width);
  }
  const std::vector<ColumnRun> runs = runs_of_blocks(std::move(blocks), width, row_shape[0]);
  set = fit_cache_to_row(name, set, columns_in(runs), dims[1]);
  const RunSpans spans(runs);
  write_runs(name, set, row, dims, row_shape, spans.first, spans.count, buffer.bytes.data(), memory_type);
}

void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const double> data,
                         const H5Shape& row_shape, double fill, H5Precision precision) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_DOUBLE,
                 precision == H5Precision::kFloat32 ? H5T_IEEE_F32LE : H5T_IEEE_F64LE);
}
void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const float> data,
                         const H5Shape& row_shape, float fill) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_FLOAT, H5T_IEEE_F32LE);
}
void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const std::int64_t> data,
                         const H5Shape& row_shape, std::int64_t fill) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_INT64, H5T_STD_I64LE);
}
void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const std::int32_t> data,
                         const H5Shape& row_shape, std::int32_t fill) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_INT32, H5T_STD_I32LE);
}
void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const std::int8_t> data,
                         const H5Shape& row_shape, std::int8_t fill) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_INT8, H5T_STD_I8LE);
}
void H5Stream::write_row(const std::string& name, std::size_t row, std::span<const std::uint8_t> data,
                         const H5Shape& row_shape, std::uint8_t fill) {
  write_row_impl(name, row, data, row_shape, fill, H5T_NATIVE_UINT8, H5T_STD_U8LE);
}

void H5Stream::write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                             std::span<const double> values, const H5Shape& row_shape, double fill,
                             H5Precision precision) {
  write_columns_impl(name, row, columns, values, row_shape, fill, H5T_NATIVE_DOUBLE,
                     precision == H5Precision::kFloat32 ? H5T_IEEE_F32LE : H5T_IEEE_F64LE);
}
void H5Stream::write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                             std::span<const float> values, const H5Shape& row_shape, float fill) {
  write_columns_impl(name, row, columns, values, row_shape, fill, H5T_NATIVE_FLOAT, H5T_IEEE_F32LE);
}
void H5Stream::write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                             std::span<const std::int8_t> values, const H5Shape& row_shape,
                             std::int8_t fill) {
  write_columns_impl(name, row, columns, values, row_shape, fill, H5T_NATIVE_INT8, H5T_STD_I8LE);
}
void H5Stream::write_columns(const std::string& name, std::size_t row, std::span<const std::size_t> columns,
                             std::span<const std::uint8_t> values, const H5Shape& row_shape,
                             std::uint8_t fill) {
  write_columns_impl(name, row, columns, values, row_shape, fill, H5T_NATIVE_UINT8, H5T_STD_U8LE);
}

std::vector<double> H5Stream::read_block(const std::string& name, const H5Shape& offset,
                                         const H5Shape& count) const {
  const auto& sets = sets_;
  const auto it = sets.find(name);
  if (it == sets.end())
    throw Error("internal: dataset not open for reading", {.file = partial_path_, .column = name});
  std::vector<double> data(product(count));
  if (data.empty()) return data;
  const std::vector<hsize_t> start(offset.begin(), offset.end()), extent(count.begin(), count.end());
  Id file_space(H5Dget_space(it->second));
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, extent.data(), nullptr);
  Id memory_space(H5Screate_simple(static_cast<int>(extent.size()), extent.data(), nullptr));
  if (H5Dread(it->second, H5T_NATIVE_DOUBLE, memory_space, file_space, H5P_DEFAULT, data.data()) < 0)
    fail("cannot read back dataset", name);
  return data;
}

void H5Stream::write_block(const std::string& name, const H5Shape& offset, const H5Shape& count,
                           std::span<const double> data) {
  const auto& sets = sets_;
  const auto it = sets.find(name);
  if (it == sets.end() || product(count) != data.size())
    throw Error("internal: block write to a dataset not open or of the wrong size",
                {.file = partial_path_, .column = name});
  if (data.empty()) return;
  const std::vector<hsize_t> start(offset.begin(), offset.end()), extent(count.begin(), count.end());
  Id file_space(H5Dget_space(it->second));
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, extent.data(), nullptr);
  Id memory_space(H5Screate_simple(static_cast<int>(extent.size()), extent.data(), nullptr));
  if (H5Dwrite(it->second, H5T_NATIVE_DOUBLE, memory_space, file_space, H5P_DEFAULT, data.data()) < 0)
    fail("cannot write dataset block", name);
}

template <typename T>
void H5Stream::write_whole(const std::string& name, std::span<const T> data, const H5Shape& shape,
                           std::int64_t memory_type) {
  if (product(shape) != data.size())
    throw Error("internal: dataset size does not match its shape", {.file = partial_path_, .column = name});
  if (has(name)) {
    close_sets();
    if (H5Ldelete(file_, name.c_str(), H5P_DEFAULT) < 0) fail("cannot replace dataset", name);
  }
  ensure_parent_groups(name);
  const std::vector<hsize_t> dims(shape.begin(), shape.end());
  Id space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr));
  Id create(H5Pcreate(H5P_DATASET_CREATE));
  if (!shape.empty() && shape[0] > 0 && data.size() * sizeof(T) > 16 * 1024) {
    std::vector<hsize_t> chunk = dims;
    chunk[0] = std::clamp<hsize_t>(kChunkBytes / std::max<std::size_t>(1, product(shape, 1) * sizeof(T)), 1,
                                   dims[0]);
    H5Pset_chunk(create, static_cast<int>(chunk.size()), chunk.data());
    H5Pset_shuffle(create);
    H5Pset_deflate(create, kDeflateLevel);
  }
  Id set(H5Dcreate2(file_, name.c_str(), memory_type, space, H5P_DEFAULT, create, H5P_DEFAULT));
  if (set < 0) fail("cannot create dataset", name);
  if (!data.empty() && H5Dwrite(set, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0)
    fail("cannot write dataset", name);
}

void H5Stream::write(const std::string& name, std::span<const double> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_DOUBLE);
}
void H5Stream::write(const std::string& name, std::span<const std::int32_t> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_INT32);
}
void H5Stream::write(const std::string& name, std::span<const std::int8_t> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_INT8);
}

void H5Stream::write(const std::string& name, std::span<const float> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_FLOAT);
}
void H5Stream::write(const std::string& name, std::span<const std::int64_t> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_INT64);
}
void H5Stream::write(const std::string& name, std::span<const std::uint8_t> data, const H5Shape& shape) {
  write_whole(name, data, shape, H5T_NATIVE_UINT8);
}

void H5Stream::attribute(const std::string& object, const std::string& name, const std::string& value) {
  if (object != "/" && !has(object)) ensure_parent_groups(object + "/");
  Id target(H5Oopen(file_, object.c_str(), H5P_DEFAULT));
  if (target < 0) fail("cannot open object for attribute '" + name + "'", object);
  if (H5Aexists(target, name.c_str()) > 0) H5Adelete(target, name.c_str());
  Id type(H5Tcopy(H5T_C_S1));
  const std::string text = value.empty() ? std::string(" ") : value;
  H5Tset_size(type, text.size());
  Id space(H5Screate(H5S_SCALAR));
  Id attr(H5Acreate2(target, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT));
  if (attr < 0 || H5Awrite(attr, type, text.data()) < 0)
    fail("cannot write attribute '" + name + "'", object);
}

void H5Stream::attribute(const std::string& object, const std::string& name, double value) {
  if (object != "/" && !has(object)) ensure_parent_groups(object + "/");
  Id target(H5Oopen(file_, object.c_str(), H5P_DEFAULT));
  if (target < 0) fail("cannot open object for attribute '" + name + "'", object);
  if (H5Aexists(target, name.c_str()) > 0) H5Adelete(target, name.c_str());
  Id space(H5Screate(H5S_SCALAR));
  Id attr(H5Acreate2(target, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT));
  if (attr < 0 || H5Awrite(attr, H5T_NATIVE_DOUBLE, &value) < 0)
    fail("cannot write attribute '" + name + "'", object);
}

void H5Stream::mark_flushed(std::size_t frames_written) {
  attribute("/", "frames_written", static_cast<double>(frames_written));
  if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) fail("cannot flush HDF5 file", "");
  // HDF5 keeps freed buffers on free lists of its own, one per size; compressed chunks come in many sizes,
  // so without this the lists grow with the recording.
  H5garbage_collect();
}

void H5Stream::commit() {
  attribute("/", "complete", 1.0);
  // Everything written and checked while the file is open, so a failure is reported, never lost in a close.
  if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) fail("cannot finish HDF5 file", "");
  while (!sets_.empty()) {
    const auto node = sets_.extract(sets_.begin());
    if (H5Dclose(node.mapped()) < 0) fail("cannot finish dataset", node.key());
  }
  const hid_t file = file_;
  file_ = -1;
  if (H5Fclose(file) < 0) throw Error("cannot finish HDF5 file", {.file = partial_path_});
  const int fd = ::open(partial_path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const int cause = errno;
    if (fd >= 0) ::close(fd);
    throw Error(std::string("cannot write: ") + std::strerror(cause), {.file = partial_path_});
  }
  ::close(fd);
  if (::rename(partial_path_.c_str(), path_.c_str()) != 0)
    throw Error(std::string("cannot rename finished file into place: ") + std::strerror(errno),
                {.file = path_});
  committed_ = true;
}

}  // namespace tirstrain
