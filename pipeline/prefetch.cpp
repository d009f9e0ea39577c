#include "pipeline/prefetch.hpp"

namespace tirstrain::pipeline {

PrefetchingReader::PrefetchingReader(capture::FrameSource& source, std::size_t capacity)
    : source_(source), capacity_(std::max<std::size_t>(1, capacity)), thread_([this] { run(); }) {}

PrefetchingReader::~PrefetchingReader() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void PrefetchingReader::run() {
  try {
    while (true) {
      {
        std::unique_lock lock(mutex_);
        changed_.wait(lock, [&] { return stop_ || queue_.size() < capacity_; });
        if (stop_) break;
      }
      std::optional<capture::Frame> frame = source_.next();
      std::lock_guard lock(mutex_);
      if (!frame) break;
      queue_.push_back(std::move(*frame));
      changed_.notify_all();
    }
  } catch (...) {
    std::lock_guard lock(mutex_);
    error_ = std::current_exception();
  }
  std::lock_guard lock(mutex_);
  finished_ = true;
  changed_.notify_all();
}

std::optional<capture::Frame> PrefetchingReader::next() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return !queue_.empty() || finished_; });
  if (!queue_.empty()) {
    capture::Frame frame = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();
    return frame;
  }
  if (error_) std::rethrow_exception(error_);
  return std::nullopt;
}

}  // namespace tirstrain::pipeline
