// MATLAB .mat channels through libmatio: files of every version are written here with matio itself (v4,
// v5, v7 compressed, v7.3) and read back exactly: vectors, matrix columns (1-based), named columns, struct
// fields, a sample rate instead of a time vector, calibration; errors name file, variable and what was
// expected.
#include <gtest/gtest.h>

#include <matio.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "signals/channels.hpp"
#include "tests/signals/cli_run.hpp"
#include "tests/support/expect_error.hpp"

namespace ts = tirstrain::signals;

namespace {

constexpr std::size_t kSamples = 6;

// One folder per test (CTest runs tests in parallel processes); every file in it is written anew.
std::string tmp(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "signals_mat" /
                                    ::testing::UnitTest::GetInstance()->current_test_info()->name();
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

// Values exact in binary so every comparison is ==.
double force(std::size_t i) {
  return 0.25 * static_cast<double>(i) - 1.0;
}
double column_value(std::size_t i, std::size_t k) {
  return static_cast<double>(100 * k + i) / 8.0;
}

void add(mat_t* mat, matvar_t* var, matio_compression compression) {
  ASSERT_NE(var, nullptr);
  ASSERT_EQ(Mat_VarWrite(mat, var, compression), 0);
  Mat_VarFree(var);
}

matvar_t* vector_var(const char* name, std::vector<double> values) {
  std::size_t dims[2] = {values.size(), 1};
  return Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, values.data(), 0);
}

// t (s), force (N x 1), dataQ (N x 3, column-major), and in v5+ rec.force.Fz (a struct in a struct) and a
// char array.
void write_recording(const std::string& path, mat_ft version, matio_compression compression, bool with_time) {
  mat_t* mat = Mat_CreateVer(path.c_str(), nullptr, version);
  ASSERT_NE(mat, nullptr) << "matio cannot write this version";
  std::vector<double> t(kSamples), f(kSamples), q(kSamples * 3);
  for (std::size_t i = 0; i < kSamples; ++i) {
    t[i] = static_cast<double>(i) / 1024.0;
    f[i] = force(i);
    for (std::size_t k = 0; k < 3; ++k) q[k * kSamples + i] = column_value(i, k);
  }
  if (with_time) add(mat, vector_var("t", t), compression);
  add(mat, vector_var("force", f), compression);
  std::size_t qdims[2] = {kSamples, 3};
  add(mat, Mat_VarCreate("dataQ", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, qdims, q.data(), 0), compression);
  if (version != MAT_FT_MAT4) {
    std::size_t one[2] = {1, 1};
    const char* inner_fields[] = {"Fz"};
    matvar_t* inner = Mat_VarCreateStruct("force", 2, one, inner_fields, 1);
    std::vector<double> fz(kSamples);
    for (std::size_t i = 0; i < kSamples; ++i) fz[i] = 2.0 * force(i);
    Mat_VarSetStructFieldByName(inner, "Fz", 0, vector_var("Fz", fz));
    const char* outer_fields[] = {"force"};
    matvar_t* rec = Mat_VarCreateStruct("rec", 2, one, outer_fields, 1);
    Mat_VarSetStructFieldByName(rec, "force", 0, inner);
    add(mat, rec, compression);
    const char text[] = "subject 1";
    std::size_t cdims[2] = {1, sizeof text - 1};
    add(mat, Mat_VarCreate("note", MAT_C_CHAR, MAT_T_UINT8, 2, cdims, const_cast<char*>(text), 0),
        compression);
  }
  Mat_Close(mat);
}

using tirstrain::testing::expect_error;

struct Version {
  const char* name;
  mat_ft version;
  matio_compression compression;
};

TEST(MatChannels, EveryVersionReadsVectorsColumnsAndStructFieldsExactly) {
  for (const Version& v :
       {Version{"v4", MAT_FT_MAT4, MAT_COMPRESSION_NONE}, Version{"v5", MAT_FT_MAT5, MAT_COMPRESSION_NONE},
        Version{"v7", MAT_FT_MAT5, MAT_COMPRESSION_ZLIB},
        Version{"v73", MAT_FT_MAT73, MAT_COMPRESSION_NONE}}) {
    SCOPED_TRACE(v.name);
    const std::string path = tmp(std::string(v.name) + ".mat");
    write_recording(path, v.version, v.compression, true);
    std::vector<std::string> wanted = {"force", "dataQ[:,2]"};
    if (v.version != MAT_FT_MAT4) wanted.push_back("rec.force.Fz");
    const auto table = ts::read_channels(path, {.time_column = "t", .required = wanted});
    EXPECT_EQ(table.sample_rate_Hz, 1024.0);
    for (std::size_t i = 0; i < kSamples; ++i) {
      EXPECT_EQ(table.time_s[i], static_cast<double>(i) / 1024.0);
      EXPECT_EQ(table.column("force")[i], force(i));
      EXPECT_EQ(table.column("dataQ[:,2]")[i], column_value(i, 1));
      if (v.version != MAT_FT_MAT4) {
        EXPECT_EQ(table.column("rec.force.Fz")[i], 2.0 * force(i));
      }
    }
  }
}

TEST(MatChannels, NamedColumnsCalibrationAndARateInsteadOfATimeVector) {
  const std::string path = tmp("rec.mat");
  write_recording(path, MAT_FT_MAT5, MAT_COMPRESSION_ZLIB, false);
  ts::ChannelReadOptions options;
  options.mat_column_names = {{"dataQ", {"lateral_V", "normal_N", "vib_V"}}};
  options.calibration = {{"normal_N", {.gain = 4.0, .offset = -0.5}}};
  options.rate_Hz = 10000.0;
  const auto table = ts::read_channels(path, options);
  EXPECT_EQ(table.names, (std::vector<std::string>{"lateral_V", "normal_N", "vib_V"}));
  for (std::size_t i = 0; i < kSamples; ++i) {
    EXPECT_EQ(table.time_s[i], static_cast<double>(i) / 10000.0);
    EXPECT_EQ(table.column("lateral_V")[i], column_value(i, 0));
    EXPECT_EQ(table.column("normal_N")[i], 4.0 * column_value(i, 1) - 0.5);
  }
  EXPECT_NE(table.time_source.find("10000 Hz"), std::string::npos) << table.time_source;
  // Without the rate there is no time axis, and the message says how to give one.
  options.rate_Hz.reset();
  auto e = expect_error([&] { ts::read_channels(path, options); });
  EXPECT_EQ(e.context().file, path);
  EXPECT_EQ(e.context().column, "t_s");
  EXPECT_NE(e.message().find("--rate-Hz"), std::string::npos) << e.what();
  // A calibration for a channel the file does not have would leave volts labelled as newtons.
  options.rate_Hz = 10000.0;
  options.calibration = {{"normal", {.gain = 4.0}}};
  e = expect_error([&] { ts::read_channels(path, options); });
  EXPECT_EQ(e.context().column, "normal");
}

TEST(MatChannels, ErrorsNameTheFileTheVariableAndWhatWasExpected) {
  const std::string path = tmp("rec.mat");
  write_recording(path, MAT_FT_MAT5, MAT_COMPRESSION_NONE, true);
  const auto read = [&](const std::string& name) {
    ts::read_channels(path, {.time_column = "t", .required = {name}});
  };
  auto e = expect_error([&] { read("dataQ"); });
  EXPECT_EQ(e.context().column, "dataQ");
  EXPECT_NE(e.message().find("6x3 matrix"), std::string::npos) << e.what();
  EXPECT_NE(e.message().find("dataQ[:,k] (k = 1..3)"), std::string::npos) << e.what();
  e = expect_error([&] { read("dataQ[:,4]"); });
  EXPECT_NE(e.message().find("column 4"), std::string::npos) << e.what();
  e = expect_error([&] { read("forse"); });
  EXPECT_NE(e.message().find("no variable 'forse'"), std::string::npos) << e.what();
  EXPECT_NE(e.message().find("dataQ"), std::string::npos) << e.what();
  e = expect_error([&] { read("rec.force.Fy"); });
  EXPECT_NE(e.message().find("no field 'Fy' (fields: Fz)"), std::string::npos) << e.what();
  e = expect_error([&] { read("note"); });
  EXPECT_NE(e.message().find("char array"), std::string::npos) << e.what();
  e = expect_error(
      [&] { ts::read_channels(path, {.time_column = "t", .required = {"force"}, .rate_Hz = 100.0}); });
  EXPECT_EQ(e.context().key, "--rate-Hz");
  // Not a MAT-file at all.
  std::ofstream(tmp("text.mat")) << "t_s,force\n0,1\n";
  e = expect_error([&] { ts::read_channels(tmp("text.mat")); });
  EXPECT_NE(e.message().find("v4, v5, v7 and v7.3"), std::string::npos) << e.what();
  // A MAT-file under another name is still read as one; other binary is named, not parsed as CSV.
  std::filesystem::copy_file(path, tmp("rec.daq"), std::filesystem::copy_options::overwrite_existing);
  EXPECT_EQ(ts::read_channels(tmp("rec.daq"), {.time_column = "t", .required = {"force"}}).column("force")[1],
            force(1));
  std::ofstream(tmp("image.bin"), std::ios::binary) << std::string("II*\0\0\0\0\0", 8);
  e = expect_error([&] { ts::read_channels(tmp("image.bin")); });
  EXPECT_NE(e.message().find("binary, starting with 'II*.....'"), std::string::npos) << e.what();
  EXPECT_NE(e.message().find("HDF5"), std::string::npos) << e.what();
}

// With no channel named, every numeric vector is a channel: one with a NaN sample is an error naming it,
// not a channel left out; a file with no vector at all is an error, not a table of times alone.
TEST(MatChannels, UnnamedChannelsAreEveryVectorWhoseSamplesMustBeFinite) {
  const std::string path = tmp("rec.mat");
  write_recording(path, MAT_FT_MAT5, MAT_COMPRESSION_NONE, true);
  EXPECT_EQ(ts::read_channels(path, {.time_column = "t"}).names, (std::vector<std::string>{"force"}));
  const std::string nan_path = tmp("nan.mat");
  {
    mat_t* mat = Mat_CreateVer(nan_path.c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(mat, nullptr);
    add(mat, vector_var("t", {0.0, 0.001, 0.002, 0.003}), MAT_COMPRESSION_NONE);
    add(mat, vector_var("normal_N", {1.0, std::nan(""), 1.0, 1.0}), MAT_COMPRESSION_NONE);
    add(mat, vector_var("tangential_N", {0.1, 0.2, 0.3, 0.4}), MAT_COMPRESSION_NONE);
    Mat_Close(mat);
  }
  auto e = expect_error([&] { ts::read_channels(nan_path, {.time_column = "t"}); });
  EXPECT_EQ(e.context().column, "normal_N");
  EXPECT_NE(e.message().find("sample 1 (0-based) is not a finite number"), std::string::npos) << e.what();
  const std::string matrix_path = tmp("matrix.mat");
  {
    mat_t* mat = Mat_CreateVer(matrix_path.c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(mat, nullptr);
    add(mat, vector_var("t", {0.0, 0.001}), MAT_COMPRESSION_NONE);
    std::vector<double> q = {1, 2, 3, 4};
    std::size_t qdims[2] = {2, 2};
    add(mat, Mat_VarCreate("dataQ", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, qdims, q.data(), 0), MAT_COMPRESSION_NONE);
    Mat_Close(mat);
  }
  e = expect_error([&] { ts::read_channels(matrix_path, {.time_column = "t"}); });
  EXPECT_NE(e.message().find("holds no numeric vector besides the time axis (dataQ)"), std::string::npos)
      << e.what();
}

// `signals resample --columns` takes a matrix column's selector whole: its comma is not a separator.
TEST(MatChannels, ResampleColumnsKeepsASelectorsComma) {
  const std::string path = tmp("rec.mat"), times = tmp("times.csv"), out = tmp("out.csv");
  write_recording(path, MAT_FT_MAT5, MAT_COMPRESSION_NONE, true);
  std::ofstream(times) << "t_s\n" << tirstrain::format_double(2.0 / 1024.0) << "\n";
  const auto r = tirstrain::testing::run_cli("signals resample " + path + " --time-column t --times " +
                                             times + " --columns 'dataQ[:,2],force' --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto table = tirstrain::read_numeric_csv(out);
  EXPECT_EQ(table.names, (std::vector<std::string>{"t", "dataQ[:,2]", "force"}));
  EXPECT_EQ(table.column("dataQ[:,2]")[0], column_value(2, 1));
  EXPECT_EQ(table.column("force")[0], force(2));
}

TEST(ChannelsCsv, RateInsteadOfATimeColumn) {
  const std::string path = tmp("daq.csv");
  std::ofstream(path) << "force_V\n1\n2\n3\n";
  const auto table = ts::read_channels(path, {.rate_Hz = 4.0, .calibration = {{"force_V", {.gain = 2.0}}}});
  EXPECT_EQ(table.time_s, (std::vector<double>{0.0, 0.25, 0.5}));
  EXPECT_EQ(table.column("force_V"), (std::vector<double>{2.0, 4.0, 6.0}));
  const auto e = expect_error([&] { ts::read_channels(path); });
  EXPECT_NE(e.message().find("--rate-Hz"), std::string::npos) << e.what();
}

}  // namespace
