// Channel reading and validation: every bad-input case names file, row (or sample) and column; HDF5 files
// (plain group layout and a MATLAB v7.3-like layout with a 512-byte user block, transposed 1×N variables,
// MATLAB_class attributes and a char variable) are written here with the HDF5 C++ API.
#include <gtest/gtest.h>

#include <H5Cpp.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "signals/channels.hpp"
#include "signals/isolated_read.hpp"
#include "tests/support/expect_error.hpp"

namespace ts = tirstrain::signals;

namespace {

std::string tmp_path(const std::string& name) {
  // One folder per test: CTest runs these tests in parallel processes.
  const std::string dir = std::string(TIRSTRAIN_TEST_TMP) + "/signals_channels/" +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name();
  std::filesystem::create_directories(dir);
  return dir + "/" + name;
}

std::string write_text(const std::string& name, const std::string& text) {
  const std::string path = tmp_path(name);
  std::ofstream(path) << text;
  return path;
}

// A file of the HDF5 channel reader's fuzz corpus (its seeds and the findings kept as regressions).
std::string corpus_file(const std::string& name) {
  return std::string(TIRSTRAIN_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_channel_hdf5/" + name;
}

using tirstrain::testing::expect_error;

template <typename Where>
void write_vector(Where& where, const std::string& name, const std::vector<double>& v,
                  std::vector<hsize_t> dims, const char* matlab_class = nullptr) {
  H5::DataSpace space(static_cast<int>(dims.size()), dims.data());
  H5::DataSet ds = where.createDataSet(name, H5::PredType::NATIVE_DOUBLE, space);
  ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
  if (matlab_class) {
    H5::StrType type(H5::PredType::C_S1, std::strlen(matlab_class));
    H5::Attribute attr = ds.createAttribute("MATLAB_class", type, H5::DataSpace(H5S_SCALAR));
    attr.write(type, std::string(matlab_class));
  }
}

}  // namespace

TEST(ChannelsCsv, ReadsColumnsAndSampleRate) {
  const auto path = write_text(
      "good.csv", "t_s,normal_N,tangential_N\n0,1,0.1\n0.001,1.1,0.2\n0.002,1.2,0.3\n0.003,1.3,0.4\n");
  const auto table = ts::read_channels(path, {.required = {"normal_N"}});
  EXPECT_NEAR(table.sample_rate_Hz, 1000.0, 1e-6);
  ASSERT_EQ(table.names.size(), 2u);
  EXPECT_EQ(table.column("tangential_N")[2], 0.3);
  EXPECT_EQ(table.samples(), 4u);
}

// A time column named with its unit (`t_ms`) is read in that unit: the table's time axis is in seconds.
TEST(ChannelsCsv, TimeColumnInMillisecondsIsReadInSeconds) {
  const auto path = write_text("ms.csv", "t_ms,normal_N\n0,1\n1,1.1\n2,1.2\n3,1.3\n");
  const auto table = ts::read_channels(path, {.time_column = "t_ms"});
  EXPECT_NEAR(table.sample_rate_Hz, 1000.0, 1e-6);
  EXPECT_DOUBLE_EQ(table.time_s[3], 0.003);
  EXPECT_DOUBLE_EQ(ts::time_column_seconds_per_unit("time_us"), 1e-6);
  EXPECT_DOUBLE_EQ(ts::time_column_seconds_per_unit("t_s"), 1.0);
}

TEST(ChannelsCsv, DuplicateTimestampNamesRowAndColumn) {
  const auto path = write_text("dup.csv", "t_s,normal_N\n0,1\n0.001,1\n0.001,1\n0.003,1\n");
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().file, path);
  EXPECT_EQ(e.context().row, 4);  // header is row 1
  EXPECT_EQ(e.context().column, "t_s");
  EXPECT_NE(e.message().find("duplicate"), std::string::npos);
}

TEST(ChannelsCsv, DecreasingTimestampAndBlankLinesKeepTrueRowNumbers) {
  const auto path = write_text("dec.csv", "t_s,normal_N\n\n0,1\n0.001,1\n\n0.0005,1\n");
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().row, 6);
  EXPECT_NE(e.message().find("not increasing"), std::string::npos);
}

TEST(ChannelsCsv, VaryingSampleRateIsReportedWithTolerance) {
  // A dropped sample at 0.004 doubles one interval.
  const auto path = write_text("drop.csv", "t_s,a\n0,1\n0.001,1\n0.002,1\n0.003,1\n0.005,1\n0.006,1\n");
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().row, 6);
  EXPECT_NE(e.message().find("sample rate varies"), std::string::npos);
  EXPECT_NE(e.message().find("1 %"), std::string::npos);
  // 0.5 % jitter passes the default 1 % tolerance.
  const auto ok = write_text("jitter.csv", "t_s,a\n0,1\n0.001005,1\n0.002,1\n0.003,1\n");
  EXPECT_NO_THROW(ts::read_channels(ok));
}

TEST(ChannelsCsv, NanEmptyMissingAndUnknownColumns) {
  const auto nan_path = write_text("nan.csv", "t_s,a\n0,1\n0.001,nan\n");
  auto e = expect_error([&] { ts::read_channels(nan_path); });
  EXPECT_EQ(e.context().row, 3);
  EXPECT_EQ(e.context().column, "a");
  const auto empty_path = write_text("empty.csv", "t_s,a\n0,1\n0.001,\n");
  e = expect_error([&] { ts::read_channels(empty_path); });
  EXPECT_EQ(e.context().row, 3);
  EXPECT_EQ(e.context().column, "a");
  const auto path = write_text("cols.csv", "t_s,a,b\n0,1,2\n0.001,1,2\n");
  e = expect_error([&] { ts::read_channels(path, {.required = {"force_N"}}); });
  EXPECT_EQ(e.context().column, "force_N");
  EXPECT_NE(e.message().find("a, b"), std::string::npos);
  e = expect_error([&] { ts::read_channels(path, {.expected = {"a"}}); });
  EXPECT_EQ(e.context().column, "b");
  EXPECT_NE(e.message().find("unknown column"), std::string::npos);
  const auto no_time = write_text("notime.csv", "time,a\n0,1\n1,2\n");
  e = expect_error([&] { ts::read_channels(no_time); });
  EXPECT_EQ(e.context().column, "t_s");
}

TEST(ChannelsHdf5, GroupLayout) {
  const auto path = tmp_path("group.h5");
  {
    H5::H5File file(path, H5F_ACC_TRUNC);
    H5::Group g = file.createGroup("/channels");
    write_vector(g, "t_s", {0.0, 0.0005, 0.001, 0.0015}, {4});
    write_vector(g, "accel_m_s2", {1, 2, 3, 4}, {4});
  }
  const auto table = ts::read_channels(path, {.required = {"accel_m_s2"}, .hdf5_group = "/channels"});
  EXPECT_NEAR(table.sample_rate_Hz, 2000.0, 1e-6);
  EXPECT_EQ(table.column("accel_m_s2")[3], 4.0);
}

TEST(ChannelsHdf5, MatlabV73Layout) {
  const auto path = tmp_path("trial.mat");
  {
    H5::FileCreatPropList create;
    create.setUserblock(512);  // MATLAB's text header lives in the user block
    H5::H5File file(path, H5F_ACC_TRUNC, create);
    // An N×1 MATLAB column vector is stored transposed, as a 1×N dataset.
    write_vector(file, "t_s", {0.0, 0.001, 0.002, 0.003, 0.004}, {1, 5}, "double");
    write_vector(file, "normal_N", {1.0, 1.5, 2.0, 2.5, 3.0}, {1, 5}, "double");
    write_vector(file, "tangential_N", {0.1, 0.2, 0.3, 0.4, 0.5}, {5, 1}, "double");
    // A char variable: uint16 codes with MATLAB_class "char".
    const std::vector<std::uint16_t> text{'s', 'u', 'b', '1'};
    hsize_t dims[2] = {4, 1};
    H5::DataSpace space(2, dims);
    H5::DataSet ds = file.createDataSet("subject", H5::PredType::NATIVE_UINT16, space);
    ds.write(text.data(), H5::PredType::NATIVE_UINT16);
    H5::StrType type(H5::PredType::C_S1, 4);
    ds.createAttribute("MATLAB_class", type, H5::DataSpace(H5S_SCALAR)).write(type, std::string("char"));
    file.createGroup("/#refs#");
  }
  const auto table = ts::read_channels(path, {.required = {"normal_N", "tangential_N"}});
  EXPECT_NEAR(table.sample_rate_Hz, 1000.0, 1e-6);
  EXPECT_EQ(table.column("normal_N")[4], 3.0);
  EXPECT_EQ(table.column("tangential_N")[1], 0.2);
  EXPECT_FALSE(table.has("subject"));  // text is skipped unless asked for
  const auto e = expect_error([&] { ts::read_channels(path, {.required = {"subject"}}); });
  EXPECT_EQ(e.context().column, "subject");
  EXPECT_NE(e.message().find("char"), std::string::npos);
}

// Any shape with one non-singleton dimension is a vector (h5py's 1 x N x 1 as much as N); with columns
// named, the other datasets are not read (a matrix there is not an error).
TEST(ChannelsHdf5, VectorsOfAnyRankAndOnlyTheNamedColumnsRead) {
  const auto path = tmp_path("ranks.h5");
  {
    H5::H5File file(path, H5F_ACC_TRUNC);
    write_vector(file, "t_s", {0.0, 0.001, 0.002}, {1, 3});
    write_vector(file, "normal_N", {1.0, 2.0, 3.0}, {1, 3, 1});
    write_vector(file, "matrix", {1, 2, 3, 4, 5, 6}, {3, 2});
  }
  const auto table = ts::read_channels(path, {.required = {"normal_N"}});
  EXPECT_EQ(table.names, (std::vector<std::string>{"normal_N"}));
  EXPECT_EQ(table.column("normal_N")[2], 3.0);
  EXPECT_EQ(table.time_s[2], 0.002);
}

TEST(ChannelsHdf5, MismatchedLengthsNanAndBadTimeAreNamed) {
  const auto path = tmp_path("bad.h5");
  {
    H5::H5File file(path, H5F_ACC_TRUNC);
    write_vector(file, "t_s", {0.0, 0.001, 0.002}, {3});
    write_vector(file, "short_N", {1.0, 2.0}, {2});
  }
  auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().column, "short_N");
  EXPECT_NE(e.message().find("2 samples"), std::string::npos);
  {
    H5::H5File file(path, H5F_ACC_TRUNC);
    write_vector(file, "t_s", {0.0, 0.001, 0.002}, {3});
    write_vector(file, "a", {1.0, std::nan(""), 2.0}, {3});
  }
  e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().column, "a");
  EXPECT_NE(e.message().find("sample 1"), std::string::npos);
  {
    H5::H5File file(path, H5F_ACC_TRUNC);
    write_vector(file, "t_s", {0.0, 0.001, 0.001, 0.002}, {4});
  }
  e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().column, "t_s");
  EXPECT_NE(e.message().find("sample 2"), std::string::npos);
  e = expect_error([&] { ts::read_channels(tmp_path("missing.h5")); });
  EXPECT_NE(std::string(e.what()).find("missing.h5"), std::string::npos);
}

// Found by fuzz_channel_hdf5 (tests/fuzz/corpus): a header claiming 4 GB wide floats makes HDF5
// allocate 4 GB for the conversion; the dataset is refused as not numeric.
TEST(ChannelsHdf5, DamagedElementSizeIsRefusedNotAllocated) {
  const std::string path = corpus_file("regression-element-4GB.h5");
  ts::ChannelReadOptions options;
  options.required = {"normal_N"};
  const auto e = expect_error([&] { ts::read_channels(path, options); });
  EXPECT_EQ(e.context().column, "normal_N");
  EXPECT_NE(e.message().find("not a numeric dataset"), std::string::npos) << e.what();
}

// Found by fuzz_channel_hdf5: a header claiming 8.8e12 samples in a 2 kB file would have them allocated.
TEST(ChannelsHdf5, LengthBeyondTheStoredBytesIsRefusedNotAllocated) {
  // Two damaged headers: one whose layout stores little, one whose layout claims the length's bytes too.
  for (const char* name : {"regression-length-2e43.h5", "regression-length-2e43-layout.h5"}) {
    const std::string path = corpus_file(name);
    ts::ChannelReadOptions options;
    options.required = {"normal_N"};
    const auto e = expect_error([&] { ts::read_channels(path, options); });
    EXPECT_EQ(e.context().column, "normal_N");
    EXPECT_NE(e.message().find("claims 8796093022214 samples but the file holds"), std::string::npos)
        << e.what();
  }
}

// Found by fuzz_channel_hdf5: a superblock naming a driver information block at byte 255 of a 2 kB file
// makes HDF5 1.10 allocate 2 GB (and take seconds) before it finds the damage.
TEST(ChannelsHdf5, DriverInformationBlockIsRefusedBeforeHdf5OpensTheFile) {
  const std::string path = corpus_file("regression-driver-info-block.h5");
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_NE(std::string(e.what()).find("regression-driver-info-block.h5"), std::string::npos) << e.what();
  EXPECT_NE(e.message().find("driver information block"), std::string::npos) << e.what();
  // The seed it was mutated from (h5import's output) opens as before.
  const auto seed = ts::read_channels(corpus_file("channels.h5"));
  EXPECT_EQ(seed.samples(), 6u);
  EXPECT_NEAR(seed.sample_rate_Hz, 1000.0, 1e-3);
}

TEST(ChannelsHdf5, DamagedGroupIndexIsRefusedBeforeHdf5ReadsIt) {
  // Two fuzz findings on which HDF5 1.10.8 reads through a null pointer while listing the root group:
  // its B-tree node naming its symbol-table node at an undefined address (and its siblings and local heap
  // overwritten), and its symbol-table message naming its B-tree and heap at undefined addresses.
  const auto child =
      expect_error([&] { ts::read_channels(corpus_file("regression-btree-child-undefined.h5")); });
  EXPECT_NE(std::string(child.what()).find("regression-btree-child-undefined.h5"), std::string::npos)
      << child.what();
  EXPECT_NE(child.message().find("group's index is damaged: the node at byte 96 points to byte 680, which is "
                                 "not a local heap"),
            std::string::npos)
      << child.what();
  const auto table =
      expect_error([&] { ts::read_channels(corpus_file("regression-stab-btree-undefined.h5")); });
  EXPECT_NE(table.message().find("the node at byte 96 points to an undefined address, outside the file"),
            std::string::npos)
      << table.what();
}

TEST(ChannelsHdf5, ACrashInTheChildsReadIsAnErrorNamingTheFileAndTheSignal) {
  // The net under the layout checks (signals/isolated_read.hpp): a read that crashes takes only the child
  // down. The signals' default actions, so that the sanitizers' own handlers do not turn them into others.
  const auto segv = expect_error([] {
    ts::survive_read_in_child("damaged.h5", "HDF5", [] {
      std::signal(SIGSEGV, SIG_DFL);
      std::raise(SIGSEGV);
    });
  });
  EXPECT_EQ(segv.context().file, "damaged.h5");
  EXPECT_NE(segv.message().find("HDF5 crashed (signal 11"), std::string::npos) << segv.what();
  EXPECT_NE(segv.message().find("it was not changed"), std::string::npos) << segv.what();
  const auto abort = expect_error([] {
    ts::survive_read_in_child("damaged.mat", "libmatio (HDF5)", [] {
      std::signal(SIGABRT, SIG_DFL);
      std::abort();
    });
  });
  EXPECT_NE(abort.message().find("libmatio (HDF5) crashed (signal 6"), std::string::npos) << abort.what();
  // A read that ends, or throws (the parent's own read reports that), is no crash.
  EXPECT_NO_THROW(ts::survive_read_in_child("good.h5", "HDF5", [] {}));
  EXPECT_NO_THROW(
      ts::survive_read_in_child("bad.h5", "HDF5", [] { throw tirstrain::Error("not channels"); }));
}

TEST(ChannelsHdf5, AFileOnWhichHdf5ItselfCrashesIsRefusedByTheChildsRead) {
  // HDF5 1.10.8 itself, with no layout check before it, on a fuzz finding it reads through a null pointer
  // (listing the root group): the child crashes, this process gets the error.
  const std::string path = corpus_file("regression-btree-child-undefined.h5");
  const auto e = expect_error([&] {
    ts::survive_read_in_child(path, "HDF5", [&] {
      H5::Exception::dontPrint();
      H5::H5File file(path, H5F_ACC_RDONLY);
      const H5::Group root = file.openGroup("/");
      for (hsize_t i = 0; i < root.getNumObjs(); ++i) (void)root.getObjnameByIdx(i);
    });
  });
  EXPECT_EQ(e.context().file, path);
  EXPECT_NE(e.message().find("HDF5 crashed (signal"), std::string::npos) << e.what();
  std::printf("  %s\n", e.what());
  // Through the reader, the layout check refuses it first, with what is damaged.
  EXPECT_NE(expect_error([&] { ts::read_channels(path); }).message().find("group's index is damaged"),
            std::string::npos);
}

TEST(ChannelsHdf5, CompactDatasetShorterThanItsShapeIsRefusedNotRead) {
  // The time dataset's layout turned compact with no bytes stored for its 6 samples: HDF5 1.10.8 copies
  // them from a null pointer.
  const std::string path = corpus_file("regression-compact-short.h5");
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().column, "t_s") << e.what();
  EXPECT_NE(e.message().find("compact storage holds 0 bytes where its shape and type need 48"),
            std::string::npos)
      << e.what();
}

TEST(ChannelsHdf5, ContiguousSamplesBeyondTheFileAreRefusedNotReadAsZeros) {
  // The seed with t_s's data address (bytes 906–913, in its layout message) moved to 16 bytes before the end
  // of the file: HDF5 1.10.8 reads its 48 bytes without an error, partly from beyond the end.
  const std::string seed = corpus_file("channels.h5");
  std::ifstream in(seed, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::uint64_t moved = bytes.size() - 16;
  for (int k = 0; k < 8; ++k)
    bytes[static_cast<std::size_t>(906 + k)] = static_cast<char>((moved >> (8 * k)) & 0xff);
  const auto path = tmp_path("moved.h5");
  std::ofstream(path, std::ios::binary) << bytes;
  {
    const H5::H5File file(path, H5F_ACC_RDONLY);
    ASSERT_EQ(file.openDataSet("t_s").getOffset(), moved);  // the patch moved what the test means to move
  }
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_EQ(e.context().column, "t_s") << e.what();
  EXPECT_NE(e.message().find("would lie beyond the end of the file (byte 2128 + 48)"), std::string::npos)
      << e.what();
}

TEST(ChannelsHdf5, GroupIndexCheckPassesAUserBlockSubgroupAndInnerNodes) {
  // Valid files of every layout the check walks: a user block before the superblock, a subgroup, and more
  // channels than one symbol-table node holds (2 × 4 by default), so that the group's B-tree has several
  // leaves.
  const auto path = tmp_path("many.h5");
  {
    H5::FileCreatPropList create;
    create.setUserblock(512);
    create.setSymk(2, 1);  // B-tree nodes of 4 children, symbol-table nodes of 2 entries
    H5::H5File file(path, H5F_ACC_TRUNC, create);
    H5::Group group = file.createGroup("/trial");
    const std::vector<double> t{0.0, 0.001, 0.002, 0.003, 0.004};
    write_vector(group, "t_s", t, {5});
    for (int k = 0; k < 40; ++k) write_vector(group, "ch" + std::to_string(k), t, {5});
  }
  {
    // A soft link's symbol-table entry names no object header (an undefined address, cache type 2).
    H5::H5File file(path, H5F_ACC_RDWR);
    ASSERT_GE(H5Lcreate_soft("/trial/ch0", file.getId(), "/alias_of_ch0", H5P_DEFAULT, H5P_DEFAULT), 0);
  }
  const auto table = ts::read_channels(path, {.hdf5_group = "/trial"});
  EXPECT_EQ(table.names.size(), 40u);
  EXPECT_EQ(table.samples(), 5u);
  EXPECT_NEAR(table.sample_rate_Hz, 1000.0, 1e-6);
  // The check does walk it: an inner node's first child turned to the superblock (address 0, after the
  // user block) is refused, named.
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t inner = std::string::npos;
  for (std::size_t at = bytes.find("TREE"); at != std::string::npos; at = bytes.find("TREE", at + 4))
    if (bytes[at + 4] == 0 && bytes[at + 5] > 0) inner = at;
  ASSERT_NE(inner, std::string::npos) << "no inner B-tree node: the test's file has too few channels";
  std::string turned = bytes;
  std::fill_n(turned.begin() + static_cast<std::ptrdiff_t>(inner + 32), 8, '\0');
  const auto damaged = tmp_path("damaged.h5");
  std::ofstream(damaged, std::ios::binary) << turned;
  const auto e = expect_error([&] { ts::read_channels(damaged, {.hdf5_group = "/trial"}); });
  EXPECT_NE(e.message().find("the node at byte " + std::to_string(inner)), std::string::npos) << e.what();
  EXPECT_NE(e.message().find("which is not a B-tree node"), std::string::npos) << e.what();
  // A leaf's first child (a symbol-table node) made undefined is refused as well.
  const std::size_t leaf = bytes.find(std::string("TREE\0\0", 6));
  ASSERT_NE(leaf, std::string::npos);
  turned = bytes;
  std::fill_n(turned.begin() + static_cast<std::ptrdiff_t>(leaf + 32), 8, '\xff');
  const auto undefined = tmp_path("undefined.h5");
  std::ofstream(undefined, std::ios::binary) << turned;
  const auto u = expect_error([&] { ts::read_channels(undefined, {.hdf5_group = "/trial"}); });
  EXPECT_NE(u.message().find("the node at byte " + std::to_string(leaf) +
                             " points to an undefined address, outside the file"),
            std::string::npos)
      << u.what();
}

TEST(Resample, LinearAtFrameTimesAndNoExtrapolation) {
  const std::vector<double> t{0.0, 0.001, 0.002, 0.003};
  const std::vector<double> v{1.0, 3.0, 5.0, 7.0};  // 1 + 2000 t
  const auto r = ts::resample_linear(t, v, {0.0, 0.00025, 0.0015, 0.003});
  EXPECT_DOUBLE_EQ(r[0], 1.0);
  EXPECT_NEAR(r[1], 1.5, 1e-12);
  EXPECT_NEAR(r[2], 4.0, 1e-12);
  EXPECT_DOUBLE_EQ(r[3], 7.0);
  const auto e = expect_error([&] { ts::resample_linear(t, v, {0.001, 0.004}); });
  EXPECT_EQ(e.context().frame, 1);
}

TEST(Alignment, TriggerAndCrossCorrelationRecoverKnownOffset) {
  const auto crossing = ts::first_crossing_s({0.0, 0.1, 0.2, 0.3}, {0.0, 0.0, 1.0, 1.0}, 0.25);
  ASSERT_TRUE(crossing);
  EXPECT_NEAR(*crossing, 0.125, 1e-12);
  EXPECT_NEAR(ts::align_by_trigger(0.125, 0.5).offset_s, 0.375, 1e-12);

  // Plate position sampled at 1 kHz on the channel clock; the camera sees the same motion at 100 fps on a
  // clock 12.34 ms ahead (t_camera = t_channel + offset). Recovered to well under a channel sample.
  const double offset = 0.01234;
  auto motion = [](double t) {
    return 2e-3 * std::sin(2.1 * t) + 1e-3 * std::sin(5.3 * t + 0.4) + 4e-4 * t * t;
  };
  std::vector<double> tc, pc, tv, pv;
  for (int i = 0; i < 3000; ++i) {
    tc.push_back(i * 1e-3);
    pc.push_back(motion(i * 1e-3));  // channel time t ↔ physical time t
  }
  for (int i = 0; i < 280; ++i) {
    const double t_cam = 0.05 + i * 0.01;
    tv.push_back(t_cam);
    pv.push_back(1000.0 * motion(t_cam - offset));  // in mm: units differ on purpose
  }
  const auto a = ts::align_by_cross_correlation(tc, pc, tv, pv, 0.05);
  std::printf("[ measured ] smooth motion: offset error %.3g s (channel sample 1e-3 s)\n",
              a.offset_s - offset);
  EXPECT_NEAR(a.offset_s, offset, 1e-5);  // 1 % of a channel sample
  EXPECT_GT(a.correlation, 0.999);
  EXPECT_EQ(a.method, "cross-correlation");
  EXPECT_EQ(a.samples_compared, 280u);
}

TEST(Alignment, ExplicitOffsetIsTakenAsGiven) {
  const auto a = ts::align_explicit(-0.0421);
  EXPECT_EQ(a.method, "explicit");
  EXPECT_DOUBLE_EQ(a.offset_s, -0.0421);
  expect_error([] { ts::align_explicit(std::nan("")); });
}

TEST(Alignment, TriggerChannelEdgeGivesTheOffset) {
  // A 0 -> 5 V edge with a 4 ms linear rise centred at 0.12345 s on the channel clock, sampled at 1 kHz; the
  // camera saw it at 0.5 s. Linear interpolation of a linear rise is exact, so the 2.5 V crossing is too.
  std::vector<double> t, v;
  for (int i = 0; i < 400; ++i) {
    t.push_back(i * 1e-3);
    v.push_back(5.0 * std::clamp((t.back() - 0.12145) / 0.004, 0.0, 1.0));
  }
  const auto a = ts::align_by_trigger_channel(t, v, 0.5);
  EXPECT_EQ(a.method, "trigger");
  EXPECT_NEAR(a.channel_edge_s, 0.12345, 1e-12);
  EXPECT_NEAR(a.offset_s, 0.5 - 0.12345, 1e-12);
  // An explicit threshold at 1 V: 20 % of the way up the rise.
  EXPECT_NEAR(ts::align_by_trigger_channel(t, v, 0.5, 1.0).channel_edge_s, 0.12145 + 0.0008, 1e-12);
  // Falling edge of the inverted pulse.
  std::vector<double> inverted(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) inverted[i] = 5.0 - v[i];
  EXPECT_NEAR(ts::align_by_trigger_channel(t, inverted, 0.5, {}, false).channel_edge_s, 0.12345, 1e-12);
  // A rising edge is never seen on the inverted pulse, a constant channel has none.
  expect_error([&] { ts::align_by_trigger_channel(t, inverted, 0.5, {}, true); });
  const auto e =
      expect_error([&] { ts::align_by_trigger_channel(t, std::vector<double>(t.size(), 1.0), 0.5); });
  EXPECT_NE(e.message().find("constant"), std::string::npos) << e.message();
}

TEST(Alignment, CrossCorrelationRecoversFractionalOffsetOfARampWithNoise) {
  // The synthetic trials' plate motion: at rest, then a constant-speed stroke from 0.2 s (5 mm/s). Channel at
  // 1 kHz on its own clock; camera at 100 fps with 0.2 ms timestamp jitter on a clock 23.37 ms ahead, plate
  // displacement in pixels (52 px/mm) with 0.05 px measurement noise. The offset is 23.37 channel samples.
  const double offset = 0.02337;
  const auto plate_mm = [](double t) { return t > 0.2 ? 5.0 * (t - 0.2) : 0.0; };
  std::vector<double> tc, pc, tv, pv, pv_clean;
  for (int i = 0; i <= 1200; ++i) {
    tc.push_back(i * 1e-3);
    pc.push_back(plate_mm(tc.back()) * 1e-3);  // metres
  }
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int k = 0; k < 100; ++k) {
    const double t_cam = 0.05 + 0.01 * k + (k > 0 ? 2e-4 * noise(rng) : 0.0);
    tv.push_back(t_cam);
    pv_clean.push_back(52.0 * plate_mm(t_cam - offset));
    pv.push_back(pv_clean.back() + 0.05 * noise(rng));
  }
  // Exact displacement: sub-sample resolution (the nearest whole samples, 23 and 24 ms, are 0.37 ms away).
  const auto exact = ts::align_by_cross_correlation(tc, pc, tv, pv_clean, 0.1);
  std::printf("[ measured ] ramp, exact: offset error %.3g s\n", exact.offset_s - offset);
  EXPECT_NEAR(exact.offset_s, offset, 1e-5);
  const auto a = ts::align_by_cross_correlation(tc, pc, tv, pv, 0.1);
  std::printf("[ measured ] ramp + noise: offset %.6f s, error %.3g s, correlation %.6f\n", a.offset_s,
              a.offset_s - offset, a.correlation);
  // Only the start of the stroke pins the lag; the noise gives σ ≈ 0.06 ms over seeds (measured); 4σ.
  EXPECT_NEAR(a.offset_s, offset, 2.5e-4);
  EXPECT_GT(a.correlation, 0.9999);
  // Lag range too small to reach the truth: the optimum sits on the edge of the range, not at the truth.
  const auto clipped = ts::align_by_cross_correlation(tc, pc, tv, pv, 0.01);
  EXPECT_LE(clipped.offset_s, 0.0100001);
  // A constant camera series cannot be aligned.
  expect_error([&] { ts::align_by_cross_correlation(tc, pc, tv, std::vector<double>(tv.size(), 3.0), 0.1); });
}
