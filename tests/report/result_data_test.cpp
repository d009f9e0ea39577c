// read_result on a result.h5 written here with known contents: every series and instant the report draws
// is checked against the numbers put in.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "core/h5_file.hpp"
#include "report/result_data.hpp"
#include "report/validation_data.hpp"

namespace tirstrain::report {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t kFrames = 5, kCells = 5;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / ("report_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_frames_and_contact(H5Writer& h5) {
  h5.write("/frames/t_s", std::vector<double>{0.0, 0.1, 0.2, 0.3, 0.4}, {kFrames});
  h5.write("/contact/area_mm2", std::vector<double>{30, 0, 32, 33, 34}, {kFrames});  // frame 1: no contact
  std::vector<double> ellipse(kFrames * 5, 0.0);
  for (std::size_t i = 0; i < kFrames; ++i)
    if (i != 1) {  // frame 1 has no ellipse: zeros
      ellipse[i * 5 + 2] = 150.0;
      ellipse[i * 5 + 3] = 100.0;
    }
  h5.write("/contact/ellipse", ellipse, {kFrames, 5});
  h5.attribute("/contact", "px_per_mm", 50.0);
}

// Tracks 0, 1 seeded in frame 0; 1 retired in frame 3; 2 born in frame 2; 3 born in frame 3.
void write_tracks(H5Writer& h5) {
  h5.write("/tracks/born_frame", std::vector<std::int32_t>{0, 0, 2, 3}, {4});
  h5.write("/tracks/retired_frame", std::vector<std::int32_t>{-1, 3, -1, -1}, {4});
  h5.attribute("/tracks", "reference_frame_row", 0.0);
}

void write_channels_and_events(H5Writer& h5) {
  h5.write("/channels/at_frames/in_span", std::vector<std::uint8_t>{0, 1, 1, 1, 1}, {kFrames});
  h5.write("/channels/at_frames/normal_force_N", std::vector<double>{0, 2, 2, 2, 2}, {kFrames});
  h5.write("/channels/at_frames/tangential_force_N", std::vector<double>{0, 0.5, 1.0, 1.8, 2.0}, {kFrames});
  h5.write("/friction/mu", std::vector<double>{0, 0.25, 0.5, 0.9, 1.0}, {kFrames});
  h5.write("/friction/valid", std::vector<std::uint8_t>{0, 1, 1, 1, 0}, {kFrames});
  h5.write("/events/onset_frame", std::vector<std::int64_t>{1}, {1});
  h5.write("/events/t90_frame", std::vector<std::int64_t>{2}, {1});
  h5.write("/events/full_slip_frame", std::vector<std::int64_t>{3}, {1});
  h5.write("/energy/total_J", std::vector<double>{0, 1e-6, 4e-6, 9e-6, 9e-6}, {kFrames});
  // 1 % of the largest work is 1e-6: frame 1's 5e-7 is below it, its ratio not drawn.
  h5.write("/work/external_cumulative_J", std::vector<double>{0, 5e-7, 2e-5, 6e-5, 1e-4}, {kFrames});
  h5.write("/work/energy_ratio", std::vector<double>{0.2}, {1});
  // The stick fit: c = a at rest, then no slip seen within the tracks (status 3), then fitted.
  h5.write("/stick/radius_ratio", std::vector<double>{1.0, kNaN, kNaN, 0.6, 0.3}, {kFrames});
  h5.write("/stick/radius_status", std::vector<std::int8_t>{1, 3, 3, 0, 0}, {kFrames});
  h5.write("/stick/tracks_reach_ratio", std::vector<double>{0.9, 0.89, 0.88, 0.88, 0.87}, {kFrames});
}

// Maps: frame f holds E_xx = f + 0.01 on the 3 × 3 cells with |x|, |y| ≤ 0.5, NaN elsewhere.
void write_maps(H5Writer& h5) {
  std::vector<double> total(kFrames * kCells * kCells * 3, kNaN),
      principal(kFrames * kCells * kCells * 2, kNaN);
  for (std::size_t f = 0; f < kFrames; ++f)
    for (std::size_t j = 1; j <= 3; ++j)
      for (std::size_t i = 1; i <= 3; ++i) {
        const std::size_t c = (f * kCells + j) * kCells + i;
        total[c * 3] = static_cast<double>(f) + 0.01;
        total[c * 3 + 1] = -0.02;
        total[c * 3 + 2] = 0.003;
        principal[c * 2] = 0.5;
        principal[c * 2 + 1] = -0.5;
      }
  h5.write("/maps/strain_total", total, {kFrames, kCells, kCells, 3});
  h5.write("/maps/principal", principal, {kFrames, kCells, kCells, 2});
  h5.attribute("/maps", "aspect", 1.0);
}

// At t90 (frame 2): triangle 0 has e1 along −45° (reported as 135°), triangle 1 is not used, triangle 2
// has no direction (e1 = e2). Ridges: two coherent blocks at 30°, one block below the coherence floor.
void write_directions(H5Writer& h5) {
  std::vector<double> principal(kFrames * 3 * 3, 0.0);
  std::vector<std::uint8_t> status(kFrames * 3, 0);
  principal[(2 * 3 + 0) * 3 + 0] = 0.1;
  principal[(2 * 3 + 0) * 3 + 2] = -std::numbers::pi / 4;
  status[2 * 3 + 1] = 1;
  h5.write("/strain/principal", principal, {kFrames, 3, 3});
  h5.write("/mesh/status", status, {kFrames, 3});
  std::vector<float> angle(kFrames * 3, 0.0f), coherence(kFrames * 3, 0.0f);
  angle[0] = angle[1] = static_cast<float>(std::numbers::pi / 6);
  coherence[0] = 0.8f;
  coherence[1] = 0.6f;
  coherence[2] = 0.1f;
  h5.write("/contact/orientation_rad", angle, {kFrames, 1, 3});
  h5.write("/contact/coherence", coherence, {kFrames, 1, 3});
}

fs::path write_result(const std::string& name) {
  const fs::path dir = fresh_dir(name);
  H5Writer h5((dir / "result.h5").string());
  write_frames_and_contact(h5);
  write_tracks(h5);
  write_channels_and_events(h5);
  write_maps(h5);
  write_directions(h5);
  h5.attribute("/", "software_version", "tirstrain test");
  h5.attribute("/", "stages", "contact,tracking,strain,channels");
  h5.commit();
  return dir;
}

TEST(ReportResultData, SeriesAreTheFileContentsInSIUnits) {
  const ResultData r = read_result(write_result("series").string());
  EXPECT_EQ(r.label, "report_series");
  EXPECT_EQ(r.software_version, "tirstrain test");
  ASSERT_EQ(r.semi_major_mm.size(), kFrames);
  EXPECT_DOUBLE_EQ(r.semi_major_mm[0], 3.0);  // 150 px at 50 px/mm
  EXPECT_DOUBLE_EQ(r.semi_minor_mm[0], 2.0);
  EXPECT_TRUE(std::isnan(r.semi_major_mm[1])) << "no ellipse: no value, not 0";
  EXPECT_DOUBLE_EQ(r.area_mm2[0], 30.0);
  EXPECT_TRUE(std::isnan(r.area_mm2[1])) << "no contact: a gap, not a contact of 0 mm²";
  EXPECT_TRUE(r.time_measured);
  EXPECT_EQ(r.tracks_alive, (std::vector<double>{2, 2, 3, 3, 3}));
  EXPECT_EQ(r.tracks_born, (std::vector<double>{2, 0, 1, 1, 0}));
  EXPECT_EQ(r.tracks_retired, (std::vector<double>{0, 0, 0, 1, 0}));
  EXPECT_TRUE(std::isnan(r.normal_N[0])) << "outside the channel's span";
  EXPECT_DOUBLE_EQ(r.tangential_N[3], 1.8);
  EXPECT_TRUE(std::isnan(r.mu[4])) << "not valid: W below the minimum";
  EXPECT_DOUBLE_EQ(r.mu[2], 0.5);
  EXPECT_TRUE(std::isnan(r.energy_ratio[1])) << "external work below 1 % of its largest";
  EXPECT_DOUBLE_EQ(r.energy_ratio[3], 9e-6 / 6e-5);
  EXPECT_DOUBLE_EQ(r.energy_ratio_at_t90, 0.2);
  // c not measured: the tracks' reach stands beside the gap, and only there.
  ASSERT_EQ(r.stick_unmeasured_reach.size(), kFrames);
  EXPECT_TRUE(std::isnan(r.stick_radius_ratio[1]));
  EXPECT_DOUBLE_EQ(r.stick_unmeasured_reach[1], 0.89);
  EXPECT_DOUBLE_EQ(r.stick_unmeasured_reach[2], 0.88);
  for (std::size_t i : {0u, 3u, 4u}) EXPECT_TRUE(std::isnan(r.stick_unmeasured_reach[i])) << i;
}

TEST(ReportResultData, InstantsComeFromTheEventsAndMapsFromTheirFrames) {
  const ResultData r = read_result(write_result("instants").string());
  ASSERT_EQ(r.instants.size(), 3u);
  EXPECT_EQ(r.instants[1].name, "t90");
  EXPECT_EQ(r.instants[1].frame, 2);
  EXPECT_DOUBLE_EQ(r.instants[1].t_s, 0.2);
  ASSERT_EQ(r.maps.size(), 3u);
  const StrainMaps& m = r.maps[2];  // full slip, frame 3
  EXPECT_EQ(m.cells, 5);
  EXPECT_DOUBLE_EQ(m.component[0][2 * 5 + 2], 3.01);  // E_xx at the centre cell
  EXPECT_DOUBLE_EQ(m.component[3][2 * 5 + 2], 0.5);   // e1
  EXPECT_TRUE(std::isnan(m.component[0][0]));
  // 13 of the 5 × 5 cell centres lie in the unit disk; 9 of them are covered.
  EXPECT_NEAR(m.covered_fraction, 9.0 / 13.0, 1e-12);
}

TEST(ReportResultData, DirectionsKeepOnlyUsedTrianglesAndCoherentBlocks) {
  const ResultData r = read_result(write_result("directions").string());
  ASSERT_EQ(r.principal_directions.angle_rad.size(), 1u);
  EXPECT_NEAR(r.principal_directions.angle_rad[0], 3 * std::numbers::pi / 4, 1e-12);
  ASSERT_EQ(r.ridge_orientation.angle_rad.size(), 2u);
  EXPECT_NEAR(r.ridge_orientation.angle_rad[0], std::numbers::pi / 6, 1e-6);
  EXPECT_NEAR(r.ridge_orientation.weight[0] + r.ridge_orientation.weight[1], 1.4, 1e-6);
}

// An HDF5 file of another command (truth.h5, fit.h5) and a CSV that is not validate's are refused by name.
TEST(ReportResultData, OtherFilesAreNotTakenForResultsOrValidations) {
  const fs::path dir = fresh_dir("other_files");
  {
    H5Writer h5((dir / "truth.h5").string());
    h5.write("/load/normal_N", std::vector<double>{1.0, 2.0}, {2});
    h5.commit();
  }
  try {
    (void)read_result((dir / "truth.h5").string());
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("not a result of `tirstrain process`"), std::string::npos)
        << e.what();
  }
  std::ofstream(dir / "validation.csv") << "garbage,1,2\n";
  try {
    (void)read_validation(dir.string());
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("not a validation table"), std::string::npos) << e.what();
  }
}

TEST(ReportResultData, AMissingResultNamesThePath) {
  const fs::path dir = fresh_dir("missing");
  try {
    (void)read_result(dir.string());
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "result.h5").string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tirstrain::report
