#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"

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
