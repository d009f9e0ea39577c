#pragma once
// Lossless recording from any FrameSource: the calling thread captures, writer threads encode and write,
// a bounded queue (in bytes) sits between them. The output folder is directly readable as an image-folder
// source (and so by `tirstrain process`):
//
//   DIR/frames/000000.tif ...  one lossless image per complete frame, named by its position in the
//                              device's sequence (device frame id minus the first one), so frames the
//                              device or the host lost show up as missing numbers
//   DIR/frames.csv             index,t_s,device_frame_id,device_time_s,host_time_s,status,frames_lost_before,
//                              received,saved — one row per frame received, appended only after its image
//                              is complete, so the folder is consistent at every instant (even after a crash)
//   DIR/recording.json         source, every setting read back ("settings") and what was asked for
//                              ("requested_settings"), options, counters, why the run stopped;
//                              written last: its absence means the recorder itself died
//
// Incomplete frames (missing packets) get a row with status 1 and saved 0 and no image, so nothing
// downstream can mistake them for good frames.
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"

namespace tirstrain::capture {

enum class ImageFormat { kPng, kTiff, kPgm };

// "png" | "tiff" | "pgm"; throws Error naming `key` otherwise.
ImageFormat parse_image_format(const std::string& name, const std::string& key);
const char* extension_of(ImageFormat format);

struct RecordProgress {
  std::int64_t frames_received = 0;
  std::int64_t frames_saved = 0;
  std::int64_t frames_incomplete = 0;
  std::int64_t frames_lost_device = 0;   // device counter jumps (lost in the camera, the network, or aravis)
  std::int64_t frames_dropped_host = 0;  // the writers could not keep up: dropped before the queue
  std::int64_t queue_frames = 0;
  double elapsed_s = 0.0;
  double receive_rate_hz = 0.0;  // frames received per second over the last interval
};

struct RecordOptions {
  std::string out_dir;
  std::string out_option = "--out";                // the command-line option that gave out_dir, for messages
  std::int64_t max_frames = -1;                    // frames received (complete or not); -1: no limit
  double max_seconds = -1.0;                       // from the start of the recording; -1: no limit
  ImageFormat format = ImageFormat::kTiff;         // raw TIFF: the fastest lossless format (docs/capture.md)
  int png_level = 1;                               // zlib level 0..9: 1 is lossless and fast
  std::size_t queue_bytes = 512u * 1024u * 1024u;  // frames waiting for the writers
  int writer_threads = 2;
  bool overwrite = false;  // replace an existing recording in out_dir
  // The source's files or folders on disk (none for a camera): out_dir must not be or hold one.
  std::vector<std::string> input_paths;
  // What was asked of the camera and where each value came from (capture/camera_settings.hpp
  // describe_requested); written to recording.json next to the values read back from the device.
  std::map<std::string, std::string> requested_settings;
  const std::atomic<bool>* stop = nullptr;  // e.g. set from a SIGINT handler
  // Called on the capture thread for every frame (live preview); must return quickly.
  std::function<void(const Frame&)> on_frame;
  // Called on the capture thread about once per second, and for every new loss.
  std::function<void(const RecordProgress&)> on_progress;
};

struct RecordReport {
  RecordProgress counts;
  std::int64_t frames_not_saved =
      0;  // complete frames that were queued but not written (after a write error)
  std::int64_t bytes_written = 0;
  std::int64_t max_queue_frames = 0;
  double elapsed_s = 0.0;
  std::string
      stop_reason;    // "frames", "seconds", "end of stream", "interrupted", "source error", "write error"
  std::string error;  // the message when the run stopped on an error
  // Where the saved frames are: the output folder, or its staging folder when a failed --overwrite run
  // kept the earlier recording in place.
  std::string folder;
  bool ok() const { return error.empty(); }
};

// Records until a limit, the end of the stream, *options.stop, or an error. Errors that happen before the
// first frame (bad folder, existing recording) throw Error; errors during the run (camera lost, disk full)
// end it cleanly — every frame received before them is saved and listed — and come back in report.error.
RecordReport record(FrameSource& source, const RecordOptions& options);

}  // namespace tirstrain::capture
