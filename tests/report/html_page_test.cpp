// The page's text: scripts inlined (nothing fetched), text escaped, a specification that holds "</script>"
// unable to end its element, the polar histogram's bins, and the refusals of write_report.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <numbers>

#include "report/figures.hpp"
#include "report/html_page.hpp"
#include "report/report.hpp"
#include "report/vendored_scripts.hpp"

namespace tirstrain::report {
namespace {

namespace fs = std::filesystem;

TEST(ReportPage, InlinesThePinnedScriptsAndEscapesText) {
  Page page;
  page.title = "A & B";
  Figure f;
  f.id = "f1";
  f.title = "Title <1>";
  f.caption = "E_xx in 1/s";
  f.spec = {{"title", "</script><script>alert(1)</script>"}};
  page.figures.push_back(f);
  const std::string html = render_page(page);
  for (const VendoredScript& s : vendored_scripts()) {
    EXPECT_GT(s.code.size(), 10000u) << s.name;
    EXPECT_NE(s.version, "unknown") << s.name;
    EXPECT_NE(html.find("data-library=\"" + std::string(s.name) + "@" + s.version + "\""), std::string::npos);
    EXPECT_NE(s.licence.find("Redistribution"), std::string_view::npos) << s.name;
  }
  EXPECT_NE(html.find("<title>A &amp; B</title>"), std::string::npos);
  EXPECT_NE(html.find("<b>Title &lt;1&gt;.</b>"), std::string::npos);
  EXPECT_EQ(html.find("</script><script>alert"), std::string::npos);
  EXPECT_NE(html.find("<\\/script><script>alert(1)<\\/script>"), std::string::npos);
  // Nothing is fetched: no script or stylesheet points anywhere.
  EXPECT_EQ(html.find("src=\"http"), std::string::npos);
  EXPECT_EQ(html.find("href=\"http"), std::string::npos);
}

TEST(ReportPage, PolarHistogramBinsAxialAnglesAndMirrorsThem) {
  ResultData r;
  r.label = "r";
  r.t_s = {0.0};
  r.principal_directions.what = "test";
  // Three at 5° (bin 0), one at 175° (bin 17): fractions 0.75 and 0.25, each drawn twice.
  for (double deg : {5.0, 5.0, 5.0, 175.0}) {
    r.principal_directions.angle_rad.push_back(deg * std::numbers::pi / 180.0);
    r.principal_directions.weight.push_back(1.0);
  }
  const std::vector<Figure> figures = result_figures({r});
  ASSERT_EQ(figures.size(), 1u);
  EXPECT_EQ(figures[0].id, "principal-directions");
  const auto& rows = figures[0].spec["hconcat"][0]["data"]["values"];
  ASSERT_EQ(rows.size(), 36u);
  EXPECT_DOUBLE_EQ(rows[0]["fraction"].get<double>(), 0.75);
  EXPECT_DOUBLE_EQ(rows[18]["fraction"].get<double>(), 0.75);
  EXPECT_DOUBLE_EQ(rows[17]["fraction"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(rows[35]["fraction"].get<double>(), 0.25);
  // 0° (+x) sits at Vega's π/2 (3 o'clock), the bins 10° wide.
  EXPECT_NEAR(rows[0]["theta0"].get<double>(), std::numbers::pi / 2, 1e-4);
  EXPECT_NEAR(rows[1]["theta0"].get<double>() - rows[0]["theta0"].get<double>(), std::numbers::pi / 18, 1e-4);
}

// A result whose input had no timestamps has the frame number as t_s: its time axes say so, not seconds.
TEST(ReportPage, AnUntimedResultsAxisSaysFrameNumber) {
  ResultData r;
  r.label = "r";
  r.t_s = {0.0, 1.0, 2.0};
  r.area_mm2 = {30.0, 31.0, 32.0};
  for (const bool timed : {true, false}) {
    r.time_measured = timed;
    const std::vector<Figure> figures = result_figures({r});
    ASSERT_FALSE(figures.empty());
    const std::string spec = figures[0].spec.dump();
    EXPECT_EQ(spec.find("time (s)") != std::string::npos, timed) << spec;
    EXPECT_EQ(spec.find("frame number (the input has no timestamps") != std::string::npos, !timed) << spec;
  }
}

TEST(ReportPage, WriteReportRefusesToOverwriteAnInputOrAFolder) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "report_refusals";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "result.h5") << "not touched";
  ReportOptions o;
  o.results = {dir.string()};
  o.out_path = (dir / "result.h5").string();
  EXPECT_THROW((void)write_report(o), std::exception);
  o.out_path = dir.string();
  EXPECT_THROW((void)write_report(o), std::exception);
  o.out_path = (dir / "report.html").string();
  EXPECT_THROW((void)write_report(o), std::exception) << "inside the result folder";
  o.out_path = (dir.parent_path() / "report_refusals.html").string();
  o.validations = {"a", "b"};
  try {
    (void)write_report(o);
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("one --validation folder per result"), std::string::npos)
        << e.what();
  }
  std::ifstream in(dir / "result.h5");
  std::string kept;
  std::getline(in, kept);
  EXPECT_EQ(kept, "not touched");
  EXPECT_FALSE(fs::exists(dir / "report.html"));
  EXPECT_FALSE(fs::exists(dir.parent_path() / "report_refusals.html"));
}

// --out never replaces what it reads (a validation table) nor a file it did not write; a missing or wrong
// input is named as such.
TEST(ReportPage, WriteReportReplacesOnlyItsOwnPagesAndNamesWrongInputs) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "report_own_pages";
  fs::remove_all(dir);
  fs::create_directories(dir / "result");
  fs::create_directories(dir / "validation");
  std::ofstream(dir / "validation" / "validation.csv") << "quantity,reference,mode,unit,rms\n";
  std::ofstream(dir / "notes.txt") << "a user's notes";
  const auto message = [](const ReportOptions& o) {
    try {
      (void)write_report(o);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  ReportOptions o;
  o.results = {(dir / "no_such_result").string()};
  o.out_path = (dir / "page.html").string();
  EXPECT_NE(message(o).find("no such result"), std::string::npos) << message(o);
  std::ofstream(dir / "result" / "result.h5") << "not an HDF5 file";
  o.results = {(dir / "result").string()};
  o.validations = {(dir / "validation").string()};
  o.out_path = (dir / "validation" / "validation.csv").string();
  EXPECT_NE(message(o).find("is inside the input folder"), std::string::npos) << message(o);
  o.out_path = (dir / "notes.txt").string();
  EXPECT_NE(message(o).find("is not a page tirstrain report wrote"), std::string::npos) << message(o);
  std::ifstream notes(dir / "notes.txt");
  std::string kept;
  std::getline(notes, kept);
  EXPECT_EQ(kept, "a user's notes");
  std::ifstream table(dir / "validation" / "validation.csv");
  std::getline(table, kept);
  EXPECT_EQ(kept, "quantity,reference,mode,unit,rms");
}

}  // namespace
}  // namespace tirstrain::report
