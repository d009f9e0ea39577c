// Multi-page TIFF and BigTIFF recordings through libtiff, one page per frame, plus what the single-file
// recordings share: sniffing a file's kind, the frame clock and the list of formats read.
#include <tiffio.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdarg>
#include <cstdio>
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

// libtiff's messages go to the open file's own buffer (never to stderr): the last one explains a failure.
int keep_message(TIFF*, void* user_data, const char* module, const char* fmt, va_list ap) {
  char text[512];
  std::vsnprintf(text, sizeof text, fmt, ap);
  *static_cast<std::string*>(user_data) = std::string(module ? module : "libtiff") + ": " + text;
  return 1;
}

struct TiffCloser {
  void operator()(TIFF* tif) const { TIFFClose(tif); }
};
using TiffHandle = std::unique_ptr<TIFF, TiffCloser>;

TiffHandle open_tiff(const std::string& path, std::string& message) {
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  TIFFOpenOptionsSetErrorHandlerExtR(options, keep_message, &message);
  // Warnings (unknown tags, ...) are dropped: they do not change the pixels.
  TIFFOpenOptionsSetWarningHandlerExtR(
      options, [](TIFF*, void*, const char*, const char*, va_list) { return 1; }, nullptr);
  TiffHandle tif(TIFFOpenExt(path.c_str(), "r", options));
  TIFFOpenOptionsFree(options);
  return tif;
}

// The layout of one page, checked before its pixels are read.
struct PageLayout {
  std::uint32_t width = 0, height = 0;
  std::uint16_t bits = 0, samples = 1, planar = PLANARCONFIG_CONTIG, photometric = PHOTOMETRIC_MINISBLACK;
  std::uint16_t sample_format = SAMPLEFORMAT_UINT;
  bool tiled = false;
};

PageLayout page_layout(TIFF* tif) {
  PageLayout p;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &p.width);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &p.height);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &p.bits);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &p.samples);
  TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &p.planar);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &p.sample_format);
  if (!TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &p.photometric)) p.photometric = PHOTOMETRIC_MINISBLACK;
  p.tiled = TIFFIsTiled(tif) != 0;
  return p;
}

// Why a page cannot be read as a grey frame, or "".
std::string unsupported(const PageLayout& p) {
  if (p.width == 0 || p.height == 0) return "has no pixels (width or height 0)";
  if (p.bits != 8 && p.bits != 16)
    return "has " + std::to_string(p.bits) + "-bit samples (8- and 16-bit pages are read)";
  if (p.sample_format != SAMPLEFORMAT_UINT) return "has signed or floating-point samples (unsigned are read)";
  if (p.samples != 1 && p.samples != 3 && p.samples != 4)
    return "has " + std::to_string(p.samples) + " samples per pixel (grey, RGB or RGBA are read)";
  if (p.samples > 1 && p.planar != PLANARCONFIG_CONTIG) return "stores colour planes separately";
  if (p.photometric == PHOTOMETRIC_PALETTE) return "is a palette image (grey or RGB are read)";
  return "";
}

class TiffStackSource final : public IndexedFileSource {
 public:
  TiffStackSource(const std::string& path, const FileSourceOptions& options)
      : IndexedFileSource(path, "multi-page TIFF") {
    tif_ = open_tiff(path, message_);
    if (!tif_) throw Error("cannot open as a TIFF: " + message_, {.file = path});
    const std::int64_t pages = TIFFNumberOfDirectories(tif_.get());
    if (pages <= 0) throw Error("the TIFF holds no page", {.file = path});
    // A page whose directory cannot be read ends the count: the file was cut (a recording that stopped
    // mid-write) or damaged, and reading the pages before it would pass for the whole recording.
    if (!message_.empty())
      throw Error("the TIFF's chain of pages breaks after page " + std::to_string(pages - 1) + " (" +
                      message_ + "): the file is cut short or damaged, so the recording's length is unknown",
                  {.file = path, .frame = pages});
    if (TIFFIsBigTIFF(tif_.get())) kind_ = "multi-page BigTIFF";
    first_ = page_layout(tif_.get());
    if (const std::string why = unsupported(first_); !why.empty())
      throw Error("page 0 " + why, {.file = path, .frame = 0});
    set_frames(pages, resolve_frame_clock(path, pages, {}, 0.0, options));
    extra_settings_["bits_per_sample"] = std::to_string(first_.bits);
  }

 private:
  cv::Mat read_frame(std::int64_t index) override {
    // Frames are read in order: the next page is the next directory (TIFFSetDirectory starts from the first).
    const bool next_page = index == static_cast<std::int64_t>(TIFFCurrentDirectory(tif_.get())) + 1;
    if (!(next_page ? TIFFReadDirectory(tif_.get())
                    : TIFFSetDirectory(tif_.get(), static_cast<tdir_t>(index))))
      throw Error("cannot go to page " + std::to_string(index) + ": " + message_,
                  {.file = path_, .frame = index});
    const PageLayout p = page_layout(tif_.get());
    if (const std::string why = unsupported(p); !why.empty())
      throw Error("page " + std::to_string(index) + " " + why, {.file = path_, .frame = index});
    if (p.width != first_.width || p.height != first_.height || p.bits != first_.bits)
      throw Error("page " + std::to_string(index) + " is " + std::to_string(p.width) + "x" +
                      std::to_string(p.height) + " " + std::to_string(p.bits) + "-bit but page 0 is " +
                      std::to_string(first_.width) + "x" + std::to_string(first_.height) + " " +
                      std::to_string(first_.bits) + "-bit; all pages must match",
                  {.file = path_, .frame = index});
    const int depth = p.bits == 8 ? CV_8U : CV_16U;
    cv::Mat pixels(static_cast<int>(p.height), static_cast<int>(p.width), CV_MAKETYPE(depth, p.samples));
    if (p.tiled)
      read_tiles(pixels, index);
    else
      read_strips(pixels, index);
    return to_grey(pixels, p);
  }

  // Whole strips decoded straight into the image (the cv::Mat is continuous, rows back to back).
  void read_strips(cv::Mat& pixels, std::int64_t index) {
    const std::size_t total = pixels.total() * pixels.elemSize();
    std::size_t done = 0;
    const tstrip_t strips = TIFFNumberOfStrips(tif_.get());
    for (tstrip_t s = 0; s < strips && done < total; ++s) {
      const tmsize_t got =
          TIFFReadEncodedStrip(tif_.get(), s, pixels.data + done, static_cast<tmsize_t>(total - done));
      if (got < 0)
        throw Error("cannot decode strip " + std::to_string(s) + " of page " + std::to_string(index) + ": " +
                        message_,
                    {.file = path_, .frame = index});
      done += static_cast<std::size_t>(got);
    }
    if (done != total)
      throw Error("page " + std::to_string(index) + " holds " + std::to_string(done) +
                      " bytes of pixels, not " + std::to_string(total),
                  {.file = path_, .frame = index});
  }

  void read_tiles(cv::Mat& pixels, std::int64_t index) {
    std::uint32_t tile_w = 0, tile_h = 0;
    TIFFGetField(tif_.get(), TIFFTAG_TILEWIDTH, &tile_w);
    TIFFGetField(tif_.get(), TIFFTAG_TILELENGTH, &tile_h);
    if (tile_w == 0 || tile_h == 0)
      throw Error("a tiled page without a tile size", {.file = path_, .frame = index});
    std::vector<std::uint8_t> tile(static_cast<std::size_t>(TIFFTileSize(tif_.get())));
    const std::size_t pixel_bytes = pixels.elemSize();
    for (std::uint32_t ty = 0; ty < static_cast<std::uint32_t>(pixels.rows); ty += tile_h)
      for (std::uint32_t tx = 0; tx < static_cast<std::uint32_t>(pixels.cols); tx += tile_w) {
        if (TIFFReadTile(tif_.get(), tile.data(), tx, ty, 0, 0) < 0)
          throw Error("cannot decode a tile of page " + std::to_string(index) + ": " + message_,
                      {.file = path_, .frame = index});
        const std::uint32_t h = std::min(tile_h, static_cast<std::uint32_t>(pixels.rows) - ty);
        const std::uint32_t w = std::min(tile_w, static_cast<std::uint32_t>(pixels.cols) - tx);
        for (std::uint32_t r = 0; r < h; ++r)
          std::memcpy(pixels.ptr(static_cast<int>(ty + r)) + tx * pixel_bytes,
                      tile.data() + static_cast<std::size_t>(r) * tile_w * pixel_bytes, w * pixel_bytes);
      }
  }

  static cv::Mat to_grey(const cv::Mat& pixels, const PageLayout& p) {
    cv::Mat grey;
    if (p.samples == 1) {
      grey = pixels;
      // White-is-zero pages are inverted so that brighter is always larger.
      if (p.photometric == PHOTOMETRIC_MINISWHITE) grey = (p.bits == 8 ? 255.0 : 65535.0) - pixels;
    } else {
      cv::cvtColor(pixels, grey, p.samples == 3 ? cv::COLOR_RGB2GRAY : cv::COLOR_RGBA2GRAY);
    }
    return grey;
  }

  TiffHandle tif_;
  std::string message_;
  PageLayout first_;
};

bool starts_with(const unsigned char* head, std::size_t n, const char* magic, std::size_t m) {
  return n >= m && std::memcmp(head, magic, m) == 0;
}

}  // namespace

FileKind sniff_file_kind(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char head[4] = {};
  in.read(reinterpret_cast<char*>(head), sizeof head);
  const auto n = static_cast<std::size_t>(in.gcount());
  if (starts_with(head, n, "II*\0", 4) || starts_with(head, n, "MM\0*", 4)) return FileKind::kTiff;
  if (starts_with(head, n, "II+\0", 4) || starts_with(head, n, "MM\0+", 4)) return FileKind::kBigTiff;
  if (starts_with(head, n, "CI", 2) && n >= 4 && head[2] == 44 && head[3] == 0) return FileKind::kCine;
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".mraw" || ext == ".cih" || ext == ".cihx") return FileKind::kPhotron;
  return FileKind::kOther;
}

std::int64_t tiff_page_count(const std::string& path) {
  std::string message;
  const TiffHandle tif = open_tiff(path, message);
  if (!tif) return 0;
  return TIFFNumberOfDirectories(tif.get());
}

std::unique_ptr<FrameSource> open_tiff_stack(const std::string& path, const FileSourceOptions& options) {
  return std::make_unique<TiffStackSource>(path, options);
}

std::string frame_formats_read() {
  return "a folder of images (PNG, TIFF, BMP, PGM, JPEG; time from frames.csv), an image pattern "
         "(img_%05d.png or *.tif), a multi-page TIFF or BigTIFF (8/16-bit), a Phantom .cine (8/10/12/16-bit "
         "mono), a Photron .mraw with its .cih (8/12/16-bit mono), or a video FFmpeg decodes (.avi, .mp4, "
         ".mkv, ...)";
}

std::vector<double> frame_times_from_csv(const std::string& csv, std::int64_t count, const std::string& of) {
  const CsvTable table = read_numeric_csv(csv);
  const std::vector<double>& t_s = table.column("t_s");
  std::vector<double> times(static_cast<std::size_t>(count));
  std::vector<long> row_of(times.size());
  if (table.has("index")) {
    std::map<std::int64_t, std::size_t> rows;
    const std::vector<double>& index = table.column("index");
    for (std::size_t r = 0; r < index.size(); ++r) rows.emplace(static_cast<std::int64_t>(index[r]), r);
    for (std::size_t i = 0; i < times.size(); ++i) {
      const auto it = rows.find(static_cast<std::int64_t>(i));
      if (it == rows.end() || index[it->second] != static_cast<double>(i))
        throw Error(
            "no row with index " + std::to_string(i) + " for frame " + std::to_string(i) + " of " + of,
            {.file = csv, .frame = static_cast<long>(i), .column = "index"});
      row_of[i] = static_cast<long>(it->second);
    }
  } else {
    if (static_cast<std::int64_t>(t_s.size()) != count)
      throw Error("has " + std::to_string(t_s.size()) + " rows but " + of + " has " + std::to_string(count) +
                      " frames (add an 'index' column to match rows to frames)",
                  {.file = csv, .column = "t_s"});
    for (std::size_t i = 0; i < times.size(); ++i) row_of[i] = static_cast<long>(i);
  }
  for (std::size_t i = 0; i < times.size(); ++i) {
    times[i] = t_s[static_cast<std::size_t>(row_of[i])];
    if (i > 0 && !(times[i] > times[i - 1]))
      throw Error(std::string(times[i] == times[i - 1] ? "two frames have the same timestamp"
                                                       : "timestamps go backwards") +
                      ": t_s = " + format_double(times[i]) + " after " + format_double(times[i - 1]),
                  {.file = csv, .frame = static_cast<long>(i), .row = row_of[i] + 2, .column = "t_s"});
  }
  return times;
}

FrameClock resolve_frame_clock(const std::string& path, std::int64_t count, std::vector<double> camera_t_s,
                               double camera_rate_Hz, const FileSourceOptions& options) {
  FrameClock clock;
  const fs::path file(path);
  const fs::path csv = (file.has_parent_path() ? file.parent_path() : fs::path(".")) / "frames.csv";
  // A recording has one clock: a rate given beside timestamps the file or a frames.csv already holds would
  // be ignored or would contradict them, so it is refused (as for a folder of images).
  if (options.frame_rate_Hz && (!camera_t_s.empty() || fs::is_regular_file(csv)))
    throw Error("--frame-rate-Hz was given but " +
                    (camera_t_s.empty() ? csv.string() : std::string("the file's per-frame timestamps")) +
                    " already gives the frames their times; a recording has one clock: drop one of them",
                {.file = path, .key = "--frame-rate-Hz"});
  if (!camera_t_s.empty()) {
    clock.t_s = std::move(camera_t_s);
    clock.source = "the camera's per-frame timestamps in the file, relative to its trigger";
    clock.measured = true;
    return clock;
  }
  if (fs::is_regular_file(csv)) {
    clock.t_s = frame_times_from_csv(csv.string(), count, path);
    clock.source = "t_s from " + csv.string();
    clock.measured = true;
    return clock;
  }
  double rate_Hz = 0.0;
  if (options.frame_rate_Hz) {
    rate_Hz = *options.frame_rate_Hz;
    if (!(rate_Hz > 0.0) || !std::isfinite(rate_Hz))
      throw Error("the frame rate must be a positive number of Hz, not " + format_double(rate_Hz),
                  {.file = path, .key = "--frame-rate-Hz"});
    clock.source = "frame number / " + format_double(rate_Hz) + " Hz (--frame-rate-Hz)";
  } else if (camera_rate_Hz > 0.0) {
    rate_Hz = camera_rate_Hz;
    clock.source = "frame number / " + format_double(rate_Hz) + " Hz (the frame rate in the file's header)";
  }
  clock.t_s.resize(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < clock.t_s.size(); ++i)
    clock.t_s[i] = rate_Hz > 0.0 ? static_cast<double>(i) / rate_Hz : static_cast<double>(i);
  clock.measured = rate_Hz > 0.0;
  if (rate_Hz <= 0.0)
    clock.source =
        "none (no timestamps in the file, no frames.csv beside it, no --frame-rate-Hz): t_s is the frame "
        "number, not a measured time";
  return clock;
}

}  // namespace tirstrain::capture
