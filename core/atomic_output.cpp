#include "core/atomic_output.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <linux/fs.h>
#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace fs = std::filesystem;

namespace tirstrain {
namespace {

constexpr std::size_t kWriteBufferBytes = 1u << 16;

// A write past RLIMIT_FSIZE must come back as EFBIG (an error with a message), not kill the process.
void ignore_file_size_signal() {
  static const bool ignored = [] {
    std::signal(SIGXFSZ, SIG_IGN);
    return true;
  }();
  (void)ignored;
}

// Atomic exchange of two existing paths; false when the filesystem cannot (EINVAL, ENOSYS).
bool exchange_paths(const std::string& a, const std::string& b) {
#ifdef SYS_renameat2
  if (::syscall(SYS_renameat2, AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0) return true;
  if (errno != EINVAL && errno != ENOSYS)
    throw Error(std::string("cannot swap the finished output into place: ") + std::strerror(errno),
                {.file = b});
#endif
  return false;
}

// Leftovers of an interrupted writer inside a folder (partial files of a run before staging).
bool is_leftover(const std::string& name) {
  const auto ends_with = [&](const std::string& tail) {
    return name.size() >= tail.size() && name.compare(name.size() - tail.size(), tail.size(), tail) == 0;
  };
  return ends_with(".partial") || ends_with(".partial.mp4") || name == ".tirstrain-write-probe" ||
         name == StagingDirectory::kStagingMarker;
}

}  // namespace

void ensure_output_dir(const std::string& dir, const std::string& what) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("output path exists and is not a directory", {.file = dir, .key = what});
  fs::create_directories(dir, ec);
  if (ec) throw Error("cannot create output directory: " + ec.message(), {.file = dir, .key = what});
  const fs::path probe = fs::path(dir) / ".tirstrain-write-probe";
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw Error(std::string("output directory is not writable: ") + std::strerror(errno),
                {.file = dir, .key = what});
  ::close(fd);
  fs::remove(probe, ec);
}

std::string recorded_path(std::string text, const std::vector<StagedFolder>& folders) {
  for (const StagedFolder& folder : folders) {
    if (folder.staging.empty()) continue;
    std::string out;
    std::size_t from = 0;
    for (std::size_t at = text.find(folder.staging); at != std::string::npos;
         at = text.find(folder.staging, at + 1)) {
      const std::size_t end = at + folder.staging.size();
      // Only the whole folder name: "/x/a.partial" in "/x/a.partial/b", not in "/x/a.partial2".
      if (at < from || (end < text.size() && text[end] != '/')) continue;
      out.append(text, from, at - from).append(folder.final_path);
      from = end;
    }
    text = out.append(text, from, std::string::npos);
  }
  return text;
}

StagingDirectory::StagingDirectory(const std::string& final_path) : StagingDirectory(final_path, false) {}

StagingDirectory::StagingDirectory(const std::string& final_path, bool adopt_existing)
    : final_path_(fs::path(final_path).lexically_normal().string()) {
  while (final_path_.size() > 1 && final_path_.back() == '/') final_path_.pop_back();
  std::error_code ec;
  // A link to a folder is followed: the output goes where the user's link points, and the link stays.
  if (fs::is_symlink(final_path_, ec)) {
    const fs::path target = fs::canonical(final_path_, ec);
    if (ec)
      throw Error("output path is a link that cannot be followed: " + ec.message(), {.file = final_path_});
    final_path_ = target.string();
  }
  staging_path_ = final_path_ + ".partial";
  if (fs::exists(final_path_, ec) && !fs::is_directory(final_path_, ec))
    throw Error("output path exists and is not a directory", {.file = final_path_});
  const fs::path parent = fs::path(final_path_).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  const bool existed = lock_staging_folder();
  if (existed && adopt_existing) {
    keep_on_failure_ = true;
  } else if (existed) {
    clear_leftover();
  }
  ensure_output_dir(staging_path_, "--out");
  std::ofstream(fs::path(staging_path_) / kStagingMarker) << "a tirstrain run is writing here\n";
}

// Creates the staging folder if needed and holds an exclusive lock on it for as long as this object lives:
// a second run into the same --out is refused instead of writing into the same files. True when the folder
// was there before.
bool StagingDirectory::lock_staging_folder() {
  for (int attempt = 0; attempt < 8; ++attempt) {
    const bool created = ::mkdir(staging_path_.c_str(), 0777) == 0;
    if (!created && errno != EEXIST)
      throw Error(std::string("cannot create output directory: ") + std::strerror(errno),
                  {.file = staging_path_, .key = "--out"});
    const int fd = ::open(staging_path_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) continue;  // removed in between by a run that found it unlocked: try again
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      ::close(fd);
      if (error == EWOULDBLOCK)
        throw Error(
            "another tirstrain run is writing this output now (its staging folder is locked); wait "
            "for it to finish or choose another --out",
            {.file = staging_path_, .key = "--out"});
      throw Error(std::string("cannot lock the output's staging folder: ") + std::strerror(error),
                  {.file = staging_path_, .key = "--out"});
    }
    // The lock holds the folder now at the path only if no one replaced it between open() and flock().
    struct stat held = {};
    struct stat at_path = {};
    if (::fstat(fd, &held) == 0 && ::stat(staging_path_.c_str(), &at_path) == 0 &&
        held.st_ino == at_path.st_ino && held.st_dev == at_path.st_dev) {
      lock_fd_ = fd;
      return !created;
    }
    ::close(fd);
  }
  throw Error("the output's staging folder keeps changing under this run",
              {.file = staging_path_, .key = "--out"});
}

// A staging folder left by an interrupted run carries the marker (or, from a writer without one, only
// partial files) and is emptied; one holding anything else is not tirstrain's, and is left alone.
void StagingDirectory::clear_leftover() {
  std::error_code ec;
  bool marked = false, only_partial_files = true;
  for (const auto& entry : fs::directory_iterator(staging_path_, ec)) {
    const std::string name = entry.path().filename().string();
    marked = marked || name == kStagingMarker;
    only_partial_files = only_partial_files && is_leftover(name);
  }
  if (!marked && !only_partial_files)
    throw Error(
        "this folder holds files a tirstrain run did not leave there; the run stages its output under "
        "this name, so move them or choose another --out",
        {.file = staging_path_, .key = "--out"});
  for (const auto& entry : fs::directory_iterator(staging_path_, ec))
    if (entry.path().filename() != kStagingMarker) fs::remove_all(entry.path(), ec);
  if (ec)
    throw Error("cannot clear an interrupted run's staging folder: " + ec.message(), {.file = staging_path_});
}

StagingDirectory::~StagingDirectory() {
  if (!committed_ && !keep_on_failure_) {
    std::error_code ec;
    fs::remove_all(staging_path_, ec);
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

// The earlier output is marked before the exchange brings it to the staging path: a run killed while it is
// being removed leaves a marked folder, which the next run clears instead of refusing.
void StagingDirectory::commit() {
  std::error_code ec;
  if (fs::is_directory(final_path_, ec))
    std::ofstream(fs::path(final_path_) / kStagingMarker) << "an earlier output being replaced\n";
  swap_in_directory(staging_path_, final_path_, kStagingMarker);
  committed_ = true;
}

void check_replaceable_output(const std::string& dir, const std::vector<std::string>& own_names,
                              const std::string& command, const std::string& option) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (std::find(own_names.begin(), own_names.end(), name) != own_names.end() || is_leftover(name)) continue;
    throw Error(
        "the output folder holds '" + name + "', which tirstrain " + command +
            " does not write; the folder is replaced as a whole when the run completes, so give a new "
            "or empty folder",
        {.file = dir, .key = option});
  }
}

void swap_in_directory(const std::string& staging, const std::string& final_path, const std::string& marker) {
  std::error_code ec;
  const auto unmark_output = [&] {
    if (!marker.empty()) fs::remove(fs::path(final_path) / marker, ec);
  };
  if (fs::exists(final_path, ec)) {
    if (!fs::is_directory(final_path, ec))
      throw Error("output path exists and is not a directory", {.file = final_path});
    if (exchange_paths(staging, final_path)) {
      unmark_output();
      fs::remove_all(staging, ec);  // holds the earlier output after the exchange
      return;
    }
    fs::remove_all(final_path, ec);
    if (ec) throw Error("cannot replace existing output directory: " + ec.message(), {.file = final_path});
  }
  fs::rename(staging, final_path, ec);
  if (ec) throw Error("cannot move finished output into place: " + ec.message(), {.file = final_path});
  unmark_output();
}

AtomicFile::AtomicFile(const std::string& path) : path_(path), partial_path_(path + ".partial") {
  ignore_file_size_signal();
  fd_ = ::open(partial_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw Error(std::string("cannot open file for writing: ") + std::strerror(errno),
                {.file = partial_path_});
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(partial_path_.c_str());
}

void AtomicFile::append(std::string_view bytes) {
  if (bytes.size() >= kWriteBufferBytes) {  // large blocks go straight out, not through a copy
    flush_buffer();
    write_all(bytes);
    return;
  }
  buffer_.append(bytes);
  if (buffer_.size() >= kWriteBufferBytes) flush_buffer();
}

void AtomicFile::flush_buffer() {
  write_all(buffer_);
  buffer_.clear();
}

void AtomicFile::write_all(std::string_view bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(std::string("cannot write: ") + std::strerror(errno), {.file = partial_path_});
    done += static_cast<std::size_t>(n);
  }
}

void AtomicFile::make_durable() {
  if (fd_ < 0) return;
  flush_buffer();
  if (::fsync(fd_) != 0)
    throw Error(std::string("cannot write: ") + std::strerror(errno), {.file = partial_path_});
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0)
    throw Error(std::string("cannot write: ") + std::strerror(errno), {.file = partial_path_});
}

void AtomicFile::commit() {
  make_durable();
  if (::rename(partial_path_.c_str(), path_.c_str()) != 0)
    throw Error(std::string("cannot rename finished file into place: ") + std::strerror(errno),
                {.file = path_});
  committed_ = true;
}

void check_writable(const std::string& dir) {
  ignore_file_size_signal();
  const std::string probe = (fs::path(dir) / ".tirstrain-write-probe").string();
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(std::string("cannot write: ") + std::strerror(errno), {.file = dir});
  const std::string block(kWriteBufferBytes, '\0');
  const bool written =
      ::write(fd, block.data(), block.size()) == static_cast<ssize_t>(block.size()) && ::fsync(fd) == 0;
  const int cause = errno;
  ::close(fd);
  ::unlink(probe.c_str());
  if (!written) throw Error(std::string("cannot write: ") + std::strerror(cause), {.file = dir});
}

void check_complete_write(const std::string& path) {
  constexpr unsigned long long kMinFreeBytes = 1ull << 20;
  struct statvfs fs_stat {};
  if (::statvfs(path.c_str(), &fs_stat) == 0) {
    const unsigned long long free_bytes =
        static_cast<unsigned long long>(geteuid() == 0 ? fs_stat.f_bfree : fs_stat.f_bavail) *
        fs_stat.f_frsize;
    if (free_bytes < kMinFreeBytes)
      throw Error(std::string("cannot write: ") + std::strerror(ENOSPC), {.file = path});
  }
  struct rlimit limit {};
  struct stat file_stat {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      ::stat(path.c_str(), &file_stat) == 0 && static_cast<rlim_t>(file_stat.st_size) >= limit.rlim_cur)
    throw Error(std::string("cannot write: ") + std::strerror(EFBIG), {.file = path});
}

bool path_is_within(const std::string& inner, const std::string& outer) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(inner, ec);
  if (ec) return false;
  const fs::path b = fs::weakly_canonical(outer, ec);
  if (ec) return false;
  const fs::path relative = a.lexically_relative(b);
  return !relative.empty() && *relative.begin() != "..";
}

void write_text_file(const std::string& path, const std::string& text) {
  AtomicFile file(path);
  file.append(text);
  file.commit();
}

}  // namespace tirstrain
