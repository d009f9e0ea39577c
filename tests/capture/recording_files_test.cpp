// Single-file recordings: multi-page TIFF (8/16-bit, BigTIFF), Phantom .cine and Photron .mraw/.cih, each
// written here in its documented layout (a few 32x24 frames) and read back pixel for pixel with the
// camera's timestamps; files that are none of the formats read are named with what they hold.
#include <gtest/gtest.h>

#include <tiffio.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "capture/file_formats.hpp"
#include "capture/file_sources.hpp"
#include "core/error.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::capture {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

constexpr int kWidth = 32, kHeight = 24;

// The known truth every writer stores: a different value at every pixel of every frame.
std::uint32_t truth(int x, int y, int frame, int bits) {
  return static_cast<std::uint32_t>(x * 37 + y * 101 + frame * 7 + (bits > 8 ? x * y * 13 : 0)) %
         (1u << bits);
}

std::vector<Frame> read_all(FrameSource& source) {
  std::vector<Frame> frames;
  while (auto f = source.next()) frames.push_back(std::move(*f));
  return frames;
}

void expect_truth(const std::vector<Frame>& frames, int bits) {
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const cv::Mat& m = frames[i].image;
    ASSERT_EQ(m.cols, kWidth);
    ASSERT_EQ(m.rows, kHeight);
    ASSERT_EQ(m.type(), bits == 8 ? CV_8UC1 : CV_16UC1);
    int wrong = 0;
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) {
        const std::uint32_t v = bits == 8 ? m.at<std::uint8_t>(y, x) : m.at<std::uint16_t>(y, x);
        wrong += v != truth(x, y, static_cast<int>(i), bits);
      }
    EXPECT_EQ(wrong, 0) << "frame " << i;
  }
}

// ---- TIFF ----

void write_tiff(const fs::path& path, int pages, int bits, bool big) {
  TIFF* tif = TIFFOpen(path.c_str(), big ? "w8" : "w");
  ASSERT_NE(tif, nullptr);
  for (int p = 0; p < pages; ++p) {
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, kWidth);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, kHeight);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, bits);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 8);
    std::vector<std::uint16_t> row16(kWidth);
    std::vector<std::uint8_t> row8(kWidth);
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        row16[x] = static_cast<std::uint16_t>(truth(x, y, p, bits));
        row8[x] = static_cast<std::uint8_t>(truth(x, y, p, bits));
      }
      void* row = bits == 8 ? static_cast<void*>(row8.data()) : static_cast<void*>(row16.data());
      ASSERT_EQ(TIFFWriteScanline(tif, row, static_cast<std::uint32_t>(y), 0), 1);
    }
    TIFFWriteDirectory(tif);
  }
  TIFFClose(tif);
}

TEST(MultiPageTiff, EightBitFileOfNPagesGivesNFramesTimedByFramesCsv) {
  const fs::path dir = testing::scratch_dir("recordings", "tiff8");
  write_tiff(dir / "video.tif", 5, 8, false);
  std::ofstream(dir / "frames.csv") << "index,t_s\n0,0.010\n1,0.011\n2,0.0125\n3,0.013\n4,0.014\n";
  auto source = open_source((dir / "video.tif").string());
  EXPECT_EQ(source->frame_count(), 5);
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 5u);
  expect_truth(frames, 8);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.0125);
  EXPECT_EQ(source->settings().at("time_measured"), "true");
}

// A rate given beside a frames.csv would be ignored or contradict it: one clock, as for a folder of images.
TEST(MultiPageTiff, ARateBesideFramesCsvIsRefused) {
  const fs::path dir = testing::scratch_dir("recordings", "tiff8_rate");
  write_tiff(dir / "video.tif", 3, 8, false);
  std::ofstream(dir / "frames.csv") << "index,t_s\n0,0.010\n1,0.011\n2,0.0125\n";
  try {
    open_file_source((dir / "video.tif").string(), FileSourceOptions{.frame_rate_Hz = 100.0});
    ADD_FAILURE() << "a rate beside frames.csv was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("frames.csv already gives the frames their times"),
              std::string::npos)
        << e.what();
    EXPECT_EQ(e.context().key, "--frame-rate-Hz");
  }
}

TEST(MultiPageTiff, SixteenBitBigTiffTimedByTheGivenFrameRate) {
  const fs::path dir = testing::scratch_dir("recordings", "bigtiff16");
  // Named .dat: the file is recognised by its bytes, not its name.
  write_tiff(dir / "video.dat", 4, 16, true);
  EXPECT_EQ(sniff_file_kind((dir / "video.dat").string()), FileKind::kBigTiff);
  auto source = open_source((dir / "video.dat").string(), FileSourceOptions{.frame_rate_Hz = 1000.0});
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 4u);
  expect_truth(frames, 16);
  EXPECT_DOUBLE_EQ(frames[3].device_time_s, 0.003);
  EXPECT_NE(source->describe().find("BigTIFF"), std::string::npos) << source->describe();
  // Without a rate or frames.csv the time axis is the frame number, and says so.
  auto unclocked = open_source((dir / "video.dat").string());
  EXPECT_EQ(unclocked->settings().at("time_measured"), "false");
  EXPECT_NE(error_of([&] {
              open_source((dir / "video.dat").string(), FileSourceOptions{.frame_rate_Hz = -5.0});
            }).find("--frame-rate-Hz"),
            std::string::npos);
}

TEST(MultiPageTiff, InsideAnImageSequenceItIsRefusedNotReadAsOneFrame) {
  const fs::path dir = testing::scratch_dir("recordings", "tiff_in_folder");
  write_tiff(dir / "a_000.tif", 1, 8, false);
  write_tiff(dir / "a_001.tif", 3, 8, false);
  auto source = open_source(dir.string());
  ASSERT_TRUE(source->next());
  const std::string message = error_of([&] { source->next(); });
  EXPECT_NE(message.find("a_001.tif"), std::string::npos) << message;
  EXPECT_NE(message.find("multi-page TIFF of 3 pages"), std::string::npos) << message;
}

TEST(MultiPageTiff, ACutFileIsRefusedNotReadShort) {
  const fs::path dir = testing::scratch_dir("recordings", "tiff_cut");
  write_tiff(dir / "whole.tif", 5, 8, false);
  // Cut inside the last page: libtiff writes each page's pixels, then its directory, so pages 0-3 stay
  // whole and the chain of directories points past the end of the file.
  const auto size = fs::file_size(dir / "whole.tif");
  {
    std::ifstream in(dir / "whole.tif", std::ios::binary);
    std::vector<char> bytes(size - 100);
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    std::ofstream(dir / "cut.tif", std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  EXPECT_EQ(open_source((dir / "whole.tif").string())->frame_count(), 5);
  const std::string message = error_of([&] { open_source((dir / "cut.tif").string()); });
  EXPECT_NE(message.find("cut.tif"), std::string::npos) << message;
  EXPECT_NE(message.find("breaks after page 3"), std::string::npos) << message;
  EXPECT_NE(message.find("cut short or damaged"), std::string::npos) << message;
}

// ---- Phantom .cine ----

struct Bytes {
  std::vector<std::uint8_t> data;
  void put(std::size_t at, std::uint64_t value, int bytes) {
    if (data.size() < at + static_cast<std::size_t>(bytes)) data.resize(at + static_cast<std::size_t>(bytes));
    for (int k = 0; k < bytes; ++k)
      data[at + static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(value >> (8 * k));
  }
  void append(const std::vector<std::uint8_t>& more) { data.insert(data.end(), more.begin(), more.end()); }
  void save(const fs::path& path) const {
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  }
};

// Pixels in row order `rows` (top-down or bottom-up), 8 bit, 16 bit little-endian or packed MSB first.
std::vector<std::uint8_t> pack_frame(int frame, int bits, bool bottom_up) {
  std::vector<std::uint8_t> out;
  std::uint64_t acc = 0;
  int filled = 0;
  for (int r = 0; r < kHeight; ++r) {
    const int y = bottom_up ? kHeight - 1 - r : r;
    for (int x = 0; x < kWidth; ++x) {
      const std::uint32_t v = truth(x, y, frame, bits);
      if (bits == 8) {
        out.push_back(static_cast<std::uint8_t>(v));
      } else if (bits == 16) {
        out.push_back(static_cast<std::uint8_t>(v & 0xff));
        out.push_back(static_cast<std::uint8_t>(v >> 8));
      } else {
        acc = (acc << bits) | v;
        filled += bits;
        while (filled >= 8) {
          out.push_back(static_cast<std::uint8_t>(acc >> (filled - 8)));
          filled -= 8;
        }
      }
    }
  }
  return out;
}

// A cine as the published layout has it: CINEFILEHEADER (44 bytes), BITMAPINFOHEADER (40), SETUP (its
// Length field at +142, FrameRate at +768), tagged blocks up to the image offset table, then each image
// behind its annotation (AnnotationSize, annotation, ImageSize).
void write_cine(const fs::path& path, int frames, int bits, bool with_time_block, std::uint32_t rate_Hz) {
  Bytes b;
  constexpr std::size_t kSetup = 84, kSetupBytes = 1000;
  const std::size_t blocks = kSetup + kSetupBytes;
  const std::size_t time_block_bytes = with_time_block ? 8 + 8 * static_cast<std::size_t>(frames) : 0;
  const std::size_t offsets = blocks + time_block_bytes;
  b.put(0, 'C' | ('I' << 8), 2);
  b.put(2, 44, 2);
  b.put(4, 0, 2);                                // Compression: grey
  b.put(6, 1, 2);                                // Version
  b.put(16, static_cast<std::uint32_t>(-2), 4);  // FirstImageNo: two frames before the trigger
  b.put(20, static_cast<std::uint64_t>(frames), 4);
  b.put(24, 44, 4);
  b.put(28, kSetup, 4);
  b.put(32, offsets, 4);
  b.put(36, (std::uint64_t{1700000000} << 32) | 0x80000000u, 8);  // trigger at 1700000000.5 s
  b.put(44, 40, 4);
  b.put(48, kWidth, 4);
  b.put(52, kHeight, 4);  // positive: rows bottom-up
  b.put(56, 1, 2);
  b.put(58, static_cast<std::uint64_t>(bits), 2);
  b.put(60, bits == 10 || bits == 12 ? 256 : 0, 4);
  b.put(kSetup + 140, 'S' | ('T' << 8), 2);
  b.put(kSetup + 142, kSetupBytes, 2);
  b.put(kSetup + 768, rate_Hz, 4);
  if (with_time_block) {
    b.put(blocks, time_block_bytes, 4);
    b.put(blocks + 4, 1002, 2);
    for (int i = 0; i < frames; ++i) {
      // Frame i at (i - 2) / 1024 s after the trigger: exact in TIME64's 2^-32 s fractions.
      const std::uint64_t t =
          ((std::uint64_t{1700000000} << 32) | 0x80000000u) +
          static_cast<std::uint64_t>(static_cast<std::int64_t>(i - 2) * (std::int64_t{1} << 22));
      b.put(blocks + 8 + 8 * static_cast<std::size_t>(i), t, 8);
    }
  }
  std::size_t at = offsets + 8 * static_cast<std::size_t>(frames);
  for (int i = 0; i < frames; ++i) {
    b.put(offsets + 8 * static_cast<std::size_t>(i), at, 8);
    const auto pixels = pack_frame(i, bits, true);
    b.put(at, 12, 4);  // AnnotationSize: itself, 4 bytes of annotation, ImageSize
    b.put(at + 4, 0xdeadbeef, 4);
    b.put(at + 8, pixels.size(), 4);
    b.data.resize(at + 12);
    b.append(pixels);
    at = b.data.size();
  }
  b.save(path);
}

TEST(PhantomCine, PackedTenAndTwelveBitWithTheCamerasTimestamps) {
  const fs::path dir = testing::scratch_dir("recordings", "cine");
  for (int bits : {8, 10, 12, 16}) {
    const fs::path path = dir / ("rec" + std::to_string(bits) + ".cine");
    write_cine(path, 4, bits, true, 1000);
    auto source = open_source(path.string());
    const auto frames = read_all(*source);
    ASSERT_EQ(frames.size(), 4u) << bits;
    expect_truth(frames, bits);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(frames[i].device_time_s, (i - 2) / 1024.0) << bits << " " << i;
    EXPECT_EQ(source->settings().at("trigger_time_unix_s"), "1700000000.5");
  }
}

TEST(PhantomCine, WithoutATimeBlockTheRecordedFrameRateCountsFromTheTrigger) {
  const fs::path dir = testing::scratch_dir("recordings", "cine_rate");
  write_cine(dir / "rec.cine", 3, 8, false, 2000);
  auto source = open_source((dir / "rec.cine").string());
  const auto frames = read_all(*source);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_DOUBLE_EQ(frames[0].device_time_s, -2.0 / 2000.0);
  EXPECT_DOUBLE_EQ(frames[2].device_time_s, 0.0);
  // A colour sensor's raw (CFA) cine is refused, not read as grey.
  {
    std::fstream f(dir / "rec.cine", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(4);
    f.put(2);
  }
  EXPECT_NE(error_of([&] { open_source((dir / "rec.cine").string()); }).find("raw colour"),
            std::string::npos);
  write_cine(dir / "rec.cine", 3, 8, false, 2000);
  // A file cut short is an error naming it, never fewer frames.
  std::filesystem::resize_file(dir / "rec.cine", std::filesystem::file_size(dir / "rec.cine") - 100);
  auto cut = open_source((dir / "rec.cine").string());
  cut->next();
  cut->next();
  const std::string message = error_of([&] { cut->next(); });
  EXPECT_NE(message.find("beyond the end"), std::string::npos) << message;
}

// ---- Photron .mraw + .cih ----

void write_photron(const fs::path& stem, int frames, int bits, const std::string& extra = "") {
  std::ofstream(stem.string() + ".cih")
      << "#Camera Information Header\r\nRecord Rate(fps) : 500\r\n"
      << "Start Frame : -1\r\nTotal Frame : " << frames << "\r\nImage Width : " << kWidth
      << "\r\nImage Height : " << kHeight << "\r\nColor Type : Mono\r\nColor Bit : " << bits
      << "\r\nFile Format : MRaw\r\n"
      << extra << "END\r\n";
  Bytes b;
  for (int i = 0; i < frames; ++i) {
    auto pixels = pack_frame(i, bits, false);
    b.append(pixels);
  }
  b.save(stem.string() + ".mraw");
}

TEST(PhotronMraw, EightTwelveAndSixteenBitFramesTimedFromTheTrigger) {
  const fs::path dir = testing::scratch_dir("recordings", "photron");
  for (int bits : {8, 12, 16}) {
    const fs::path stem = dir / ("C001H001S0001_" + std::to_string(bits));
    write_photron(stem, 3, bits);
    for (const char* ext : {".mraw", ".cih"}) {
      auto source = open_source(stem.string() + ext);
      const auto frames = read_all(*source);
      ASSERT_EQ(frames.size(), 3u) << bits;
      expect_truth(frames, bits);
      EXPECT_DOUBLE_EQ(frames[0].device_time_s, -1.0 / 500.0);
      EXPECT_DOUBLE_EQ(frames[2].device_time_s, 1.0 / 500.0);
    }
  }
  // A header claiming more frames than the .mraw holds is refused before anything is read.
  write_photron(dir / "short", 2, 8);
  std::ofstream(dir / "short.cih", std::ios::app) << "Total Frame : 3\r\n";
  const std::string message = error_of([&] { open_source((dir / "short.mraw").string()); });
  EXPECT_NE(message.find("claims 3 frames"), std::string::npos) << message;
}

// The byte-wise fast paths and the bit-wise remainder agree with packing done bit by bit here.
TEST(PackedPixels, TenTwelveAndOddWidthsUnpackExactly) {
  for (int bits : {10, 12, 14}) {
    for (std::size_t count : {std::size_t{1}, std::size_t{7}, std::size_t{64}}) {
      std::vector<std::uint16_t> values(count), unpacked(count);
      std::vector<std::uint8_t> packed((count * static_cast<std::size_t>(bits) + 7) / 8);
      std::size_t bit = 0;
      for (std::size_t k = 0; k < count; ++k) {
        values[k] = static_cast<std::uint16_t>((k * 2654435761u) % (1u << bits));
        for (int b = bits - 1; b >= 0; --b, ++bit)
          if ((values[k] >> b) & 1) packed[bit / 8] |= static_cast<std::uint8_t>(0x80 >> (bit % 8));
      }
      unpack_msb_first(packed.data(), bits, count, unpacked.data());
      EXPECT_EQ(unpacked, values) << bits << " bits, " << count << " pixels";
    }
  }
}

// ---- anything else ----

TEST(UnrecognisedFile, NamesWhatItFoundAndTheFormatsRead) {
  const fs::path dir = testing::scratch_dir("recordings", "unknown");
  std::ofstream(dir / "rec.mat") << "MATLAB 5.0 MAT-file, Platform: GLNXA64" << std::string(200, '\0');
  const std::string message = error_of([&] { open_source((dir / "rec.mat").string()); });
  EXPECT_NE(message.find("rec.mat"), std::string::npos) << message;
  EXPECT_NE(message.find("'MATLAB 5'"), std::string::npos) << message;
  for (const char* format : {"multi-page TIFF", ".cine", ".mraw", "FFmpeg"})
    EXPECT_NE(message.find(format), std::string::npos) << message;
  // A still image that FFmpeg would read as one frame is never taken for a one-frame video.
  cv::imwrite((dir / "still.png").string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(7)));
  fs::rename(dir / "still.png", dir / "still.avi");
  const std::string still = error_of([&] { open_source((dir / "still.avi").string()); });
  EXPECT_NE(still.find("still.avi"), std::string::npos) << still;
  EXPECT_NE(still.find("Frames are read from"), std::string::npos) << still;
}

}  // namespace
}  // namespace tirstrain::capture
