#include "core/progress.hpp"

#include <unistd.h>

#include <algorithm>

namespace tirstrain {

Progress::Progress(std::string label, long total, bool quiet, std::FILE* stream)
    : label_(std::move(label)),
      total_(std::max(1L, total)),
      quiet_(quiet),
      terminal_(isatty(fileno(stream)) != 0),
      stream_(stream),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

void Progress::update(long done) {
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  const double elapsed_s = std::chrono::duration<double>(now - start_).count();
  const double fraction = std::clamp(static_cast<double>(done) / static_cast<double>(total_), 0.0, 1.0);
  if (terminal_) {
    if (done < total_ && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    const int width = 30;
    const int filled = static_cast<int>(fraction * width);
    const double rate = elapsed_s > 0 ? static_cast<double>(done) / elapsed_s : 0.0;
    std::fprintf(stream_, "\r%s [%.*s%*s] %ld/%ld  %.1f/s ", label_.c_str(), filled,
                 "##############################", width - filled, "", done, total_, rate);
    std::fflush(stream_);
  } else {
    const long decile = static_cast<long>(fraction * 10.0);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    std::fprintf(stream_, "%s: %ld/%ld (%ld%%) after %.1f s\n", label_.c_str(), done, total_, decile * 10,
                 elapsed_s);
  }
}

void Progress::finish() {
  if (quiet_ || finished_) return;
  finished_ = true;
  update(total_);
  if (terminal_) std::fprintf(stream_, "\n");
}

}  // namespace tirstrain
