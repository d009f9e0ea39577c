#pragma once
// Outputs appear complete or not at all: files are written under a temporary name and renamed when done
// (CsvWriter, H5Writer do this themselves); whole directories are staged under a sibling name.
#include <string>

namespace tirstrain {

// Creates `dir` and its parents if needed and checks that files can be created in it. `what` names the
// option or key the path came from, for the message.
void ensure_output_dir(const std::string& dir, const std::string& what);

// A directory built at "<final>.partial" and renamed to <final> by commit(), replacing an existing one.
// Destroyed uncommitted (error, exception), it removes the staging directory.
class StagingDirectory {
 public:
  explicit StagingDirectory(const std::string& final_path);
  ~StagingDirectory();
  StagingDirectory(const StagingDirectory&) = delete;
  StagingDirectory& operator=(const StagingDirectory&) = delete;

  const std::string& path() const { return staging_path_; }
  const std::string& final_path() const { return final_path_; }
  void commit();

 private:
  std::string final_path_;
  std::string staging_path_;
  bool committed_ = false;
};

// Writes text to path via a temporary name.
void write_text_file(const std::string& path, const std::string& text);

}  // namespace tirstrain
