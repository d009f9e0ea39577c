#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "cli_support.hpp"
#include "core/csv.hpp"
#include "core/h5_file.hpp"
#include "model/cattaneo_mindlin.hpp"

namespace tirstrain {
namespace {

using testing::fresh_dir;
using testing::run_cli;

const std::string kLoads =
    "model cattaneo-mindlin --normal-N 2 --tangential-N 1.2 --radius-m 0.01 --young-Pa 1e6 --poisson 0.4 "
    "--friction 1.0";

TEST(ModelCli, GridModeWritesH5MapsAndSummary) {
  const std::string out = fresh_dir("model_grid");
  const auto r = run_cli(kLoads + " --grid 41 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"model.h5", "strain_Exx.png", "strain_Eyy.png", "strain_Exy.png",
                        "energy_density.png", "summary.json"})
    EXPECT_TRUE(std::filesystem::exists(out + "/" + f)) << f;

  const model::CattaneoMindlin cm({.normal_N = 2,
                                   .tangential_N = 1.2,
                                   .radius_m = 0.01,
                                   .young_Pa = 1e6,
                                   .poisson = 0.4,
                                   .friction = 1.0});
  std::ifstream in(out + "/summary.json");
  const auto summary = nlohmann::json::parse(in);
  EXPECT_DOUBLE_EQ(summary["contact_radius_m"].get<double>(), cm.hertz().contact_radius_m);
  EXPECT_DOUBLE_EQ(summary["stick_radius_m"].get<double>(), cm.stick_radius_m());

  H5Reader h5(out + "/model.h5");
  H5Shape shape;
  const auto strain = h5.read_doubles("/strain", &shape);
  ASSERT_EQ(shape, (H5Shape{41, 41, 3}));
  const auto x = h5.read_doubles("/grid/x_m");
  // Spot-check one grid node against the library.
  const std::size_t r0 = 13, c0 = 29;
  const auto s = cm.evaluate(x[c0], x[r0]);
  EXPECT_DOUBLE_EQ(strain[(r0 * 41 + c0) * 3 + 0], s.strain.xx);
  EXPECT_DOUBLE_EQ(strain[(r0 * 41 + c0) * 3 + 2], s.strain.xy);
  EXPECT_DOUBLE_EQ(h5.attribute_number("/", "stick_radius_m"), cm.stick_radius_m());
}

// The output folder is staged and swapped in whole: a rerun replaces the earlier output (no staging folder
// left), and a folder holding anything else is refused before anything is written, the file untouched.
TEST(ModelCli, GridOutputIsReplacedWholeAndForeignFilesAreRefused) {
  const std::string out = fresh_dir("model_grid_rerun");
  ASSERT_EQ(run_cli(kLoads + " --grid 41 --out " + out).exit_code, 0);
  ASSERT_EQ(run_cli(kLoads + " --grid 21 --out " + out).exit_code, 0);
  H5Shape shape;
  H5Reader(out + "/model.h5").read_doubles("/strain", &shape);
  EXPECT_EQ(shape, (H5Shape{21, 21, 3}));
  EXPECT_FALSE(std::filesystem::exists(out + ".partial"));

  const std::string mixed = fresh_dir("model_grid_foreign");
  std::filesystem::create_directories(mixed);
  std::ofstream(mixed + "/notes.txt") << "mine\n";
  const auto r = run_cli(kLoads + " --grid 21 --out " + mixed);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("notes.txt"), std::string::npos) << r.output;
  EXPECT_TRUE(std::filesystem::exists(mixed + "/notes.txt"));
  EXPECT_FALSE(std::filesystem::exists(mixed + "/model.h5"));
}

TEST(ModelCli, PointsModeWritesFullPrecisionColumns) {
  const std::string dir = fresh_dir("model_points");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/in.csv") << "x_m,y_m\n0,0\n0.001,-0.0005\n0.004,0.002\n";
  const auto r =
      run_cli(kLoads + " --direction-deg 30 --points " + dir + "/in.csv --out " + dir + "/out.csv");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const CsvTable t = read_numeric_csv(dir + "/out.csv");
  const std::vector<std::string> expected = {"x_m", "y_m", "ux_m", "uy_m", "Hxx", "Hxy",
                                             "Hyx", "Hyy", "Exx",  "Eyy",  "Exy", "energy_J_m3"};
  EXPECT_EQ(t.names, expected);
  ASSERT_EQ(t.rows(), 3u);
  const model::CattaneoMindlin cm({.normal_N = 2,
                                   .tangential_N = 1.2,
                                   .radius_m = 0.01,
                                   .young_Pa = 1e6,
                                   .poisson = 0.4,
                                   .friction = 1.0,
                                   .direction_rad = M_PI / 6});
  for (std::size_t i = 0; i < 3; ++i) {
    const auto s = cm.evaluate(t.column("x_m")[i], t.column("y_m")[i]);
    EXPECT_EQ(t.column("ux_m")[i], s.displacement_m.x);  // exact: written with round-trip precision
    EXPECT_EQ(t.column("Hyx")[i], s.gradient.yx);
    EXPECT_EQ(t.column("energy_J_m3")[i], s.energy_density_J_m3);
  }
}

struct Refusal {
  std::string arguments;
  std::string option;  // the message must name it
};

TEST(ModelCli, RefusedInputsNameTheOption) {
  const std::string base =
      "model cattaneo-mindlin --radius-m 0.01 --young-Pa 1e6 --poisson 0.4 --friction 1 ";
  const std::string out = " --grid 5 --out " + fresh_dir("model_refused");
  const std::vector<Refusal> cases = {
      {base + "--normal-N 2 --tangential-N 2.5" + out, "--tangential-N"},
      {base + "--normal-N -1 --tangential-N 0" + out, "--normal-N"},
      {base + "--normal-N 2 --tangential-N -0.1" + out, "--tangential-N"},
      {"model cattaneo-mindlin --radius-m 0.01 --young-Pa 1e6 --poisson 0.5 --friction 1 --normal-N 2 "
       "--tangential-N 1" +
           out,
       "--poisson"},
      {"model cattaneo-mindlin --radius-m 0 --young-Pa 1e6 --poisson 0.4 --friction 1 --normal-N 2 "
       "--tangential-N 1" +
           out,
       "--radius-m"},
      {"model cattaneo-mindlin --radius-m 0.01 --young-Pa -5 --poisson 0.4 --friction 1 --normal-N 2 "
       "--tangential-N 1" +
           out,
       "--young-Pa"},
      {"model cattaneo-mindlin --radius-m 0.01 --young-Pa 1e6 --poisson 0.4 --friction 0 --normal-N 2 "
       "--tangential-N 0" +
           out,
       "--friction"},
      {base + "--normal-N 2 --tangential-N 1 --out x", "--grid"},
      {base + "--normal-N 2 --tangential-N 1 --grid 1 --out x", "--grid"},
      {base + "--normal-N abc --tangential-N 1" + out, "--normal-N"},
  };
  for (const auto& c : cases) {
    const auto r = run_cli(c.arguments);
    EXPECT_NE(r.exit_code, 0) << c.arguments;
    EXPECT_NE(r.output.find(c.option), std::string::npos) << c.arguments << "\n" << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists(std::string(TIRSTRAIN_TEST_TMP) + "/model_refused/model.h5"));
}

TEST(ModelCli, BadPointsFileNamesRowAndColumn) {
  const std::string dir = fresh_dir("model_badpoints");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/in.csv") << "x_m,y_m\n0,0\n0.001,oops\n";
  const auto r = run_cli(kLoads + " --points " + dir + "/in.csv --out " + dir + "/out.csv");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("row 3: column 'y_m': not a number"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.csv"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.csv.partial"));
}

TEST(ModelCli, PointsModeNeverWritesOverItsInput) {
  const std::string dir = fresh_dir("model_points_in_place");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/p.csv") << "x_m,y_m\n0,0\n";
  const auto r = run_cli(kLoads + " --points " + dir + "/p.csv --out " + dir + "/./p.csv");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("is the points file being read"), std::string::npos) << r.output;
  std::ifstream in(dir + "/p.csv");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "x_m,y_m\n0,0\n");
}

}  // namespace
}  // namespace tirstrain
