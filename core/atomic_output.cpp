#include "core/atomic_output.hpp"

#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace fs = std::filesystem;

namespace tirstrain {

void ensure_output_dir(const std::string& dir, const std::string& what) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("output path exists and is not a directory", {.file = dir, .key = what});
  fs::create_directories(dir, ec);
  if (ec) throw Error("cannot create output directory: " + ec.message(), {.file = dir, .key = what});
  const fs::path probe = fs::path(dir) / ".tirstrain-write-probe";
  {
    std::ofstream out(probe);
    if (!out) throw Error("output directory is not writable", {.file = dir, .key = what});
  }
  fs::remove(probe, ec);
}

StagingDirectory::StagingDirectory(const std::string& final_path)
    : final_path_(fs::path(final_path).lexically_normal().string()) {
  while (final_path_.size() > 1 && final_path_.back() == '/') final_path_.pop_back();
  staging_path_ = final_path_ + ".partial";
  std::error_code ec;
  fs::remove_all(staging_path_, ec);
  const fs::path parent = fs::path(final_path_).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  fs::create_directories(staging_path_, ec);
  if (ec) throw Error("cannot create output directory: " + ec.message(), {.file = staging_path_});
}

StagingDirectory::~StagingDirectory() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_path_, ec);
  }
}

void StagingDirectory::commit() {
  std::error_code ec;
  if (fs::exists(final_path_, ec)) {
    if (!fs::is_directory(final_path_, ec))
      throw Error("output path exists and is not a directory", {.file = final_path_});
    fs::remove_all(final_path_, ec);
    if (ec) throw Error("cannot replace existing output directory: " + ec.message(), {.file = final_path_});
  }
  fs::rename(staging_path_, final_path_, ec);
  if (ec) throw Error("cannot move finished output into place: " + ec.message(), {.file = final_path_});
  committed_ = true;
}

void write_text_file(const std::string& path, const std::string& text) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::trunc);
    if (!out) throw Error("cannot open file for writing", {.file = partial});
    out << text;
    out.flush();
    if (!out) throw Error("write failed (disk full?)", {.file = partial});
  }
  std::error_code ec;
  fs::rename(partial, path, ec);
  if (ec) throw Error("cannot rename finished file into place: " + ec.message(), {.file = path});
}

}  // namespace tirstrain
