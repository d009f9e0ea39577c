#include "capture/recorder.hpp"

#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {

ImageFormat parse_image_format(const std::string& name, const std::string& key) {
  if (name == "png") return ImageFormat::kPng;
  if (name == "tiff" || name == "tif") return ImageFormat::kTiff;
  if (name == "pgm") return ImageFormat::kPgm;
  throw Error("unknown image format '" + name + "' (lossless choices: png, tiff, pgm)", {.key = key});
}

const char* extension_of(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPng:
      return ".png";
    case ImageFormat::kTiff:
      return ".tif";
    case ImageFormat::kPgm:
      return ".pgm";
  }
  return ".png";
}

namespace {

namespace fs = std::filesystem;

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string json_escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\u%04x", c);
          out += buffer;
        } else {
          out += c;
        }
    }
  }
  return out;
}

// Built by appending: GCC 12 reports a false -Wrestrict for "\"" + std::string&& at -O2.
std::string json_string(const std::string& text) {
  std::string out(1, '"');
  out += json_escape(text);
  out += '"';
  return out;
}

// Binary PGM is the cheapest lossless container there is: a text header and the samples (16-bit ones
// big-endian, as the format requires).
void encode_pgm(const cv::Mat& image, std::vector<unsigned char>& out) {
  const bool wide = image.depth() == CV_16U;
  const std::string header = "P5\n" + std::to_string(image.cols) + " " + std::to_string(image.rows) + "\n" +
                             (wide ? "65535" : "255") + "\n";
  const std::size_t row_bytes = static_cast<std::size_t>(image.cols) * image.elemSize();
  out.resize(header.size() + row_bytes * static_cast<std::size_t>(image.rows));
  std::memcpy(out.data(), header.data(), header.size());
  unsigned char* dst = out.data() + header.size();
  for (int y = 0; y < image.rows; ++y, dst += row_bytes) {
    const unsigned char* src = image.ptr<unsigned char>(y);
    if (!wide) {
      std::memcpy(dst, src, row_bytes);
    } else {
      for (std::size_t i = 0; i < row_bytes; i += 2) {
        dst[i] = src[i + 1];
        dst[i + 1] = src[i];
      }
    }
  }
}

// Writes `head` then `data` to `path` through "<path>.partial" + rename, so a reader never sees half a frame.
// Returns an empty string on success, else what went wrong (errno text: "No space left on device", ...).
std::string write_file_atomically(const std::string& path, const unsigned char* data, std::size_t size,
                                  const std::string& head = {}) {
  const std::string partial = path + ".partial";
  const int fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return std::strerror(errno);
  // One writev for header and pixels: no copy of the frame into an encode buffer.
  std::size_t done = 0;
  const std::size_t total = head.size() + size;
  while (done < total) {
    iovec parts[2];
    int count = 0;
    if (done < head.size()) parts[count++] = {const_cast<char*>(head.data()) + done, head.size() - done};
    const std::size_t data_done = done > head.size() ? done - head.size() : 0;
    parts[count++] = {const_cast<unsigned char*>(data) + data_done, size - data_done};
    const ssize_t n = ::writev(fd, parts, count);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string reason = n < 0 ? std::strerror(errno) : "short write";
      ::close(fd);
      ::unlink(partial.c_str());
      return reason;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) {
    const std::string reason = std::strerror(errno);
    ::unlink(partial.c_str());
    return reason;
  }
  if (::rename(partial.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    ::unlink(partial.c_str());
    return reason;
  }
  return {};
}

struct Job {
  std::int64_t sequence = 0;  // order of arrival: rows are committed in this order
  std::int64_t position = 0;  // index column and file number
  Frame frame;
  std::size_t bytes = 0;
  bool save = false;
};

struct Done {
  Job job;
  bool saved = false;
  std::string image_path;
  std::int64_t bytes = 0;
};

class Recording {
 public:
  Recording(const RecordOptions& options, FrameSource& source) : options_(options), source_(source) {
    if (options.out_dir.empty()) throw Error("no output folder given", {.key = options.out_option});
    if (options.png_level < 0 || options.png_level > 9)
      throw Error("PNG compression level must be 0..9, got " + std::to_string(options.png_level),
                  {.key = "--png-level"});
    if (options.writer_threads < 1 || options.writer_threads > 64)
      throw Error("writer threads must be 1..64", {.key = "--writers"});
    choose_folder(options);
    frames_dir_ = root_ / "frames";
    csv_path_ = (root_ / "frames.csv").string();
    std::error_code ec;
    fs::create_directories(frames_dir_, ec);
    if (ec)
      throw Error("cannot create folder: " + ec.message(),
                  {.file = frames_dir_.string(), .key = options.out_option});
    csv_fd_ = ::open(csv_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
    if (csv_fd_ < 0)
      throw Error(std::string("cannot create file: ") + std::strerror(errno), {.file = csv_path_});
    const std::string header =
        "index,t_s,device_frame_id,device_time_s,host_time_s,status,frames_lost_before,received,saved\n";
    if (!append_csv(header)) throw Error("cannot write: " + failure_, {.file = csv_path_});
    for (int i = 0; i < options.writer_threads; ++i) writers_.emplace_back([this] { writer_loop(); });
  }

  ~Recording() {
    close_queue();
    for (auto& writer : writers_)
      if (writer.joinable()) writer.join();
    if (csv_fd_ >= 0) ::close(csv_fd_);
  }

  Recording(const Recording&) = delete;
  Recording& operator=(const Recording&) = delete;

  RecordReport run() {
    start_s_ = steady_now_s();
    double last_progress_s = start_s_;
    std::int64_t received_at_last_progress = 0;
    std::int64_t lost_at_last_progress = 0;
    Frame frame;
    for (;;) {
      if (options_.stop != nullptr && options_.stop->load()) {
        report_.stop_reason = "interrupted";
        break;
      }
      if (options_.max_frames >= 0 && report_.counts.frames_received >= options_.max_frames) {
        report_.stop_reason = "frames";
        break;
      }
      const double now_s = steady_now_s();
      if (options_.max_seconds >= 0 && now_s - start_s_ >= options_.max_seconds) {
        report_.stop_reason = "seconds";
        break;
      }
      if (writer_failed()) {
        report_.stop_reason = "write error";
        break;
      }
      if (options_.on_progress && now_s - last_progress_s >= 1.0) {
        RecordProgress progress = snapshot();
        progress.receive_rate_hz = static_cast<double>(progress.frames_received - received_at_last_progress) /
                                   (now_s - last_progress_s);
        received_at_last_progress = progress.frames_received;
        last_progress_s = now_s;
        options_.on_progress(progress);
      }
      FrameSource::Poll result = FrameSource::Poll::kTimeout;
      try {
        result = source_.poll(frame, 0.1);
      } catch (const Error& e) {
        report_.stop_reason = "source error";
        report_.error = e.what();
        break;
      }
      if (result == FrameSource::Poll::kEnd) {
        report_.stop_reason = "end of stream";
        break;
      }
      if (result == FrameSource::Poll::kTimeout) continue;
      accept(std::move(frame));
      frame = Frame{};
      const std::int64_t lost = report_.counts.frames_lost_device + report_.counts.frames_dropped_host;
      if (options_.on_progress && lost != lost_at_last_progress) {
        lost_at_last_progress = lost;
        options_.on_progress(snapshot());
      }
    }
    close_queue();
    for (auto& writer : writers_) writer.join();
    writers_.clear();
    {
      std::lock_guard lock(mutex_);
      commit_ready_rows();
      if (!failure_.empty() && report_.error.empty()) {
        report_.error = failure_;
        if (report_.stop_reason != "source error") report_.stop_reason = "write error";
      }
    }
    report_.elapsed_s = steady_now_s() - start_s_;
    report_.counts.elapsed_s = report_.elapsed_s;
    write_summary();
    report_.folder = root_.string();
    if (staged_) swap_in();
    return report_;
  }

 private:
  // A new folder is recorded in place. An earlier recording (--overwrite) stays whole until the new one
  // ends: the new one is recorded beside it in "<DIR>.partial" and swapped in then, so a crash or a kill at
  // any instant loses neither (captured frames are never deleted, not even those of an unfinished run).
  void choose_folder(const RecordOptions& options) {
    std::string dir = fs::path(options.out_dir).lexically_normal().string();
    while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
    final_dir_ = dir;
    for (const std::string& input : options.input_paths)
      if (path_is_within(input, dir))
        throw Error("the output folder " + std::string(path_is_within(dir, input) ? "is" : "contains") +
                        " the input " + input + "; record into a folder of its own",
                    {.file = options.out_dir, .key = options.out_option});
    const fs::path final_root(dir);
    const bool existing = fs::exists(final_root / "frames") || fs::exists(final_root / "frames.csv") ||
                          fs::exists(final_root / "recording.json");
    if (existing && !options.overwrite)
      throw Error(
          "already holds a recording (frames/, frames.csv); choose another folder or pass --overwrite",
          {.file = options.out_dir, .key = options.out_option});
    // The earlier recording's folder is replaced as a whole: anything else in it would go with it.
    if (existing)
      check_replaceable_output(dir, {"frames", "frames.csv", "recording.json"}, "record", options.out_option);
    staged_ = existing;
    root_ = staged_ ? fs::path(dir + ".partial") : final_root;
    if (staged_ && fs::exists(root_))
      throw Error(
          "holds the unfinished recording of an earlier run; move it away or delete it, then record again "
          "(the recording in " +
              dir + " is untouched)",
          {.file = root_.string(), .key = options.out_option});
    ensure_output_dir(root_.string(), options.out_option);
  }

  // The finished recording replaces the earlier one. After a write error both are kept and the error
  // says where.
  void swap_in() {
    if (!report_.error.empty()) {
      report_.error +=
          " (the new recording is kept in " + root_.string() + ", the earlier one in " + final_dir_ + ")";
      return;
    }
    try {
      swap_in_directory(root_.string(), final_dir_);
      report_.folder = final_dir_;
    } catch (const Error& e) {
      report_.error = std::string(e.what()) + " (the new recording is kept in " + root_.string() + ")";
    }
  }

  RecordProgress snapshot() {
    std::lock_guard lock(mutex_);
    RecordProgress progress = report_.counts;
    progress.queue_frames = static_cast<std::int64_t>(queue_.size());
    progress.elapsed_s = steady_now_s() - start_s_;
    return progress;
  }

  void accept(Frame&& frame) {
    RecordProgress& counts = report_.counts;
    ++counts.frames_received;
    counts.frames_lost_device += frame.frames_lost_before;
    if (frame.status == FrameStatus::kIncomplete) ++counts.frames_incomplete;
    // The time origin comes from the first frame that has a time of its own (an incomplete frame without an
    // id has no device timestamp either).
    if (!have_first_ && !(frame.device_frame_id < 0 && frame.status == FrameStatus::kIncomplete)) {
      have_first_ = true;
      first_device_time_s_ = frame.device_time_s;
      first_host_time_s_ = frame.host_time_s;
    }
    // A frame without an id carries no device time either: its row gives the host's arrival time, put on
    // the device's clock by the two clocks' offset at the first frame (docs/capture.md).
    if (have_first_ && frame.device_frame_id < 0 && frame.status == FrameStatus::kIncomplete)
      frame.device_time_s = first_device_time_s_ + (frame.host_time_s - first_host_time_s_);
    // Positions follow the device counter so that lost frames leave holes in the file numbers.
    const bool unidentified =
        frame.device_frame_id < 0 && frame.status == FrameStatus::kIncomplete && have_ids_;
    if (frame.device_frame_id >= 0 && !have_ids_) {
      have_ids_ = true;
      first_device_id_ = frame.device_frame_id - (have_position_ ? last_position_ + 1 : 0);
    }
    std::int64_t position = frame.device_frame_id >= 0 && have_ids_
                                ? frame.device_frame_id - first_device_id_
                                : last_position_ + 1 + frame.frames_lost_before + pending_lost_;
    // A frame delivered late (frames_lost_before -1: counted as lost when newer frames came first) takes the
    // place that was left empty for it; anything else that goes backwards (a camera that restarted its
    // counter) continues after the last position so that no file is overwritten. An incomplete frame whose
    // id the camera could not tell (no image is stored for it) gets a negative index of its own.
    const bool late = frame.frames_lost_before < 0 && position >= 0 && position < last_position_;
    if (unidentified) {
      position = -(++unidentified_);
    } else if (!late) {
      if (have_position_ && position <= last_position_) position = last_position_ + 1;
      have_position_ = true;
      last_position_ = position;
    }
    if (options_.on_frame) options_.on_frame(frame);

    Job job;
    job.sequence = next_sequence_++;
    job.position = position;
    job.save = frame.status != FrameStatus::kIncomplete && !frame.image.empty();
    job.bytes = job.save ? frame.image.total() * frame.image.elemSize() : 0;
    // Frames dropped here before this one (and the device losses they carried) are reported on it.
    const bool carries = !late && !unidentified;
    if (carries && pending_lost_ > 0) {
      frame.frames_lost_before += pending_lost_;
      if (pending_host_drops_ > 0 && frame.status != FrameStatus::kIncomplete)
        frame.status = FrameStatus::kOverrun;
    }
    job.frame = std::move(frame);
    if (!job.save) job.frame.image.release();

    std::unique_lock lock(mutex_);
    if (job.save && queued_bytes_ + job.bytes > options_.queue_bytes && !queue_.empty()) {
      // The disk cannot keep up: drop here, loudly counted, rather than stall the camera's buffers.
      ++counts.frames_dropped_host;
      ++pending_host_drops_;
      // Its row is not written: what it reported (itself, and the losses before it) goes to the next row.
      pending_lost_ = (carries ? 0 : pending_lost_) + job.frame.frames_lost_before + 1;
      --next_sequence_;
      return;
    }
    if (carries) {
      pending_host_drops_ = 0;
      pending_lost_ = 0;
    }
    queued_bytes_ += job.bytes;
    queue_.push_back(std::move(job));
    report_.max_queue_frames =
        std::max<std::int64_t>(report_.max_queue_frames, static_cast<std::int64_t>(queue_.size()));
    lock.unlock();
    queue_ready_.notify_one();
  }

  bool writer_failed() {
    std::lock_guard lock(mutex_);
    return !failure_.empty();
  }

  void close_queue() {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    queue_ready_.notify_all();
  }

  void writer_loop() {
    std::vector<unsigned char> encoded;
    const std::vector<int> png_params = {cv::IMWRITE_PNG_COMPRESSION, options_.png_level};
    const std::vector<int> tiff_params = {cv::IMWRITE_TIFF_COMPRESSION, 1};  // 1 = none
    for (;;) {
      Job job;
      {
        std::unique_lock lock(mutex_);
        queue_ready_.wait(lock, [this] { return closed_ || !queue_.empty(); });
        if (queue_.empty()) return;
        job = std::move(queue_.front());
        queue_.pop_front();
        queued_bytes_ -= job.bytes;
      }
      Done done;
      done.job = std::move(job);
      const bool skip = [this] {
        std::lock_guard lock(mutex_);
        return !failure_.empty();
      }();
      if (done.job.save && !skip) {
        char name[32];
        std::snprintf(name, sizeof(name), "%06lld", static_cast<long long>(done.job.position));
        done.image_path = (frames_dir_ / (std::string(name) + extension_of(options_.format))).string();
        std::string reason;
        std::size_t file_bytes = 0;
        try {
          switch (options_.format) {
            case ImageFormat::kPng:
              cv::imencode(".png", done.job.frame.image, encoded, png_params);
              break;
            case ImageFormat::kTiff:
              cv::imencode(".tiff", done.job.frame.image, encoded, tiff_params);
              break;
            case ImageFormat::kPgm:
              if (done.job.frame.image.depth() == CV_8U && done.job.frame.image.isContinuous()) {
                encoded.clear();  // 8-bit PGM is a header and the pixels as they are: written in place below
              } else {
                encode_pgm(done.job.frame.image, encoded);
              }
              break;
          }
          if (options_.format == ImageFormat::kPgm && encoded.empty()) {
            const cv::Mat& image = done.job.frame.image;
            const std::string header =
                "P5\n" + std::to_string(image.cols) + " " + std::to_string(image.rows) + "\n255\n";
            reason = write_file_atomically(done.image_path, image.data, image.total(), header);
            file_bytes = header.size() + image.total();
          } else {
            reason = write_file_atomically(done.image_path, encoded.data(), encoded.size());
            file_bytes = encoded.size();
          }
        } catch (const cv::Exception& e) {
          reason = std::string("cannot encode: ") + e.what();
        }
        if (reason.empty()) {
          done.saved = true;
          done.bytes = static_cast<std::int64_t>(file_bytes);
        } else {
          std::lock_guard lock(mutex_);
          ++report_.frames_not_saved;  // the frame whose write failed is one of them
          if (failure_.empty())
            failure_ = format_error("cannot write frame " + std::to_string(done.job.position) + ": " + reason,
                                    {.file = done.image_path});
        }
      } else if (done.job.save) {
        std::lock_guard lock(mutex_);
        ++report_.frames_not_saved;
      }
      done.job.frame.image.release();
      std::lock_guard lock(mutex_);
      finished_.emplace(done.job.sequence, std::move(done));
      commit_ready_rows();
    }
  }

  // Appends rows in arrival order once every earlier frame is finished. Caller holds mutex_.
  void commit_ready_rows() {
    std::string rows;
    std::vector<std::string> images;
    std::vector<const Done*> batch;
    auto it = finished_.begin();
    while (it != finished_.end() && it->first == next_commit_) {
      const Done& done = it->second;
      if (done.saved || !done.job.save) {
        const Frame& f = done.job.frame;
        rows += std::to_string(done.job.position) + "," +
                format_double(f.device_time_s - first_device_time_s_) + "," +
                std::to_string(f.device_frame_id) + "," + format_double(f.device_time_s) + "," +
                format_double(f.host_time_s - first_host_time_s_) + "," +
                std::to_string(static_cast<int>(f.status)) + "," + std::to_string(f.frames_lost_before) +
                "," + std::to_string(f.index) + "," + (done.saved ? "1" : "0") + "\n";
        if (done.saved) images.push_back(done.image_path);
        batch.push_back(&done);
      }
      ++next_commit_;
      ++it;
    }
    if (!rows.empty()) {
      if (append_csv(rows)) {
        for (const Done* done : batch) {
          if (done->saved) {
            ++report_.counts.frames_saved;
            report_.bytes_written += done->bytes;
          }
        }
      } else {
        // A frame without its row would be invisible to readers' time axis: take the images back out.
        for (const auto& image : images) ::unlink(image.c_str());
        report_.frames_not_saved += static_cast<std::int64_t>(images.size());
      }
    }
    finished_.erase(finished_.begin(), it);
  }

  // Caller holds mutex_ (or is the constructor). On failure the file is cut back to its last complete row.
  bool append_csv(const std::string& text) {
    if (csv_fd_ < 0 || !failure_.empty()) return false;
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t n = ::write(csv_fd_, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        failure_ = format_error(
            std::string("cannot append to frames.csv: ") + (n < 0 ? std::strerror(errno) : "short write"),
            {.file = csv_path_});
        if (::ftruncate(csv_fd_, static_cast<off_t>(csv_bytes_)) != 0) {
          // Nothing more can be done; the message above already says the disk refused.
        }
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    csv_bytes_ += text.size();
    return true;
  }

  void write_summary() {
    const RecordProgress& c = report_.counts;
    std::string json = "{\n";
    json += "  \"format\": \"tirstrain-recording\",\n  \"version\": 1,\n";
    json += "  \"source\": " + json_string(source_.describe()) + ",\n";
    json += "  \"settings\": {";
    bool first = true;
    for (const auto& [key, value] : source_.settings()) {
      json += std::string(first ? "\n" : ",\n") + "    " + json_string(key) + ": " + json_string(value);
      first = false;
    }
    json += "\n  },\n";
    json += "  \"requested_settings\": {";
    first = true;
    for (const auto& [key, value] : options_.requested_settings) {
      json += std::string(first ? "\n" : ",\n") + "    " + json_string(key) + ": " + json_string(value);
      first = false;
    }
    json += first ? "},\n" : "\n  },\n";
    json += "  \"image_format\": " + json_string(extension_of(options_.format) + 1) + ",\n";
    json += "  \"png_level\": " + std::to_string(options_.png_level) + ",\n";
    json += "  \"frames_received\": " + std::to_string(c.frames_received) + ",\n";
    json += "  \"frames_saved\": " + std::to_string(c.frames_saved) + ",\n";
    json += "  \"frames_incomplete\": " + std::to_string(c.frames_incomplete) + ",\n";
    json += "  \"frames_lost_device\": " + std::to_string(c.frames_lost_device) + ",\n";
    json += "  \"frames_dropped_host\": " + std::to_string(c.frames_dropped_host) + ",\n";
    json += "  \"frames_not_saved\": " + std::to_string(report_.frames_not_saved) + ",\n";
    json += "  \"bytes_written\": " + std::to_string(report_.bytes_written) + ",\n";
    json += "  \"max_queue_frames\": " + std::to_string(report_.max_queue_frames) + ",\n";
    json += "  \"elapsed_s\": " + format_double(report_.elapsed_s) + ",\n";
    json += "  \"stop_reason\": " + json_string(report_.stop_reason) + ",\n";
    json += "  \"error\": " + json_string(report_.error) + ",\n";
    json +=
        "  \"status_codes\": {\"0\": \"ok\", \"1\": \"incomplete (no image saved)\", \"2\": \"corrupt\", "
        "\"3\": \"gap_before (frames_lost_before lost in the device or network)\", "
        "\"4\": \"overrun (frames_lost_before dropped by the host)\"}\n}\n";
    try {
      write_text_file((root_ / "recording.json").string(), json);
    } catch (const Error& e) {
      // The frames and frames.csv are what matter; a full disk may refuse this last small file, which is
      // said (process then calls the recording unfinished, and says so too).
      const std::string missing =
          std::string(e.what()) +
          " (no recording.json: the frames and frames.csv are complete up to the last "
          "row, but process will call the recording unfinished)";
      report_.error = report_.error.empty() ? missing : report_.error + "; " + missing;
    }
  }

  const RecordOptions& options_;
  FrameSource& source_;
  fs::path root_;          // where this run records: the output folder, or its staging folder
  std::string final_dir_;  // the output folder
  bool staged_ = false;    // recording beside an earlier recording, swapped in at the end
  fs::path frames_dir_;
  std::string csv_path_;
  int csv_fd_ = -1;
  std::size_t csv_bytes_ = 0;
  RecordReport report_;
  double start_s_ = 0.0;

  bool have_first_ = false;
  double first_device_time_s_ = 0.0;
  double first_host_time_s_ = 0.0;
  std::int64_t first_device_id_ = -1;
  bool have_position_ = false;
  std::int64_t last_position_ = -1;
  std::int64_t pending_host_drops_ = 0;
  std::int64_t pending_lost_ = 0;  // frames missing before the next row that no row has reported yet
  bool have_ids_ = false;          // the source numbers its frames (device_frame_id >= 0)
  std::int64_t unidentified_ = 0;  // incomplete frames without a device id so far
  std::int64_t next_sequence_ = 0;

  std::mutex mutex_;
  std::condition_variable queue_ready_;
  std::deque<Job> queue_;
  std::size_t queued_bytes_ = 0;
  bool closed_ = false;
  std::string failure_;
  std::map<std::int64_t, Done> finished_;
  std::int64_t next_commit_ = 0;
  std::vector<std::thread> writers_;
};

}  // namespace

RecordReport record(FrameSource& source, const RecordOptions& options) {
  Recording recording(options, source);
  return recording.run();
}

}  // namespace tirstrain::capture
