// Lossless encode + write cost of one 1280x1024 Mono8 TIR-like frame per format: what bounds the record
// rate once the camera delivers (the end-to-end rate from the fake camera is bench/capture_record_bench.sh);
// and the read rate of single-file recordings (multi-page TIFF, Photron .mraw) with their pixel errors.
// Frames are written to $TIRSTRAIN_BENCH_DIR (default /tmp/tirstrain-capture-bench) and deleted.
#include <benchmark/benchmark.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "capture/file_sources.hpp"

namespace {

// Ridges at ~9 px period inside an elliptical contact, plus sensor noise: compresses like a real frame,
// unlike the fake camera's ramp.
cv::Mat tir_frame() {
  cv::Mat image(1024, 1280, CV_8UC1);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const double dx = (x - 640) / 420.0, dy = (y - 512) / 330.0;
      const double inside = dx * dx + dy * dy < 1 ? 1.0 : 0.15;
      const double ridge =
          0.5 + 0.5 * std::sin(2 * M_PI * (x * 0.8 + y * 0.6 + 6 * std::sin(y / 90.0)) / 9.0);
      image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(30 + 180 * inside * ridge);
    }
  cv::Mat noise(image.size(), CV_16SC1);
  cv::randn(noise, 0, 4);
  cv::Mat out;
  image.convertTo(out, CV_16SC1);
  out += noise;
  out.convertTo(image, CV_8UC1);
  return image;
}

std::string bench_dir() {
  const char* env = std::getenv("TIRSTRAIN_BENCH_DIR");
  const std::string dir = env != nullptr ? env : "/tmp/tirstrain-capture-bench";
  std::filesystem::create_directories(dir);
  return dir;
}

void write_file(const std::string& path, const std::vector<unsigned char>& data) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
}

void report(benchmark::State& state, double bytes) {
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["MB_per_s_raw"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * 1280 * 1024 / 1e6, benchmark::Counter::kIsRate);
  state.counters["ratio"] = bytes / static_cast<double>(state.iterations()) / (1280.0 * 1024.0);
}

void BM_Png(benchmark::State& state) {
  const cv::Mat frame = tir_frame();
  const std::string path = bench_dir() + "/png.png";
  std::vector<unsigned char> buffer;
  double bytes = 0;
  for (auto _ : state) {
    cv::imencode(".png", frame, buffer, {cv::IMWRITE_PNG_COMPRESSION, static_cast<int>(state.range(0))});
    write_file(path, buffer);
    bytes += static_cast<double>(buffer.size());
  }
  report(state, bytes);
  std::filesystem::remove(path);
}
BENCHMARK(BM_Png)->Arg(0)->Arg(1)->Arg(3)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_TiffUncompressed(benchmark::State& state) {
  const cv::Mat frame = tir_frame();
  const std::string path = bench_dir() + "/raw.tif";
  std::vector<unsigned char> buffer;
  double bytes = 0;
  for (auto _ : state) {
    cv::imencode(".tiff", frame, buffer, {cv::IMWRITE_TIFF_COMPRESSION, 1});
    write_file(path, buffer);
    bytes += static_cast<double>(buffer.size());
  }
  report(state, bytes);
  std::filesystem::remove(path);
}
BENCHMARK(BM_TiffUncompressed)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Pgm(benchmark::State& state) {
  const cv::Mat frame = tir_frame();
  const std::string path = bench_dir() + "/raw.pgm";
  std::vector<unsigned char> buffer;
  double bytes = 0;
  for (auto _ : state) {
    const std::string header = "P5\n1280 1024\n255\n";
    buffer.assign(header.begin(), header.end());
    buffer.insert(buffer.end(), frame.data, frame.data + frame.total());
    write_file(path, buffer);
    bytes += static_cast<double>(buffer.size());
  }
  report(state, bytes);
  std::filesystem::remove(path);
}
BENCHMARK(BM_Pgm)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Ffv1Mkv(benchmark::State& state) {
  const cv::Mat frame = tir_frame();
  const std::string path = bench_dir() + "/ffv1.mkv";
  cv::VideoWriter writer(path, cv::CAP_FFMPEG, cv::VideoWriter::fourcc('F', 'F', 'V', '1'), 500, frame.size(),
                         false);
  if (!writer.isOpened()) {
    state.SkipWithError("OpenCV's FFmpeg backend cannot write FFV1 here");
    return;
  }
  for (auto _ : state) writer.write(frame);
  writer.release();
  report(state, static_cast<double>(std::filesystem::file_size(path)));
  std::filesystem::remove(path);
}
BENCHMARK(BM_Ffv1Mkv)->Unit(benchmark::kMillisecond)->UseRealTime();

// Reading single-file recordings (capture/file_formats.hpp): 32 frames of 1280x1024, each frame the TIR-like
// image scaled to 12 bits plus its frame number, read back through open_source. Speed next to error: the
// pixels that differ from what was written (must be 0).
constexpr int kRecordingFrames = 32;

cv::Mat frame_12bit(const cv::Mat& base, int i) {
  cv::Mat out;
  base.convertTo(out, CV_16UC1, 16.0, i);
  return out;
}

void read_back(benchmark::State& state, const std::string& path, const cv::Mat& base) {
  double wrong = 0;
  for (auto _ : state) {
    auto source = tirstrain::capture::open_source(path);
    int i = 0;
    while (auto frame = source->next()) {
      state.PauseTiming();
      wrong += cv::countNonZero(frame->image != frame_12bit(base, i++));
      state.ResumeTiming();
    }
    if (i != kRecordingFrames) state.SkipWithError("wrong frame count");
  }
  state.counters["frames_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * kRecordingFrames, benchmark::Counter::kIsRate);
  state.counters["pixel_errors"] = wrong;
}

void BM_ReadMultiPageTiff16(benchmark::State& state) {
  const cv::Mat base = tir_frame();
  const std::string path = bench_dir() + "/stack.tif";
  std::vector<cv::Mat> pages;
  for (int i = 0; i < kRecordingFrames; ++i) pages.push_back(frame_12bit(base, i));
  cv::imwritemulti(path, pages, {cv::IMWRITE_TIFF_COMPRESSION, static_cast<int>(state.range(0))});
  read_back(state, path, base);
  std::filesystem::remove(path);
}
// Arg: TIFF compression tag, 1 none (as cameras export), 5 LZW (OpenCV's default).
BENCHMARK(BM_ReadMultiPageTiff16)->Arg(1)->Arg(5)->Unit(benchmark::kMillisecond)->UseRealTime();

// Photron's 12-bit packing: two pixels in three bytes, most significant bit first.
void BM_ReadMraw12(benchmark::State& state) {
  const cv::Mat base = tir_frame();
  const std::string stem = bench_dir() + "/rec";
  std::ofstream(stem + ".cih")
      << "Record Rate(fps) : 1000\nStart Frame : 0\nTotal Frame : " << kRecordingFrames
      << "\nImage Width : 1280\nImage Height : 1024\nColor Type : Mono\nColor Bit : 12\n"
      << "File Format : MRaw\nEND\n";
  std::vector<unsigned char> packed;
  for (int i = 0; i < kRecordingFrames; ++i) {
    const cv::Mat f = frame_12bit(base, i);
    for (auto it = f.begin<std::uint16_t>(); it != f.end<std::uint16_t>(); it += 2) {
      const unsigned a = *it, b = *(it + 1);
      packed.push_back(static_cast<unsigned char>(a >> 4));
      packed.push_back(static_cast<unsigned char>(((a & 0xf) << 4) | (b >> 8)));
      packed.push_back(static_cast<unsigned char>(b & 0xff));
    }
  }
  write_file(stem + ".mraw", packed);
  read_back(state, stem + ".mraw", base);
  std::filesystem::remove(stem + ".mraw");
  std::filesystem::remove(stem + ".cih");
}
BENCHMARK(BM_ReadMraw12)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
