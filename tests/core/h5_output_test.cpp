#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/h5_stream.hpp"

namespace tirstrain {
namespace {

const std::string kTmp = TIRSTRAIN_TEST_TMP;

TEST(H5, WritesAndReadsDatasetsGroupsAndAttributes) {
  const std::string path = kTmp + "/roundtrip.h5";
  std::filesystem::remove(path);
  std::vector<double> big(100 * 50 * 2);
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = 0.5 * static_cast<double>(i);
  std::vector<std::int32_t> status = {0, 1, 2};
  {
    H5Writer w(path);
    w.write("/frames/t_s", std::span<const double>(big.data(), 3), {3});
    w.write("/frames/status", std::span<const std::int32_t>(status), {3});
    w.write("/tracks/position_px", std::span<const double>(big), {100, 50, 2});  // chunked + compressed
    w.attribute("/", "software", "tirstrain test");
    w.attribute("/tracks/position_px", "unit", "px");
    w.attribute("/frames", "count", 3.0);
    EXPECT_FALSE(std::filesystem::exists(path));
    w.commit();
  }
  ASSERT_TRUE(std::filesystem::exists(path));
  H5Reader r(path);
  H5Shape shape;
  const auto data = r.read_doubles("/tracks/position_px", &shape);
  EXPECT_EQ(shape, (H5Shape{100, 50, 2}));
  EXPECT_EQ(data, big);
  EXPECT_EQ(r.read_integers("/frames/status"), (std::vector<std::int64_t>{0, 1, 2}));
  EXPECT_EQ(r.attribute_text("/", "software"), "tirstrain test");
  EXPECT_EQ(r.attribute_text("/tracks/position_px", "unit"), "px");
  EXPECT_DOUBLE_EQ(r.attribute_number("/frames", "count"), 3.0);
  EXPECT_TRUE(r.has("/frames/t_s"));
  EXPECT_FALSE(r.has("/strain/total"));
  EXPECT_EQ(r.members("/frames").size(), 2u);
}

// Rows of 300 tracks where only two blocks hold values, as when most tracks ever created are retired: the
// values come back where written and the fill everywhere else; a row written again replaces the first
// version whole, also where the new one is all fill.
TEST(H5, StreamedRowsKeepValuesAndFillAndARewriteReplacesTheWholeRow) {
  const std::string path = kTmp + "/sparse_rows.h5";
  std::filesystem::remove(path);
  constexpr std::size_t kWidth = 300;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto row_with = [&](std::size_t first, std::size_t count, double base) {
    std::vector<double> row(kWidth * 2, nan);
    for (std::size_t i = first; i < first + count; ++i) {
      row[2 * i] = base + static_cast<double>(i);
      row[2 * i + 1] = -base - static_cast<double>(i);
    }
    return row;
  };
  {
    H5Stream out(path);
    for (std::size_t frame = 0; frame < 40; ++frame) {
      const std::vector<double> row = row_with(frame % 2 == 0 ? 3 : 250, 10, 1000.0 * frame);
      out.write_row("/tracks/position_px", frame, row, {kWidth, 2}, nan);
    }
    // Frame 7 again, now with its values in columns 100-109 only.
    out.write_row("/tracks/position_px", 7, row_with(100, 10, -5.0), {kWidth, 2}, nan);
    out.commit();
  }
  H5Reader in(path);
  H5Shape shape;
  const std::vector<double> all = in.read_doubles("/tracks/position_px", &shape);
  ASSERT_EQ(shape, (H5Shape{40, kWidth, 2}));
  for (std::size_t frame = 0; frame < 40; ++frame) {
    const std::vector<double> expected =
        frame == 7 ? row_with(100, 10, -5.0) : row_with(frame % 2 == 0 ? 3 : 250, 10, 1000.0 * frame);
    for (std::size_t k = 0; k < kWidth * 2; ++k) {
      const double got = all[frame * kWidth * 2 + k];
      if (std::isnan(expected[k])) {
        EXPECT_TRUE(std::isnan(got)) << "frame " << frame << " value " << k;
      } else {
        EXPECT_EQ(got, expected[k]) << "frame " << frame << " value " << k;
      }
    }
  }
}

TEST(H5, UncommittedWriterLeavesNothing) {
  const std::string path = kTmp + "/abandoned.h5";
  std::filesystem::remove(path);
  {
    H5Writer w(path);
    const double v = 1.0;
    w.write("/x", std::span<const double>(&v, 1), {1});
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

TEST(H5, ReaderRejectsMissingAndNonHdf5Files) {
  EXPECT_THROW(H5Reader(kTmp + "/none.h5"), Error);
  std::ofstream(kTmp + "/text.h5") << "not hdf5";
  try {
    H5Reader r(kTmp + "/text.h5");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a readable HDF5 file"), std::string::npos);
  }
}

TEST(StagingDirectory, CommitReplacesAndAbandonRemoves) {
  const std::string final_dir = kTmp + "/staged";
  std::filesystem::remove_all(final_dir);
  {
    StagingDirectory stage(final_dir);
    std::ofstream(stage.path() + "/a.txt") << "a";
  }
  EXPECT_FALSE(std::filesystem::exists(final_dir));
  EXPECT_FALSE(std::filesystem::exists(final_dir + ".partial"));
  {
    StagingDirectory stage(final_dir);
    std::ofstream(stage.path() + "/b.txt") << "b";
    stage.commit();
  }
  EXPECT_TRUE(std::filesystem::exists(final_dir + "/b.txt"));
}

TEST(OutputDir, RefusesAFileInTheWay) {
  std::ofstream(kTmp + "/plainfile") << "x";
  EXPECT_THROW(ensure_output_dir(kTmp + "/plainfile", "--out"), Error);
  EXPECT_NO_THROW(ensure_output_dir(kTmp + "/new/nested", "--out"));
}

}  // namespace
}  // namespace tirstrain
