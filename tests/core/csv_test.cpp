#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain {
namespace {

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = std::string(TIRSTRAIN_TEST_TMP) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  try {
    read_numeric_csv(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Csv, ReadsColumnsByName) {
  const auto path = write_file("ok.csv", "t_s,normal_N\n0,1.5\n0.001,-2e-3\n\n");
  const CsvTable t = read_numeric_csv(path);
  ASSERT_EQ(t.rows(), 2u);
  EXPECT_DOUBLE_EQ(t.column("normal_N")[1], -2e-3);
  EXPECT_DOUBLE_EQ(t.column("t_s")[1], 0.001);
}

// A table `process` wrote marks a value not measured in a frame "nan": read so, it is NaN; infinities
// and text stay errors.
TEST(Csv, ReadsNaNCellsOnlyWhenAllowed) {
  const auto path = write_file("not_measured.csv", "index,c_mm\n0,2.5\n1,nan\n");
  const CsvTable t = read_numeric_csv(path, NaNCells::kNotMeasured);
  ASSERT_EQ(t.rows(), 2u);
  EXPECT_DOUBLE_EQ(t.column("c_mm")[0], 2.5);
  EXPECT_TRUE(std::isnan(t.column("c_mm")[1]));
  EXPECT_NE(error_of(path).find("row 3: column 'c_mm': non-finite"), std::string::npos);
  EXPECT_THROW(read_numeric_csv(write_file("inf.csv", "a\ninf\n"), NaNCells::kNotMeasured), Error);
  EXPECT_THROW(read_numeric_csv(write_file("text2.csv", "a\nn/a\n"), NaNCells::kNotMeasured), Error);
}

TEST(Csv, ErrorsNameFileRowAndColumn) {
  EXPECT_NE(error_of(write_file("text.csv", "a,b\n1,2\n3,x\n")).find("row 3: column 'b': not a number"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("empty.csv", "a,b\n1,\n")).find("row 2: column 'b': empty cell"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("nan.csv", "a,b\n1,nan\n")).find("column 'b': non-finite"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("ragged.csv", "a,b\n1,2,3\n")).find("row 2: expected 2 cells, found 3"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("dup.csv", "a,a\n1,2\n")).find("duplicate column"), std::string::npos);
  EXPECT_NE(error_of(std::string(TIRSTRAIN_TEST_TMP) + "/missing.csv").find("cannot open"),
            std::string::npos);
  const auto path = write_file("cols.csv", "a,b\n1,2\n");
  try {
    read_numeric_csv(path).column("c");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("column 'c': no such column (columns present: a, b)"),
              std::string::npos);
    EXPECT_EQ(e.context().file, path);
  }
}

// What spreadsheets and other programs write: a byte-order mark is read past; CRLF is read; a number too
// small for a double is 0 and one too large an error; other separators and CR-only lines are named.
TEST(Csv, SpreadsheetExportsAreReadOrNamed) {
  const CsvTable bom =
      read_numeric_csv(write_file("bom.csv", "\xEF\xBB\xBFt_s,normal_N\r\n0,1\r\n1,2e-400\r\n"));
  ASSERT_EQ(bom.names.front(), "t_s");
  EXPECT_DOUBLE_EQ(bom.column("normal_N")[0], 1.0);
  EXPECT_EQ(bom.column("normal_N")[1], 0.0);
  EXPECT_NE(
      error_of(write_file("huge.csv", "a\n1e400\n")).find("row 2: column 'a': '1e400' is beyond the range"),
      std::string::npos);
  EXPECT_NE(error_of(write_file("semicolon.csv", "t_s;normal_N\n0;1,5\n")).find("separated by ';'"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("tab.csv", "t_s\tnormal_N\n0\t1\n")).find("separated by tabs"),
            std::string::npos);
  EXPECT_NE(error_of(write_file("cr.csv", "t_s,normal_N\r0,1\r1,2\r")).find("carriage return alone"),
            std::string::npos);
}

// A name or text cell holding a comma or a quote is written quoted and read back whole.
TEST(Csv, QuotedCellsRoundTrip) {
  const std::string path = std::string(TIRSTRAIN_TEST_TMP) + "/quoted.csv";
  {
    CsvWriter out(path, {"t_s", "dataQ[:,2]", "say \"hi\""});
    out.row({0.5, 1.0, 2.0});
    out.commit();
  }
  const CsvTable t = read_numeric_csv(path);
  ASSERT_EQ(t.names, (std::vector<std::string>{"t_s", "dataQ[:,2]", "say \"hi\""}));
  EXPECT_EQ(t.column("dataQ[:,2]")[0], 1.0);
  EXPECT_EQ(split_csv_line("a, \"b,c\" ,\"d\"\"e\"\r"), (std::vector<std::string>{"a", "b,c", "d\"e"}));
  EXPECT_EQ(csv_cell("plain"), "plain");
}

TEST(Csv, WriterRoundTripsFullPrecisionAndIsAtomic) {
  const std::string path = std::string(TIRSTRAIN_TEST_TMP) + "/written.csv";
  std::filesystem::remove(path);
  {
    CsvWriter w(path, {"x", "y"});
    w.row({0.1, 1.0 / 3.0});
    EXPECT_FALSE(std::filesystem::exists(path));  // only the partial file exists until commit
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  CsvWriter w(path, {"x", "y"});
  w.row({0.1, 1.0 / 3.0});
  w.commit();
  const CsvTable t = read_numeric_csv(path);
  EXPECT_EQ(t.column("y")[0], 1.0 / 3.0);
  EXPECT_EQ(t.column("x")[0], 0.1);
}

}  // namespace
}  // namespace tirstrain
