// High-speed camera recordings read from their published layouts: Phantom .cine (Vision Research, "Cine
// File Format") and Photron .mraw with its .cih text header. Mono only; 8-bit, 16-bit and packed 10/12-bit
// pixels (packed most significant bit first).
#include <opencv2/core.hpp>
#include <opencv2/core/mat.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>

#include "capture/file_formats.hpp"
#include "capture/indexed_source.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;

// Reads little-endian fields at absolute offsets; every read is checked against the file's size so that a
// damaged header is an error, never a read past the end or a huge allocation.
class LittleEndianFile {
 public:
  explicit LittleEndianFile(std::string path) : path_(std::move(path)), in_(path_, std::ios::binary) {
    if (!in_) throw Error("cannot open for reading", {.file = path_});
    std::error_code ec;
    size_ = fs::file_size(path_, ec);
  }
  void read(std::uint64_t offset, void* out, std::size_t bytes, const char* what) {
    if (offset > size_ || bytes > size_ - offset)
      throw Error(std::string(what) + " at byte " + std::to_string(offset) + " lies beyond the end of the " +
                      std::to_string(size_) + "-byte file (truncated or damaged)",
                  {.file = path_});
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(static_cast<char*>(out), static_cast<std::streamsize>(bytes));
    if (in_.gcount() != static_cast<std::streamsize>(bytes))
      throw Error(std::string("cannot read ") + what, {.file = path_});
  }
  template <typename T>
  T get(std::uint64_t offset, const char* what) {
    unsigned char b[sizeof(T)];
    read(offset, b, sizeof b, what);
    std::uint64_t v = 0;
    for (std::size_t k = sizeof(T); k-- > 0;) v = (v << 8) | b[k];
    T out;
    if constexpr (sizeof(T) == 8) {
      std::memcpy(&out, &v, 8);
    } else {
      out = static_cast<T>(v);
    }
    return out;
  }
  std::uint64_t size() const { return size_; }

 private:
  std::string path_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
};

// Pixels of one frame: `bits` per pixel stored as 8, 16 (little-endian) or packed 10/12 (MSB first).
cv::Mat decode_pixels(const std::vector<std::uint8_t>& raw, int width, int height, int bits) {
  if (bits == 8) return cv::Mat(height, width, CV_8UC1, const_cast<std::uint8_t*>(raw.data())).clone();
  cv::Mat out(height, width, CV_16UC1);
  const std::size_t count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  auto* dst = out.ptr<std::uint16_t>(0);
  if (bits == 16) {
    for (std::size_t k = 0; k < count; ++k)
      dst[k] = static_cast<std::uint16_t>(raw[2 * k] | (raw[2 * k + 1] << 8));
  } else {
    unpack_msb_first(raw.data(), bits, count, dst);
  }
  return out;
}

std::size_t frame_bytes(int width, int height, int bits) {
  return (static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
              static_cast<std::size_t>(bits) +
          7) /
         8;
}

double time64_s(std::uint64_t raw) {
  // TIME64: low 32 bits are fractions of a second (units of 2^-32 s), high 32 bits whole seconds since 1970.
  return static_cast<double>(raw >> 32) + static_cast<double>(raw & 0xffffffffu) / 4294967296.0;
}

// ---- Phantom .cine -------------------------------------------------------------------------------------

// Offsets of the fields read, from the start of each structure (all little-endian, packed).
struct CineLayout {
  static constexpr std::uint64_t kHeaderBytes = 44;
  static constexpr std::uint64_t kCompression = 4, kFirstImageNo = 16, kImageCount = 20, kOffImageHeader = 24,
                                 kOffSetup = 28, kOffImageOffsets = 32, kTriggerTime = 36;
  static constexpr std::uint64_t kBiWidth = 4, kBiHeight = 8, kBiBitCount = 14, kBiCompression = 16,
                                 kBiSizeImage = 20;
  static constexpr std::uint64_t kSetupLength = 142, kSetupFrameRate = 768;
  static constexpr std::uint16_t kTimeOnlyBlock = 1002, kTimeBlock = 1001;
};

class CineSource final : public IndexedFileSource {
 public:
  CineSource(const std::string& path, const FileSourceOptions& options)
      : IndexedFileSource(path, "Phantom cine"), file_(path) {
    using L = CineLayout;
    const std::int64_t count = read_header();
    const std::uint64_t offsets_at = file_.get<std::uint32_t>(L::kOffImageOffsets, "OffImageOffsets");
    image_offsets_.resize(static_cast<std::size_t>(count));
    for (std::int64_t i = 0; i < count; ++i)
      image_offsets_[static_cast<std::size_t>(i)] =
          file_.get<std::uint64_t>(offsets_at + 8 * static_cast<std::uint64_t>(i), "the image offset table");
    set_frames(count, frame_clock(count, offsets_at, options));
  }

 private:
  std::int64_t read_header() {
    using L = CineLayout;
    const auto compression = file_.get<std::uint16_t>(L::kCompression, "Compression");
    if (compression == 1)
      throw Error("is a JPEG-compressed cine; uncompressed mono cines are read (save it uncompressed)",
                  {.file = path_});
    // 2 is a colour sensor's raw (CFA) image: read as grey it would carry the colour mosaic.
    if (compression != 0)
      throw Error("has Compression " + std::to_string(compression) +
                      " (2: raw colour, CFA); grey (0) mono cines are read",
                  {.file = path_});
    const std::uint64_t bih = file_.get<std::uint32_t>(L::kOffImageHeader, "OffImageHeader");
    width_ = file_.get<std::int32_t>(bih + L::kBiWidth, "biWidth");
    const auto height = file_.get<std::int32_t>(bih + L::kBiHeight, "biHeight");
    // As in a Windows bitmap, a positive height stores rows bottom-up.
    bottom_up_ = height > 0;
    height_ = std::abs(height);
    bits_ = file_.get<std::uint16_t>(bih + L::kBiBitCount, "biBitCount");
    if (bits_ != 8 && bits_ != 10 && bits_ != 12 && bits_ != 16)
      throw Error("has " + std::to_string(bits_) +
                      " bits per pixel (colour or an unknown packing); 8, 10, 12 (packed) and 16-bit mono "
                      "cines are read",
                  {.file = path_});
    if (width_ <= 0 || height_ <= 0 || width_ > 65536 || height_ > 65536)
      throw Error("claims an image of " + std::to_string(width_) + "x" + std::to_string(height_) + " pixels",
                  {.file = path_});
    const auto size_image = file_.get<std::uint32_t>(bih + L::kBiSizeImage, "biSizeImage");
    bytes_ = std::max<std::size_t>(frame_bytes(width_, height_, bits_), size_image);
    const auto count = file_.get<std::uint32_t>(L::kImageCount, "ImageCount");
    if (count == 0 || static_cast<std::uint64_t>(count) * bytes_ > file_.size())
      throw Error("claims " + std::to_string(count) + " images of " + std::to_string(bytes_) +
                      " bytes, more than the file holds",
                  {.file = path_});
    first_image_no_ = file_.get<std::int32_t>(L::kFirstImageNo, "FirstImageNo");
    trigger_s_ = time64_s(file_.get<std::uint64_t>(L::kTriggerTime, "TriggerTime"));
    extra_settings_["bits_per_pixel"] = std::to_string(bits_);
    extra_settings_["first_image_no"] = std::to_string(first_image_no_);
    extra_settings_["trigger_time_unix_s"] = format_double(trigger_s_);
    return count;
  }

  // The camera's clock: per-frame TIME64 stamps from a time block when the file has one, else frame numbers
  // (relative to the trigger) over the recorded frame rate.
  FrameClock frame_clock(std::int64_t count, std::uint64_t blocks_end, const FileSourceOptions& options) {
    using L = CineLayout;
    const std::uint64_t setup = file_.get<std::uint32_t>(L::kOffSetup, "OffSetup");
    const auto setup_bytes = file_.get<std::uint16_t>(setup + L::kSetupLength, "SETUP.Length");
    double rate_Hz = 0.0;
    if (setup_bytes >= L::kSetupFrameRate + 4)
      rate_Hz = file_.get<std::uint32_t>(setup + L::kSetupFrameRate, "SETUP.FrameRate");
    if (rate_Hz > 0.0) extra_settings_["frame_rate_Hz"] = format_double(rate_Hz);
    FrameClock clock;
    for (std::uint64_t at = setup + setup_bytes; at + 8 <= blocks_end;) {
      const auto block_bytes = file_.get<std::uint32_t>(at, "a tagged block's size");
      const auto type = file_.get<std::uint16_t>(at + 4, "a tagged block's type");
      if (block_bytes < 8) break;
      if ((type == L::kTimeOnlyBlock || type == L::kTimeBlock) &&
          block_bytes >= 8 + 8 * static_cast<std::uint64_t>(count)) {
        clock.t_s.resize(static_cast<std::size_t>(count));
        for (std::int64_t i = 0; i < count; ++i)
          clock.t_s[static_cast<std::size_t>(i)] =
              time64_s(file_.get<std::uint64_t>(at + 8 + 8 * static_cast<std::uint64_t>(i), "a frame time")) -
              trigger_s_;
        clock.source = "the camera's per-frame timestamps (cine time block), seconds after its trigger";
        clock.measured = true;
        if (options.frame_rate_Hz)
          throw Error(
              "--frame-rate-Hz was given but the file's per-frame timestamps (cine time block) already give "
              "the "
              "frames their times; a recording has one clock: drop one of them",
              {.file = path_, .key = "--frame-rate-Hz"});
        return clock;
      }
      at += block_bytes;
    }
    if (rate_Hz > 0.0 && !options.frame_rate_Hz) {
      clock.t_s.resize(static_cast<std::size_t>(count));
      for (std::int64_t i = 0; i < count; ++i)
        clock.t_s[static_cast<std::size_t>(i)] = static_cast<double>(first_image_no_ + i) / rate_Hz;
      clock.source =
          "image number after the trigger / the cine's frame rate " + format_double(rate_Hz) + " Hz";
      clock.measured = true;
      return clock;
    }
    return resolve_frame_clock(path_, count, {}, 0.0, options);
  }

  cv::Mat read_frame(std::int64_t index) override {
    const std::uint64_t at = image_offsets_[static_cast<std::size_t>(index)];
    const auto annotation_bytes = file_.get<std::uint32_t>(at, "an image's annotation size");
    std::vector<std::uint8_t> raw(bytes_);
    file_.read(at + annotation_bytes, raw.data(), raw.size(), "an image's pixels");
    cv::Mat image = decode_pixels(raw, width_, height_, bits_);
    if (bottom_up_) cv::flip(image, image, 0);
    return image;
  }

  LittleEndianFile file_;
  int width_ = 0, height_ = 0, bits_ = 0;
  bool bottom_up_ = true;
  std::size_t bytes_ = 0;
  std::int32_t first_image_no_ = 0;
  double trigger_s_ = 0.0;
  std::vector<std::uint64_t> image_offsets_;
};

// ---- Photron .mraw + .cih ------------------------------------------------------------------------------

// "Key : Value" lines of a .cih header, keys and values trimmed.
std::map<std::string, std::string> read_cih(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error("cannot open the Photron header", {.file = path});
  std::map<std::string, std::string> fields;
  std::string line;
  const auto trim = [](std::string s) {
    const auto b = s.find_first_not_of(" \t\r");
    const auto e = s.find_last_not_of(" \t\r");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  while (std::getline(in, line)) {
    const auto colon = line.find(" : ");
    if (colon != std::string::npos) fields[trim(line.substr(0, colon))] = trim(line.substr(colon + 3));
  }
  return fields;
}

class PhotronSource final : public IndexedFileSource {
 public:
  PhotronSource(const std::string& mraw, const std::string& cih, const FileSourceOptions& options)
      : IndexedFileSource(mraw, "Photron mraw"), file_(mraw), cih_(cih) {
    fields_ = read_cih(cih);
    check_format();
    width_ = whole("Image Width", 1, 65536);
    height_ = whole("Image Height", 1, 65536);
    bits_ = static_cast<int>(whole("Color Bit", 8, 16));
    if (bits_ != 8 && bits_ != 12 && bits_ != 16)
      throw Error("Color Bit is " + std::to_string(bits_) + "; 8, 12 (packed) and 16-bit mono .mraw are read",
                  {.file = cih_});
    const std::int64_t count = whole("Total Frame", 1, 1LL << 40);
    bytes_ = frame_bytes(width_, height_, bits_);
    if (static_cast<std::uint64_t>(count) * bytes_ > file_.size())
      throw Error("the header claims " + std::to_string(count) + " frames of " + std::to_string(bytes_) +
                      " bytes but the .mraw holds " + std::to_string(file_.size()) + " bytes",
                  {.file = cih_});
    lower_bits_ = effective_shift();
    set_frames(count, frame_clock(count, options));
    extra_settings_["header"] = cih_;
    extra_settings_["bits_per_pixel"] = std::to_string(bits_);
  }

 private:
  void check_format() {
    const auto format = fields_.find("File Format");
    if (format == fields_.end())
      throw Error("no 'File Format' line; not a Photron .cih header", {.file = cih_});
    std::string f = format->second;
    for (char& c : f) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (f != "mraw")
      throw Error("File Format is '" + format->second + "'; the raw .mraw layout is read", {.file = cih_});
    const auto colour = fields_.find("Color Type");
    if (colour != fields_.end() && colour->second != "Mono")
      throw Error("Color Type is '" + colour->second + "'; mono recordings are read", {.file = cih_});
  }

  std::int64_t whole(const std::string& key, std::int64_t low, std::int64_t high) const {
    const auto it = fields_.find(key);
    if (it == fields_.end()) throw Error("no '" + key + "' line", {.file = cih_, .key = key});
    char* end = nullptr;
    const long long v = std::strtoll(it->second.c_str(), &end, 10);
    if (end == it->second.c_str() || v < low || v > high)
      throw Error("'" + key + " : " + it->second + "' is not a whole number in [" + std::to_string(low) +
                      ", " + std::to_string(high) + "]",
                  {.file = cih_, .key = key});
    return v;
  }

  // 16-bit storage of fewer effective bits aligned to the high end is shifted down to the sensor's values.
  int effective_shift() const {
    const auto side = fields_.find("EffectiveBit Side");
    const auto depth = fields_.find("EffectiveBit Depth");
    if (bits_ != 16 || side == fields_.end() || depth == fields_.end() || side->second != "Higher") return 0;
    const int effective = std::atoi(depth->second.c_str());
    return effective > 0 && effective < 16 ? 16 - effective : 0;
  }

  // Photron numbers frames from the trigger ("Start Frame", negative before it) at "Record Rate(fps)".
  FrameClock frame_clock(std::int64_t count, const FileSourceOptions& options) {
    const auto rate = fields_.find("Record Rate(fps)");
    const double rate_Hz = rate == fields_.end() ? 0.0 : std::strtod(rate->second.c_str(), nullptr);
    const auto start = fields_.find("Start Frame");
    const long long first = start == fields_.end() ? 0 : std::strtoll(start->second.c_str(), nullptr, 10);
    extra_settings_["start_frame"] = std::to_string(first);
    if (rate_Hz > 0.0) extra_settings_["frame_rate_Hz"] = format_double(rate_Hz);
    if (!(rate_Hz > 0.0) || options.frame_rate_Hz) return resolve_frame_clock(path_, count, {}, 0.0, options);
    FrameClock clock;
    clock.t_s.resize(static_cast<std::size_t>(count));
    for (std::int64_t i = 0; i < count; ++i)
      clock.t_s[static_cast<std::size_t>(i)] = static_cast<double>(first + i) / rate_Hz;
    clock.source = "frame number after the trigger ('Start Frame') / 'Record Rate(fps)' " +
                   format_double(rate_Hz) + " Hz of " + cih_;
    clock.measured = true;
    return clock;
  }

  cv::Mat read_frame(std::int64_t index) override {
    std::vector<std::uint8_t> raw(bytes_);
    file_.read(static_cast<std::uint64_t>(index) * bytes_, raw.data(), raw.size(), "a frame's pixels");
    cv::Mat image = decode_pixels(raw, width_, height_, bits_);
    if (lower_bits_ > 0) image /= (1 << lower_bits_);
    return image;
  }

  LittleEndianFile file_;
  std::string cih_;
  std::map<std::string, std::string> fields_;
  int width_ = 0, height_ = 0, bits_ = 0, lower_bits_ = 0;
  std::size_t bytes_ = 0;
};

}  // namespace

void unpack_msb_first(const std::uint8_t* packed, int bits, std::size_t count, std::uint16_t* out) {
  // Whole groups of the two packings in use byte by byte (12 bit: 2 pixels in 3 bytes, 10 bit: 4 in 5);
  // any remainder, and other widths, bit by bit.
  std::size_t k = 0;
  if (bits == 12)
    for (; k + 2 <= count; k += 2, packed += 3) {
      out[k] = static_cast<std::uint16_t>(packed[0] << 4 | packed[1] >> 4);
      out[k + 1] = static_cast<std::uint16_t>((packed[1] & 0x0f) << 8 | packed[2]);
    }
  if (bits == 10)
    for (; k + 4 <= count; k += 4, packed += 5) {
      out[k] = static_cast<std::uint16_t>(packed[0] << 2 | packed[1] >> 6);
      out[k + 1] = static_cast<std::uint16_t>((packed[1] & 0x3f) << 4 | packed[2] >> 4);
      out[k + 2] = static_cast<std::uint16_t>((packed[2] & 0x0f) << 6 | packed[3] >> 2);
      out[k + 3] = static_cast<std::uint16_t>((packed[3] & 0x03) << 8 | packed[4]);
    }
  out += k;
  count -= k;
  std::uint64_t bit = 0;
  for (std::size_t r = 0; r < count; ++r) {
    std::uint32_t v = 0;
    for (int b = 0; b < bits; ++b, ++bit) v = (v << 1) | ((packed[bit >> 3] >> (7 - (bit & 7))) & 1u);
    out[r] = static_cast<std::uint16_t>(v);
  }
}

std::unique_ptr<FrameSource> open_cine(const std::string& path, const FileSourceOptions& options) {
  return std::make_unique<CineSource>(path, options);
}

std::unique_ptr<FrameSource> open_photron(const std::string& path, const FileSourceOptions& options) {
  const fs::path p(path);
  std::string ext = p.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  fs::path mraw = p, cih = p;
  if (ext == ".cih") {
    mraw.replace_extension(".mraw");
  } else {
    cih.replace_extension(".cih");
    if (!fs::exists(cih) && fs::exists(fs::path(p).replace_extension(".cihx")))
      throw Error(
          "its header is a .cihx (XML); the text .cih header is read (export the recording with a "
          ".cih)",
          {.file = path});
  }
  if (ext == ".cihx")
    throw Error("is a .cihx (XML) header; the text .cih header is read (export the recording with a .cih)",
                {.file = path});
  if (!fs::is_regular_file(cih))
    throw Error("no Photron header " + cih.string() + " beside it", {.file = path});
  if (!fs::is_regular_file(mraw))
    throw Error("no Photron image file " + mraw.string() + " beside it", {.file = path});
  return std::make_unique<PhotronSource>(mraw.string(), cih.string(), options);
}

}  // namespace tirstrain::capture
