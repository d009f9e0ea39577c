#pragma once
// Decoding overlapped with analysis: a reader thread pulls frames from a FrameSource into a small bounded
// queue (memory stays at `capacity` frames). Errors thrown by the source are re-thrown, in order, by next().
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "capture/frame_source.hpp"

namespace tirstrain::pipeline {

class PrefetchingReader {
 public:
  PrefetchingReader(capture::FrameSource& source, std::size_t capacity);
  ~PrefetchingReader();
  PrefetchingReader(const PrefetchingReader&) = delete;
  PrefetchingReader& operator=(const PrefetchingReader&) = delete;

  std::optional<capture::Frame> next();

 private:
  void run();

  capture::FrameSource& source_;
  std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<capture::Frame> queue_;
  std::exception_ptr error_;
  bool finished_ = false;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace tirstrain::pipeline
