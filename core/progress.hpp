#pragma once
// Progress on long work: a redrawn bar on a terminal, a plain line every 10 % otherwise, nothing if quiet.
#include <chrono>
#include <cstdio>
#include <string>

namespace tirstrain {

class Progress {
 public:
  Progress(std::string label, long total, bool quiet, std::FILE* stream = stderr);
  void update(long done);
  void finish();

 private:
  std::string label_;
  long total_;
  bool quiet_;
  bool terminal_;
  std::FILE* stream_;
  long last_decile_ = -1;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  bool finished_ = false;
};

}  // namespace tirstrain
