#pragma once
// Outputs appear complete or not at all: files are written under a temporary name and renamed when done
// (CsvWriter, H5Writer do this themselves); whole directories are staged under a sibling name and swapped
// in. Write errors name their cause from errno ("No space left on device", "File too large").
#include <string>
#include <string_view>
#include <vector>

namespace tirstrain {

// Creates `dir` and its parents if needed and checks that files can be created in it. `what` names the
// option or key the path came from, for the message.
void ensure_output_dir(const std::string& dir, const std::string& what);

// A folder being built (`staging`) and where it will be once swapped in (`final_path`): paths that outputs
// record (an input inside the folder, say) name the final place, so that they stay true after the swap.
struct StagedFolder {
  std::string staging;
  std::string final_path;
};

// `text` with every path under a staging folder of `folders` renamed to the folder's final place, the
// folders taken in order (innermost first).
std::string recorded_path(std::string text, const std::vector<StagedFolder>& folders);

// A directory built at "<final>.partial" and swapped in for <final> by commit(): an existing <final> is
// exchanged atomically (renameat2 RENAME_EXCHANGE) and only then removed, so at every instant <final> is
// either the earlier complete output or the new complete one. Destroyed uncommitted (error, exception), it
// removes the staging directory. While it lives it holds an exclusive lock (flock) on the staging
// directory, so a second run into the same output is refused rather than interleaved; the directory carries
// a marker file until commit, and commit marks the earlier <final> before exchanging it, so that a later
// run clears only what an interrupted run left, at any instant it was killed (a "<final>.partial" holding
// anything else is refused). A <final> that is a link to a folder is followed.
class StagingDirectory {
 public:
  explicit StagingDirectory(const std::string& final_path);
  // `adopt_existing`: an existing "<final_path>.partial" is kept as it is (an interrupted run continued),
  // and kept too if this run fails in turn, so that it can be continued again.
  StagingDirectory(const std::string& final_path, bool adopt_existing);
  ~StagingDirectory();
  StagingDirectory(const StagingDirectory&) = delete;
  StagingDirectory& operator=(const StagingDirectory&) = delete;

  const std::string& path() const { return staging_path_; }
  const std::string& final_path() const { return final_path_; }
  StagedFolder folder() const { return {staging_path_, final_path_}; }
  void commit();

  // The marker file a staging directory carries while a run writes it.
  static constexpr const char* kStagingMarker = ".tirstrain-staging";

 private:
  bool lock_staging_folder();
  void clear_leftover();

  std::string final_path_;
  std::string staging_path_;
  int lock_fd_ = -1;
  bool committed_ = false;
  bool keep_on_failure_ = false;
};

// Throws Error (key `option`) when the folder `dir` exists and holds anything but `own_names` (or leftovers
// of an interrupted writer, "*.partial"): `command` replaces the folder as a whole when it completes, which
// would delete the rest.
void check_replaceable_output(const std::string& dir, const std::vector<std::string>& own_names,
                              const std::string& command, const std::string& option = "--out");

// Puts the complete directory `staging` in place of `final_path`: an existing <final_path> is exchanged
// atomically (renameat2 RENAME_EXCHANGE) and only then removed, so at every instant <final_path> is either
// the earlier complete output or the new one (where the filesystem cannot exchange, the earlier one is
// removed first). Errors name the path and the cause. A non-empty `marker` names a file that both folders
// carry through the swap: it is removed from the new output at once, and stays in the earlier one, which is
// removed after it.
void swap_in_directory(const std::string& staging, const std::string& final_path,
                       const std::string& marker = {});

// A file written to "<path>.partial" through a checked write(2) loop, made durable (fsync) and renamed to
// <path> by commit(); destroyed uncommitted, it removes the partial file. Errors name the file and errno's
// cause.
class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void append(std::string_view bytes);
  // Writes out everything appended and makes it durable, so that commit() only renames: a writer of
  // several files calls it on each before committing any.
  void make_durable();
  void commit();
  const std::string& partial_path() const { return partial_path_; }

 private:
  void flush_buffer();
  void write_all(std::string_view bytes);

  std::string path_;
  std::string partial_path_;
  std::string buffer_;  // bytes not yet handed to write(2)
  int fd_ = -1;
  bool committed_ = false;
};

// Throws Error naming errno's cause when a file cannot be created in `dir` and written (64 KiB, made
// durable): tells a full disk or read-only folder apart from other failures of a library writer.
void check_writable(const std::string& dir);

// For a file written by a library that does not report write errors (FFmpeg through OpenCV): throws Error
// when the file may be cut short, because its filesystem has less than 1 MiB left or the file reached the
// process's file-size limit (RLIMIT_FSIZE).
void check_complete_write(const std::string& path);

// True when `inner` is `outer` or lies inside it, with links and ".." resolved.
bool path_is_within(const std::string& inner, const std::string& outer);

// Writes text to path via a temporary name.
void write_text_file(const std::string& path, const std::string& text);

}  // namespace tirstrain
