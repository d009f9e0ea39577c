#include <gtest/gtest.h>

#include <algorithm>
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

// Rows given as scattered columns (in no order) of a row that widens every frame, past 521 chunk columns
// (the chunk cache's smallest hash table), and one row given again: the same file content as the rows
// assembled in full.
TEST(H5, RowsGivenAsColumnsEqualTheRowsInFull) {
  const std::string path = kTmp + "/column_rows.h5";
  std::filesystem::remove(path);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  constexpr std::size_t kFrames = 24;
  const auto width_at = [](std::size_t frame) { return 2000 + frame * 1500; };  // 35 500 = 555 chunk columns
  // Frame f's live columns: a block near the end (newborn) and survivors scattered over the whole width.
  const auto columns_at = [&](std::size_t frame, std::size_t salt) {
    std::vector<std::size_t> columns;
    const std::size_t width = width_at(frame);
    for (std::size_t k = 0; k < 50; ++k) columns.push_back(width - 1 - k * 3);
    for (std::size_t k = 0; k < 200; ++k) columns.push_back((k * 7919 + frame * 131 + salt) % (width - 200));
    std::sort(columns.begin(), columns.end());
    columns.erase(std::unique(columns.begin(), columns.end()), columns.end());
    std::reverse(columns.begin(), columns.end());
    return columns;
  };
  const auto value = [](std::size_t frame, std::size_t column, std::size_t c, double base) {
    return base + 1000.0 * static_cast<double>(frame) + static_cast<double>(column) +
           0.25 * static_cast<double>(c);
  };
  const auto full_row = [&](std::size_t frame, const std::vector<std::size_t>& columns, double base) {
    std::vector<double> row(width_at(frame) * 2, nan);
    for (const std::size_t k : columns)
      for (std::size_t c = 0; c < 2; ++c) row[2 * k + c] = value(frame, k, c, base);
    return row;
  };
  const auto listed = [&](std::size_t frame, const std::vector<std::size_t>& columns, double base) {
    std::vector<double> values;
    for (const std::size_t k : columns)
      for (std::size_t c = 0; c < 2; ++c) values.push_back(value(frame, k, c, base));
    return values;
  };
  {
    H5Stream out(path);
    for (std::size_t frame = 0; frame < kFrames; ++frame) {
      const std::vector<std::size_t> columns = columns_at(frame, 0);
      const H5Shape shape{width_at(frame), 2};
      out.write_columns("/by_columns", frame, columns, listed(frame, columns, 0.0), shape, nan);
      out.write_row("/in_full", frame, full_row(frame, columns, 0.0), shape, nan);
      std::vector<std::int8_t> status(columns.size(), 2);
      out.write_columns("/status", frame, columns, std::span<const std::int8_t>(status), {width_at(frame)},
                        std::int8_t{-1});
    }
    // Frame 5 again, with other columns: nothing of the first version stays.
    const std::vector<std::size_t> again = columns_at(5, 17);
    out.write_columns("/by_columns", 5, again, listed(5, again, -0.5), {width_at(5), 2}, nan);
    out.write_row("/in_full", 5, full_row(5, again, -0.5), {width_at(5), 2}, nan);
    out.commit();
  }
  H5Reader in(path);
  H5Shape shape_columns, shape_full;
  const std::vector<double> by_columns = in.read_doubles("/by_columns", &shape_columns);
  const std::vector<double> in_full = in.read_doubles("/in_full", &shape_full);
  const std::size_t width = width_at(kFrames - 1);
  ASSERT_EQ(shape_columns, (H5Shape{kFrames, width, 2}));
  ASSERT_EQ(shape_full, shape_columns);
  std::size_t values = 0;
  for (std::size_t frame = 0; frame < kFrames; ++frame) {
    const std::vector<std::size_t> columns = columns_at(frame, frame == 5 ? 17 : 0);
    std::vector<double> expected = full_row(frame, columns, frame == 5 ? -0.5 : 0.0);
    expected.resize(width * 2, nan);
    for (std::size_t k = 0; k < width * 2; ++k) {
      const double got = by_columns[frame * width * 2 + k], full = in_full[frame * width * 2 + k];
      if (std::isnan(expected[k])) {
        ASSERT_TRUE(std::isnan(got) && std::isnan(full)) << "frame " << frame << " value " << k;
      } else {
        ASSERT_EQ(got, expected[k]) << "frame " << frame << " value " << k;
        ASSERT_EQ(full, expected[k]) << "frame " << frame << " value " << k;
        ++values;
      }
    }
  }
  EXPECT_GT(values, kFrames * 400);
  const std::vector<std::int64_t> status = in.read_integers("/status");
  std::size_t set = 0;
  for (const std::int64_t s : status) {
    ASSERT_TRUE(s == 2 || s == -1);
    set += s == 2 ? 1 : 0;
  }
  std::size_t listed_total = 0;
  for (std::size_t frame = 0; frame < kFrames; ++frame) listed_total += columns_at(frame, 0).size();
  EXPECT_EQ(set, listed_total);
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
  {  // over an earlier output: the earlier one is marked while it is removed, the new one is left unmarked
    StagingDirectory stage(final_dir);
    std::ofstream(stage.path() + "/c.txt") << "c";
    stage.commit();
  }
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(final_dir))
    names.push_back(entry.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"c.txt"});
  EXPECT_FALSE(std::filesystem::exists(final_dir + ".partial"));
}

TEST(OutputDir, RefusesAFileInTheWay) {
  std::ofstream(kTmp + "/plainfile") << "x";
  EXPECT_THROW(ensure_output_dir(kTmp + "/plainfile", "--out"), Error);
  EXPECT_NO_THROW(ensure_output_dir(kTmp + "/new/nested", "--out"));
}

}  // namespace
}  // namespace tirstrain
