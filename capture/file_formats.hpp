#pragma once
// Single-file recordings holding many frames: multi-page TIFF (classic and BigTIFF), Phantom .cine and
// Photron .mraw (with its .cih header). Each is a FrameSource yielding every frame of the file.
//
// Time axis, in order of preference:
//   - the camera's own per-frame timestamps (.cine time block), relative to the trigger;
//   - a frames.csv (`t_s`, optionally `index`) beside the file, one row per frame;
//   - a frame rate: the one the camera wrote (.cine setup, .cih "Record Rate(fps)") or the user's
//     --frame-rate-Hz (FileSourceOptions), t_s = frame number / rate;
//   - none: t_s is the frame number and settings()["time_source"] says so.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"

namespace tirstrain::capture {

struct FileSourceOptions {
  // Frame rate of a recording whose file holds no timestamps, Hz; unset = none given (t_s is then the
  // frame number, labelled as such). A video's or camera file's own timestamps take precedence; an image
  // sequence with a frames.csv refuses it (one clock).
  std::optional<double> frame_rate_Hz;
};

// What the first bytes of a file say it is.
enum class FileKind { kTiff, kBigTiff, kCine, kPhotron, kOther };
FileKind sniff_file_kind(const std::string& path);

// Pages in a TIFF or BigTIFF file (0 when it is not one libtiff can open).
std::int64_t tiff_page_count(const std::string& path);

std::unique_ptr<FrameSource> open_tiff_stack(const std::string& path, const FileSourceOptions& options);
std::unique_ptr<FrameSource> open_cine(const std::string& path, const FileSourceOptions& options);
// `path` is the .mraw or the .cih; the other is found beside it with the same stem.
std::unique_ptr<FrameSource> open_photron(const std::string& path, const FileSourceOptions& options);

// The formats read as frame sources, for messages about a file that is none of them.
std::string frame_formats_read();

// t_s of `count` frames from a frames.csv (`t_s`, optional `index` matching 0-based frame numbers); checks
// the count and that time increases. Throws Error naming the csv.
std::vector<double> frame_times_from_csv(const std::string& csv, std::int64_t count, const std::string& of);

// Unpacks `count` pixels of `bits` (10, 12) packed most significant bit first into 16-bit values.
void unpack_msb_first(const std::uint8_t* packed, int bits, std::size_t count, std::uint16_t* out);

}  // namespace tirstrain::capture
