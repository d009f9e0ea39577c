#include "capture/file_sources.hpp"

#include <fnmatch.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>

#include <nlohmann/json.hpp>

#include "capture/file_formats.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

double host_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

// The last run of digits in a file stem ("img_000042" -> 42), or -1: the file's own frame number, which
// links it to its row in frames.csv and reveals frames missing from the sequence.
std::int64_t trailing_number(const std::string& stem) {
  std::size_t end = stem.size();
  while (end > 0 && !std::isdigit(static_cast<unsigned char>(stem[end - 1]))) --end;
  std::size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end || end - begin > 15) return -1;
  return std::stoll(stem.substr(begin, end - begin));
}

bool has_glob_chars(const std::string& text) {
  return text.find_first_of("*?[") != std::string::npos;
}

// A printf integer conversion in a file name ("img_%06d.png"): what surrounds it and how it pads.
struct PrintfSpec {
  std::string prefix, suffix;
  bool zero_pad = false;
  std::size_t width = 0;
};

std::optional<PrintfSpec> parse_printf(const std::string& text) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '%') continue;
    std::size_t j = i + 1;
    PrintfSpec spec;
    if (j < text.size() && text[j] == '0') {
      spec.zero_pad = true;
      ++j;
    }
    const std::size_t digits = j;
    while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) ++j;
    if (j > digits) spec.width = std::stoul(text.substr(digits, j - digits));
    while (j < text.size() && text[j] == 'l') ++j;
    if (j < text.size() && text[j] == 'd') {
      spec.prefix = text.substr(0, i);
      spec.suffix = text.substr(j + 1);
      return spec;
    }
  }
  return std::nullopt;
}

bool has_printf_spec(const std::string& text) {
  return parse_printf(text).has_value();
}

// Exact inverse of printf: the digits between prefix and suffix, formatted back, must give the name.
bool matches_printf(const PrintfSpec& spec, const std::string& name) {
  if (name.size() <= spec.prefix.size() + spec.suffix.size()) return false;
  if (name.compare(0, spec.prefix.size(), spec.prefix) != 0) return false;
  if (name.compare(name.size() - spec.suffix.size(), spec.suffix.size(), spec.suffix) != 0) return false;
  const std::string middle =
      name.substr(spec.prefix.size(), name.size() - spec.prefix.size() - spec.suffix.size());
  if (middle.size() > 15 ||
      !std::all_of(middle.begin(), middle.end(), [](unsigned char c) { return std::isdigit(c); }))
    return false;
  std::string formatted = std::to_string(std::stoll(middle));
  if (formatted.size() < spec.width)
    formatted.insert(0, spec.width - formatted.size(), spec.zero_pad ? '0' : ' ');
  return formatted == middle;
}

struct SequenceFile {
  std::string path;
  std::int64_t number = -1;  // from the file name; -1 when it has none
};

std::vector<SequenceFile> make_sequence(std::vector<std::string> paths) {
  std::sort(paths.begin(), paths.end(), natural_less);
  std::vector<SequenceFile> files;
  files.reserve(paths.size());
  for (auto& p : paths) {
    const std::int64_t number = trailing_number(fs::path(p).stem().string());
    files.push_back({std::move(p), number});
  }
  return files;
}

// Converts a decoded image to the grey 8/16-bit layout every consumer expects.
cv::Mat to_grey(const cv::Mat& decoded, const std::string& path, std::int64_t index) {
  if (decoded.depth() != CV_8U && decoded.depth() != CV_16U)
    throw Error("unsupported pixel type (expected 8- or 16-bit grey or colour images)",
                {.file = path, .frame = index});
  switch (decoded.channels()) {
    case 1:
      return decoded;
    case 3: {
      cv::Mat grey;
      cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY);
      return grey;
    }
    case 4: {
      cv::Mat grey;
      cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY);
      return grey;
    }
    default:
      throw Error(
          "unsupported channel count " + std::to_string(decoded.channels()) + " (expected grey, BGR or BGRA)",
          {.file = path, .frame = index});
  }
}

std::string size_text(const cv::Size& size) {
  return std::to_string(size.width) + "x" + std::to_string(size.height);
}

// A JPEG ends with its end-of-image marker (FF D9). libjpeg decodes a file cut short anyway, fills the
// missing rows with grey and only prints a warning, so a cut file would pass for a frame: its tail is
// checked (some writers append a few bytes after the marker, hence the last 4 KiB).
bool jpeg_is_cut_short(const std::string& path) {
  std::string extension = fs::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".jpg" && extension != ".jpeg") return false;
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return false;  // the decoder reports an unreadable file
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 4096);
  std::string bytes(static_cast<std::size_t>(tail), '\0');
  in.seekg(size - tail);
  in.read(bytes.data(), tail);
  return bytes.find("\xFF\xD9") == std::string::npos;
}

// The decoded image, or an empty one when the file cannot be decoded: OpenCV's decoders throw on some
// malformed headers (a TIFF 0 pixels wide) where others return nothing, and either is a corrupt frame.
cv::Mat read_image(const std::string& path) {
  if (jpeg_is_cut_short(path)) return {};
  try {
    return cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    return {};
  }
}

// `tirstrain record` from a source without a clock writes the frame number as t_s in its frames.csv and
// says so in the recording.json beside it: such times were never measured.
bool recording_has_no_clock(const std::string& frames_csv) {
  std::ifstream in(fs::path(frames_csv).parent_path() / "recording.json");
  if (!in) return false;
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (!j.is_object() || !j.contains("settings") || !j["settings"].is_object()) return false;
  return j["settings"].value("time_measured", std::string("true")) == "false";
}

// A frame rate given on the command line: a positive, finite number of Hz.
double checked_rate_Hz(double rate_Hz) {
  if (!(rate_Hz > 0.0) || !std::isfinite(rate_Hz))
    throw Error("the frame rate must be a positive number of Hz, not " + format_double(rate_Hz),
                {.key = "--frame-rate-Hz"});
  return rate_Hz;
}

class ImageSequenceSource final : public FrameSource {
 public:
  ImageSequenceSource(std::vector<SequenceFile> files, std::string description,
                      const std::optional<std::string>& times_csv, const FileSourceOptions& options)
      : files_(std::move(files)), description_(std::move(description)) {
    const bool clockless = times_csv && recording_has_no_clock(*times_csv);
    if (times_csv && options.frame_rate_Hz && !clockless)
      throw Error("--frame-rate-Hz was given but " + *times_csv +
                      " times the frames already; a recording has one clock: drop one of them",
                  {.file = *times_csv, .key = "--frame-rate-Hz"});
    if (clockless) {
      // Its rows still say which frames were lost; its t_s, the frame number, is timed by the rate if given.
      load_times(*times_csv);
      times_csv_.clear();
      time_source_ = "none: " + *times_csv +
                     " holds the frame number as t_s (recording.json: the recorded source had no clock)";
      if (options.frame_rate_Hz) {
        const double rate_Hz = checked_rate_Hz(*options.frame_rate_Hz);
        for (double& t : times_s_) t /= rate_Hz;
        time_source_ =
            "frame number in " + *times_csv + " / " + format_double(rate_Hz) + " Hz (--frame-rate-Hz)";
        rate_timed_ = true;
      }
    } else if (times_csv) {
      load_times(*times_csv);
    } else if (options.frame_rate_Hz) {
      const double rate_Hz = checked_rate_Hz(*options.frame_rate_Hz);
      time_source_ = "frame number / " + format_double(rate_Hz) + " Hz (--frame-rate-Hz)";
      rate_timed_ = true;
      times_s_.resize(files_.size());
      for (std::size_t i = 0; i < files_.size(); ++i) times_s_[i] = static_cast<double>(i) / rate_Hz;
    } else {
      // No clock anywhere: the frame number is the only honest axis, and it is labelled as such.
      time_source_ = "none (no frames.csv found): t_s is the frame number, not a measured time";
      times_s_.resize(files_.size());
      for (std::size_t i = 0; i < files_.size(); ++i) times_s_[i] = static_cast<double>(i);
    }
  }

  std::optional<Frame> next() override {
    if (next_ >= files_.size()) return std::nullopt;
    const std::size_t i = next_++;
    const SequenceFile& file = files_[i];
    Frame frame;
    frame.index = static_cast<std::int64_t>(i);
    frame.device_frame_id = file.number >= 0 ? file.number : frame.index;
    frame.device_time_s = times_s_[i];
    frame.host_time_s = host_now_s();
    frame.origin = file.path;
    if (i > 0 && numbered_ && file.number > files_[i - 1].number + 1) {
      frame.frames_lost_before = file.number - files_[i - 1].number - 1;
      frame.status = FrameStatus::kGapBefore;
    }
    refuse_multi_page(file.path, frame.index);
    const cv::Mat decoded = read_image(file.path);
    if (decoded.empty()) {
      frame.status = FrameStatus::kCorrupt;
      return frame;
    }
    frame.image = to_grey(decoded, file.path, frame.index);
    if (!size_) {
      size_ = frame.image.size();
      depth_ = frame.image.depth();
    } else if (frame.image.size() != *size_) {
      throw Error("frame is " + size_text(frame.image.size()) + " but the first frame was " +
                      size_text(*size_) + "; all frames of a sequence must have the same size",
                  {.file = file.path, .frame = frame.index});
    } else if (frame.image.depth() != depth_) {
      throw Error("frame bit depth differs from the first frame's; all frames must have the same depth",
                  {.file = file.path, .frame = frame.index});
    }
    return frame;
  }

  std::int64_t frame_count() const override { return static_cast<std::int64_t>(files_.size()); }

  std::string describe() const override {
    return description_ + " (" + std::to_string(files_.size()) + " frames; time: " + time_source_ + ")";
  }

  std::map<std::string, std::string> settings() const override {
    return {{"kind", "image_sequence"},
            {"first_file", files_.front().path},
            {"frames", std::to_string(files_.size())},
            {"time_source", time_source_},
            {"time_measured", times_csv_.empty() && !rate_timed_ ? "false" : "true"},
            {"rows_after_last_image", std::to_string(rows_after_last_image_)}};
  }

 private:
  void load_times(const std::string& csv) {
    const CsvTable table = read_numeric_csv(csv);
    const std::vector<double>& t_s = table.column("t_s");
    numbered_ =
        std::all_of(files_.begin(), files_.end(), [](const SequenceFile& f) { return f.number >= 0; });
    std::vector<std::size_t> row_of(files_.size());
    bool mapped = false;
    if (table.has("index")) {
      const std::vector<double>& index = table.column("index");
      std::map<std::int64_t, std::size_t> rows;
      for (std::size_t r = 0; r < index.size(); ++r) {
        const auto key = static_cast<std::int64_t>(index[r]);
        if (static_cast<double>(key) != index[r] || !rows.emplace(key, r).second)
          throw Error("index must be distinct whole frame numbers",
                      {.file = csv, .row = static_cast<long>(r) + 2, .column = "index"});
      }
      // Rows are matched to files by the number in the file name (so a missing file is a lost frame), also
      // when the names count from another origin than the index (000001.png for index 0); by position only
      // when the names carry no numbers, or when the numbers match no origin and there are exactly as many
      // rows as files (otherwise a lost file would shift every later frame's time).
      if (numbered_) {
        const std::int64_t origin = files_.front().number - rows.begin()->first;
        for (const std::int64_t offset : {std::int64_t{0}, origin}) {
          mapped = std::all_of(files_.begin(), files_.end(),
                               [&](const SequenceFile& f) { return rows.count(f.number - offset); });
          if (!mapped) continue;
          for (std::size_t i = 0; i < files_.size(); ++i) row_of[i] = rows.at(files_[i].number - offset);
          // Rows past the last image: frames recorded whose files are gone (no later frame counts them).
          rows_after_last_image_ = static_cast<std::int64_t>(
              std::distance(rows.upper_bound(files_.back().number - offset), rows.end()));
          break;
        }
        if (!mapped && rows.size() != files_.size()) refuse_unmatched(csv, rows, origin);
      }
      if (!mapped) {
        numbered_ = false;
        for (std::size_t i = 0; i < files_.size(); ++i) {
          const auto it = rows.find(static_cast<std::int64_t>(i));
          if (it == rows.end())
            throw Error("no row with index " + std::to_string(i) + " for image " + files_[i].path,
                        {.file = csv, .frame = static_cast<long>(i), .column = "index"});
          row_of[i] = it->second;
        }
      }
    } else {
      numbered_ = false;
      if (t_s.size() != files_.size())
        throw Error("has " + std::to_string(t_s.size()) + " rows but there are " +
                        std::to_string(files_.size()) +
                        " images (add an 'index' column to match rows to files)",
                    {.file = csv, .column = "t_s"});
      for (std::size_t i = 0; i < files_.size(); ++i) row_of[i] = i;
    }
    times_s_.resize(files_.size());
    for (std::size_t i = 0; i < files_.size(); ++i) {
      times_s_[i] = t_s[row_of[i]];
      if (i > 0 && !(times_s_[i] > times_s_[i - 1]))
        throw Error(std::string(times_s_[i] == times_s_[i - 1] ? "two frames have the same timestamp"
                                                               : "timestamps go backwards") +
                        ": t_s = " + format_double(times_s_[i]) + " after " + format_double(times_s_[i - 1]) +
                        " (image " + files_[i].path + ")",
                    {.file = csv,
                     .frame = static_cast<long>(i),
                     .row = static_cast<long>(row_of[i]) + 2,
                     .column = "t_s"});
    }
    times_csv_ = csv;
    time_source_ = "t_s from " + csv;
  }

  // The images no row names, under whichever origin of the numbers leaves fewest: rows lost from frames.csv
  // (or images added) are named when most images match a row, or when every row matches an image (a
  // frames.csv cut short); otherwise the whole numbering is said to differ.
  [[noreturn]] void refuse_unmatched(const std::string& csv, const std::map<std::int64_t, std::size_t>& rows,
                                     std::int64_t origin) const {
    std::vector<std::string> best;
    bool every_row_matched = false;
    for (const std::int64_t offset : {std::int64_t{0}, origin}) {
      std::vector<std::string> unmatched;
      std::size_t matched = 0;
      for (const SequenceFile& f : files_) {
        if (rows.count(f.number - offset))
          ++matched;
        else
          unmatched.push_back(fs::path(f.path).filename().string());
      }
      if (best.empty() || unmatched.size() < best.size()) {
        best = std::move(unmatched);
        every_row_matched = matched == rows.size();
      }
    }
    if (2 * best.size() < files_.size() || (every_row_matched && best.size() < files_.size())) {
      std::string names;
      for (std::size_t i = 0; i < best.size() && i < 5; ++i) names += (i ? ", " : "") + best[i];
      if (best.size() > 5) names += " and " + std::to_string(best.size() - 5) + " more";
      throw Error("has no row for " + std::to_string(best.size()) + " of the " +
                      std::to_string(files_.size()) + " images: " + names +
                      " (a row lost, or an image that is not part of the recording)",
                  {.file = csv, .column = "index"});
    }
    throw Error("the image names are numbered " + std::to_string(files_.front().number) + " to " +
                    std::to_string(files_.back().number) + " and match no row's index, and the " +
                    std::to_string(rows.size()) + " rows are not one per image (" +
                    std::to_string(files_.size()) + "): rows cannot be matched to images",
                {.file = csv, .column = "index"});
  }

  // A multi-page TIFF among the images would give only its first page: the user is told to open it alone.
  static void refuse_multi_page(const std::string& path, std::int64_t index) {
    const std::string ext = lower(fs::path(path).extension().string());
    if (ext != ".tif" && ext != ".tiff") return;
    const std::int64_t pages = tiff_page_count(path);
    if (pages > 1)
      throw Error("is a multi-page TIFF of " + std::to_string(pages) +
                      " pages inside an image sequence, which reads one frame per file; give this file alone "
                      "as the input to read every page",
                  {.file = path, .frame = index});
  }

  std::vector<SequenceFile> files_;
  std::string description_;
  std::vector<double> times_s_;
  std::string times_csv_;
  bool rate_timed_ = false;                 // timed by --frame-rate-Hz
  std::int64_t rows_after_last_image_ = 0;  // frames.csv rows past the last image file
  std::string time_source_;
  bool numbered_ = false;
  std::size_t next_ = 0;
  std::optional<cv::Size> size_;
  int depth_ = -1;
};

// A file that is a video but cannot be read faithfully here: said as it is, not as "not a recording".
class VideoRefused : public Error {
 public:
  using Error::Error;
};

// FFmpeg's tag for a pixel format of more than 8 bits per sample carries the bit count in its last byte
// (gray16le 'Y1',0,16; yuv420p10le 'Y3',11,10).
int bits_of_pixel_format_tag(double tag) {
  if (!(tag > 0.0)) return 8;
  const auto t = static_cast<std::uint32_t>(tag);
  const unsigned third = (t >> 16) & 0xffu, fourth = (t >> 24) & 0xffu;
  return third < 32u && fourth > 8u && fourth <= 16u ? static_cast<int>(fourth) : 8;
}

class VideoFileSource final : public FrameSource {
 public:
  VideoFileSource(std::string path, const FileSourceOptions& options) : path_(std::move(path)) {
    if (!capture_.open(path_, cv::CAP_FFMPEG))
      throw Error("cannot open as a video: FFmpeg could not read it (not a video, or an unsupported codec)",
                  {.file = path_});
    // OpenCV's FFmpeg reader converts every frame to 8 bits: a 10-16-bit camera's data would lose its low
    // bits (a 10-bit camera's codes in 16-bit samples become 0-3), so such a video is refused.
    const int bits = bits_of_pixel_format_tag(capture_.get(cv::CAP_PROP_CODEC_PIXEL_FORMAT));
    if (bits > 8)
      throw VideoRefused(
          "the video stores " + std::to_string(bits) +
              "-bit samples, which the video reader here decodes to 8 bits, losing the camera's low bits: "
              "export the frames as 16-bit images and process the folder, e.g. ffmpeg -i " +
              path_ + " -pix_fmt gray16le frames/%06d.png",
          {.file = path_});
    count_ = static_cast<std::int64_t>(capture_.get(cv::CAP_PROP_FRAME_COUNT));
    fps_ = capture_.get(cv::CAP_PROP_FPS);
    if (options.frame_rate_Hz) given_rate_Hz_ = checked_rate_Hz(*options.frame_rate_Hz);
    // Decoding the first frame now turns an undecodable stream into an error before any work starts.
    std::optional<Frame> first = read_one();
    if (!first) throw Error("the video contains no decodable frame", {.file = path_, .frame = 0});
    pending_.push_back(std::move(*first));
    // FFmpeg also opens still images (whatever their name); a single decoded frame is never taken for a
    // recording, so the second frame is decoded now too.
    std::optional<Frame> second = read_one();
    if (!second)
      throw Error("FFmpeg decodes a single frame from it (a still image?), not a recording of frames",
                  {.file = path_});
    pending_.push_back(std::move(*second));
  }

  std::optional<Frame> next() override {
    if (!pending_.empty()) {
      Frame out = std::move(pending_.front());
      pending_.pop_front();
      return out;
    }
    return read_one();
  }

  std::int64_t frame_count() const override { return count_ > 0 ? count_ : -1; }

  std::string describe() const override {
    return "video file " + path_ + " (" + std::to_string(count_) + " frames by its header; time: " +
           std::string(given_rate_Hz_ > 0.0 ? "frame index / --frame-rate-Hz"
                       : fallback_from_     ? "container timestamps, then frame rate"
                                            : "container timestamps") +
           ")";
  }

  std::map<std::string, std::string> settings() const override {
    return {{"kind", "video"},
            {"file", path_},
            {"frames_in_header", std::to_string(count_)},
            {"nominal_fps", format_double(fps_)},
            {"time_source", time_source()},
            {"time_measured", "true"}};
  }

 private:
  std::optional<Frame> read_one() {
    cv::Mat decoded;
    if (!capture_.read(decoded) || decoded.empty()) return std::nullopt;
    Frame frame;
    frame.index = index_++;
    frame.device_frame_id = frame.index;
    frame.device_time_s = frame_time_s(frame.index, capture_.get(cv::CAP_PROP_POS_MSEC) * 1e-3);
    frame.host_time_s = host_now_s();
    frame.origin = path_;
    frame.image = to_grey(decoded, path_, frame.index);
    last_time_s_ = frame.device_time_s;
    return frame;
  }

  // The container's presentation time while it increases. FFmpeg reports 0 for the frames drained from
  // the decoder at the end of a stream with B-frames, so from the first time that does not increase on,
  // time runs on at the nominal frame rate from the last good timestamp (and settings() says so).
  double frame_time_s(std::int64_t index, double container_s) {
    // A high-speed camera's export plays back at another rate than it recorded: the rate given wins.
    if (given_rate_Hz_ > 0.0) return static_cast<double>(index) / given_rate_Hz_;
    if (index == 0 || (!fallback_from_ && container_s > last_time_s_)) return container_s;
    if (!(fps_ > 0.0))
      throw Error("timestamps do not increase (t_s = " + format_double(container_s) + " after " +
                      format_double(last_time_s_) + ") and the video gives no frame rate to count by",
                  {.file = path_, .frame = index});
    if (!fallback_from_) {
      fallback_from_ = index;
      fallback_cause_ = "t_s = " + format_double(container_s) + " after " + format_double(last_time_s_);
    }
    return last_time_s_ + 1.0 / fps_;
  }

  std::string time_source() const {
    if (given_rate_Hz_ > 0.0)
      return "frame index / " + format_double(given_rate_Hz_) +
             " Hz (--frame-rate-Hz, in place of the container's timestamps at a nominal " +
             format_double(fps_) + " fps)";
    const std::string pts = "container presentation timestamps (CAP_PROP_POS_MSEC)";
    if (!fallback_from_) return pts;
    return pts + " to frame " + std::to_string(*fallback_from_ - 1) + ", then frame index / nominal " +
           format_double(fps_) + " fps (the container's timestamps stopped increasing: " + fallback_cause_ +
           ")";
  }

  std::string path_;
  cv::VideoCapture capture_;
  std::int64_t count_ = -1;
  double fps_ = 0.0;
  double given_rate_Hz_ = 0.0;  // --frame-rate-Hz, which replaces the container's times
  std::int64_t index_ = 0;
  double last_time_s_ = 0.0;
  std::optional<std::int64_t> fallback_from_;  // first frame timed by the frame rate
  std::string fallback_cause_;
  std::deque<Frame> pending_;  // frames decoded by the constructor, not yet delivered
};

// Hidden files are not frames: macOS leaves "._NAME.png" metadata beside every file it copies to a foreign
// disk, which would otherwise be read as corrupt frames carrying the same numbers as the real ones.
bool hidden(const std::string& file_name) {
  return !file_name.empty() && file_name.front() == '.';
}

std::vector<std::string> list_images(const fs::path& dir) {
  std::vector<std::string> paths;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_regular_file() && !hidden(name) && is_image_file_name(name))
      paths.push_back(entry.path().string());
  }
  if (ec) throw Error("cannot list folder: " + ec.message(), {.file = dir.string()});
  return paths;
}

std::optional<std::string> existing(const fs::path& path) {
  if (fs::is_regular_file(path)) return path.string();
  return std::nullopt;
}

// The first bytes of a file as text for a message: printable characters as they are, others in hex.
std::string first_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[8] = {};
  in.read(head, sizeof head);
  std::string text;
  for (std::streamsize i = 0; i < in.gcount(); ++i) {
    const auto c = static_cast<unsigned char>(head[i]);
    char hex[8];
    std::snprintf(hex, sizeof hex, "\\x%02x", c);
    text += std::isprint(c) ? std::string(1, static_cast<char>(c)) : std::string(hex);
  }
  return "'" + text + "'";
}

std::unique_ptr<FrameSource> open_single_image(const std::string& path, const FileSourceOptions& options) {
  // A single image is a one-frame sequence; its time comes from a frames.csv beside it, as for folders.
  const fs::path file(path);
  const fs::path dir = file.has_parent_path() ? file.parent_path() : fs::path(".");
  return std::make_unique<ImageSequenceSource>(make_sequence({path}), "image " + path,
                                               existing(dir / "frames.csv"), options);
}

// A file is judged by its first bytes before its name: a multi-page TIFF named .dat is still every page.
std::unique_ptr<FrameSource> open_regular_file(const std::string& path, const FileSourceOptions& options) {
  switch (sniff_file_kind(path)) {
    case FileKind::kTiff:
    case FileKind::kBigTiff:
      return open_tiff_stack(path, options);
    case FileKind::kCine:
      return open_cine(path, options);
    case FileKind::kPhotron:
      return open_photron(path, options);
    case FileKind::kOther:
      break;
  }
  if (is_image_file_name(path)) return open_single_image(path, options);
  try {
    return open_video_file(path, options);
  } catch (const VideoRefused&) {
    throw;
  } catch (const Error& e) {
    throw Error("is not a recording read here (it starts with " + first_bytes(path) + "; " + e.message() +
                    "). Frames are read from " + frame_formats_read(),
                {.file = path});
  }
}

}  // namespace

bool is_image_file_name(const std::string& name) {
  static const std::vector<std::string> extensions = {".png", ".tif", ".tiff", ".bmp", ".pgm",
                                                      ".ppm", ".jpg", ".jpeg", ".jp2"};
  const std::string ext = lower(fs::path(name).extension().string());
  return std::find(extensions.begin(), extensions.end(), ext) != extensions.end();
}

bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const bool da = std::isdigit(static_cast<unsigned char>(a[i])) != 0;
    const bool db = std::isdigit(static_cast<unsigned char>(b[j])) != 0;
    if (da && db) {
      std::size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      std::string na = a.substr(i, ie - i), nb = b.substr(j, je - j);
      na.erase(0, std::min(na.find_first_not_of('0'), na.size()));
      nb.erase(0, std::min(nb.find_first_not_of('0'), nb.size()));
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  if ((a.size() - i) != (b.size() - j)) return (a.size() - i) < (b.size() - j);
  return a < b;
}

std::unique_ptr<FrameSource> open_image_folder(const std::string& dir, const FileSourceOptions& options) {
  const fs::path root(dir);
  if (!fs::is_directory(root)) throw Error("not a folder", {.file = dir});
  fs::path images = root;
  std::optional<std::string> csv;
  if (fs::is_directory(root / "frames")) {
    images = root / "frames";
    csv = existing(root / "frames.csv");
    if (!csv) csv = existing(images / "frames.csv");
  } else {
    csv = existing(root / "frames.csv");
    // A trial's frames/ folder given itself: its frames.csv lies beside it, as `synth` and `record` write.
    if (!csv && root.filename() == "frames" && root.has_parent_path())
      csv = existing(root.parent_path() / "frames.csv");
  }
  auto paths = list_images(images);
  if (paths.empty())
    throw Error("no image files (.png, .tif, .bmp, .jpg, ...) in this folder", {.file = images.string()});
  return std::make_unique<ImageSequenceSource>(make_sequence(std::move(paths)),
                                               "image folder " + images.string(), csv, options);
}

std::unique_ptr<FrameSource> open_image_pattern(const std::string& pattern,
                                                const FileSourceOptions& options) {
  const fs::path full(pattern);
  const fs::path dir = full.has_parent_path() ? full.parent_path() : fs::path(".");
  const std::string name = full.filename().string();
  if (has_glob_chars(dir.string()) || has_printf_spec(dir.string()))
    throw Error("wildcards and %d are only allowed in the file name, not in folder names", {.file = pattern});
  if (!fs::is_directory(dir)) throw Error("the pattern's folder does not exist", {.file = pattern});

  std::vector<std::string> paths;
  std::error_code ec;
  const std::optional<PrintfSpec> spec = parse_printf(name);
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (!entry.is_regular_file()) continue;
    const std::string file = entry.path().filename().string();
    if (hidden(file)) continue;
    const bool match = spec ? matches_printf(*spec, file) : fnmatch(name.c_str(), file.c_str(), 0) == 0;
    if (match) paths.push_back(entry.path().string());
  }
  if (ec) throw Error("cannot list folder: " + ec.message(), {.file = dir.string()});
  if (paths.empty()) throw Error("no files match this pattern", {.file = pattern});

  std::optional<std::string> csv = existing(dir / "frames.csv");
  if (!csv && dir.filename() == "frames" && dir.has_parent_path())
    csv = existing(dir.parent_path() / "frames.csv");
  return std::make_unique<ImageSequenceSource>(make_sequence(std::move(paths)), "image pattern " + pattern,
                                               csv, options);
}

std::unique_ptr<FrameSource> open_video_file(const std::string& path, const FileSourceOptions& options) {
  if (!fs::is_regular_file(path)) throw Error("no such video file", {.file = path});
  return std::make_unique<VideoFileSource>(path, options);
}

std::unique_ptr<FrameSource> open_file_source(const std::string& path, const FileSourceOptions& options) {
  if (path.empty()) throw Error("empty input path");
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (fs::is_directory(status)) return open_image_folder(path, options);
  if (fs::is_regular_file(status)) return open_regular_file(path, options);
  if (fs::exists(status)) throw Error("not a regular file or folder", {.file = path});
  const std::string name = fs::path(path).filename().string();
  if (has_glob_chars(name) || has_printf_spec(name)) return open_image_pattern(path, options);
  throw Error("no such file or folder", {.file = path});
}

}  // namespace tirstrain::capture
