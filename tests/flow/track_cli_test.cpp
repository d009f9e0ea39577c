// `tirstrain track` on an image pair with a known sub-pixel shift of a speckle pattern (not a fingerprint:
// the command tracks any texture).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>

#include "core/csv.hpp"

namespace {

// Gaussian speckles (σ = 2 px) evaluated exactly at the shifted position, 16 bit.
cv::Mat speckle(int size, double shift_x, double shift_y) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-10.0, size + 10.0), amp(0.3, 1.0);
  std::vector<cv::Vec3d> dots(static_cast<std::size_t>(size * size / 40));
  for (auto& d : dots) d = {pos(rng), pos(rng), amp(rng)};
  cv::Mat img(size, size, CV_64F, cv::Scalar(0.1));
  for (const auto& d : dots)
    for (int y = std::max(0, int(d[1] + shift_y) - 8); y < std::min(size, int(d[1] + shift_y) + 9); ++y)
      for (int x = std::max(0, int(d[0] + shift_x) - 8); x < std::min(size, int(d[0] + shift_x) + 9); ++x) {
        const double dx = x - d[0] - shift_x, dy = y - d[1] - shift_y;
        img.at<double>(y, x) += 0.5 * d[2] * std::exp(-(dx * dx + dy * dy) / 8.0);
      }
  cv::Mat out;
  img.convertTo(out, CV_16U, 65535.0 / 1.6);
  return out;
}

int run(const std::string& args) {
  const int status = std::system((std::string(TIRSTRAIN_CLI) + " " + args).c_str());
  // (args may carry their own redirections)
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(TrackCli, SubPixelShiftOfSpeckle) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "speckle";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  const double sx = 2.37, sy = -1.62;
  cv::imwrite((dir / "frames" / "000000.png").string(), speckle(128, 0.0, 0.0));
  cv::imwrite((dir / "frames" / "000001.png").string(), speckle(128, sx, sy));
  const std::string out = (dir / "tracks.csv").string();
  ASSERT_EQ(run("track " + (dir / "frames").string() + " --grid 16 --out " + out + " --quiet"), 0);
  const tirstrain::CsvTable t = tirstrain::read_numeric_csv(out);
  const auto& frame = t.column("frame");
  double worst = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < t.rows(); ++i) {
    if (frame[i] != 1) continue;
    EXPECT_EQ(t.column("status")[i], 0);
    const double ex = t.column("x_px")[i] - t.column("X_px")[i] - sx;
    const double ey = t.column("y_px")[i] - t.column("Y_px")[i] - sy;
    worst = std::max(worst, std::hypot(ex, ey));
    ++n;
  }
  EXPECT_GE(n, 25);
  EXPECT_LT(worst, 0.02);  // measured: see the test log
  std::printf("speckle: %d points, worst error %.4f px\n", n, worst);

  // Two frames: no rest test runs (the texture is noise-free), no model stands in for a match beyond the
  // fusion, the local fit (each with the window it was fitted over) and the frame's affine fit of the
  // shift, and the JSON beside the CSV says the texture has no ridges, which settings ran and what the
  // affine test found.
  long on_affine_fit = 0;
  for (std::size_t i = 0; i < t.rows(); ++i) {
    const double model = t.column("model")[i];
    EXPECT_TRUE(model == 0.0 || model == 1.0 || model == 4.0 || model == 5.0) << model;
    on_affine_fit += model == 5.0 ? 1 : 0;
    const double wx = t.column("model_window_x_px")[i], wy = t.column("model_window_y_px")[i];
    if (model == 4.0) {
      // Each component's window: the own match's (0) or at least the smallest, one of them a window.
      EXPECT_TRUE(wx == 0.0 || wx >= 10.0) << wx;
      EXPECT_TRUE(wy == 0.0 || wy >= 10.0) << wy;
      EXPECT_GE(std::max(wx, wy), 10.0);
    } else {
      EXPECT_EQ(wx, 0.0);
      EXPECT_EQ(wy, 0.0);
    }
  }
  std::ifstream json_file(dir / "tracks.json");
  ASSERT_TRUE(json_file.good());
  const nlohmann::json j = nlohmann::json::parse(json_file);
  EXPECT_FALSE(j["texture"]["ridges"].get<bool>());
  EXPECT_LT(j["texture"]["coherence"].get<double>(), 0.35);
  EXPECT_EQ(j["settings"]["subset_stride"].get<int>(), 1);
  EXPECT_EQ(j["unmeasured_direction_track_frames"].get<int>(), 0);  // a speckle determines both directions
  EXPECT_EQ(j["settings"]["preset"].get<std::string>(), "auto");
  EXPECT_EQ(j["per_frame"].size(), 2u);
  EXPECT_FALSE(j["per_frame"][1]["at_rest"].get<bool>());
  EXPECT_TRUE(j["per_frame"][1]["affine_fit"].get<bool>());
  EXPECT_LE(j["per_frame"][1]["affine_chi2_per_dof"].get<double>(), 1.5);
  EXPECT_LE(j["per_frame"][1]["affine_hidden_px"].get<double>(), 0.03);
  EXPECT_EQ(j["per_frame"][1]["on_affine_fit"].get<long>(), on_affine_fit);
  EXPECT_GE(on_affine_fit, n / 2);
  const auto& by_model = j["track_frames_by_model"];
  EXPECT_EQ(by_model["rest_fit"].get<long>(), 0);
  EXPECT_EQ(by_model["affine_fit"].get<long>(), on_affine_fit);
  long alive_rows = 0;
  for (std::size_t i = 0; i < t.rows(); ++i) alive_rows += t.column("status")[i] < 10 ? 1 : 0;
  EXPECT_EQ(by_model["own_match"].get<long>() + by_model["fused"].get<long>() +
                by_model["local_fit"].get<long>() + by_model["affine_fit"].get<long>(),
            alive_rows);

  // Tracks written into the frames' folder would change the input: refused, and the folder stays as it was.
  EXPECT_EQ(run("track " + (dir / "frames").string() + " --grid 16 --out " +
                (dir / "frames" / "t.csv").string() + " --quiet 2>/dev/null"),
            2);  // the command line's --out is wrong
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir / "frames")) ++files;
  EXPECT_EQ(files, 2u);
}

// A corrupt frame (here the first and the third file) is skipped: the CSV's frame column is the input's
// frame index, so the frames after it keep their numbers, and the JSON lists the skipped ones.
TEST(TrackCli, SkippedFramesKeepTheInputsFrameNumbers) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "skipped";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  for (int k = 0; k < 5; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", k);
    if (k == 0 || k == 2)
      std::ofstream(dir / "frames" / name) << "not a PNG";
    else
      cv::imwrite((dir / "frames" / name).string(), speckle(96, 0.3 * k, 0.0));
  }
  const std::string out = (dir / "tracks.csv").string();
  ASSERT_EQ(run("track " + (dir / "frames").string() + " --grid 16 --out " + out + " --quiet"), 0);
  const tirstrain::CsvTable t = tirstrain::read_numeric_csv(out);
  std::vector<double> frames;
  for (const double f : t.column("frame"))
    if (frames.empty() || frames.back() != f) frames.push_back(f);
  EXPECT_EQ(frames, (std::vector<double>{1, 3, 4}));
  // Frame 4 is 0.9 px from frame 1, the tracks' reference.
  for (std::size_t i = 0; i < t.rows(); ++i)
    if (t.column("frame")[i] == 4) {
      EXPECT_NEAR(t.column("x_px")[i] - t.column("X_px")[i], 0.9, 0.02);
    }
  std::ifstream json(dir / "tracks.json");
  const nlohmann::json report = nlohmann::json::parse(json);
  EXPECT_EQ(report["frames"], 3);
  EXPECT_EQ(report["frames_skipped"], (std::vector<int>{0, 2}));
}

TEST(TrackCli, TenBitCodesInSixteenBitFilesTrackAsWell) {
  // A 10-bit camera's frames stored as 16-bit PNGs: codes up to 1023. Full scale is decided the way contact/
  // decides it (1023 here), so the tracker sees the same texture as from a full-range file and finds the
  // same shift.
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "speckle_10bit";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  const double sx = 2.37, sy = -1.62;
  for (int f = 0; f < 2; ++f) {
    cv::Mat ten_bit;
    speckle(128, f * sx, f * sy).convertTo(ten_bit, CV_16U, 1023.0 / 65535.0);
    cv::imwrite((dir / "frames" / ("00000" + std::to_string(f) + ".png")).string(), ten_bit);
  }
  const std::string out = (dir / "tracks.csv").string();
  ASSERT_EQ(run("track " + (dir / "frames").string() + " --grid 16 --out " + out + " --quiet"), 0);
  const tirstrain::CsvTable t = tirstrain::read_numeric_csv(out);
  double worst = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < t.rows(); ++i) {
    if (t.column("frame")[i] != 1 || t.column("status")[i] != 0) continue;
    worst = std::max(worst, std::hypot(t.column("x_px")[i] - t.column("X_px")[i] - sx,
                                       t.column("y_px")[i] - t.column("Y_px")[i] - sy));
    ++n;
  }
  EXPECT_GE(n, 25);
  EXPECT_LT(worst, 0.03);  // 10-bit quantisation costs a little against the 16-bit frames' 0.02 px
}

TEST(TrackCli, RequiresPointsOrGrid) {
  EXPECT_NE(run("track nowhere --out /dev/null 2>/dev/null"), 0);
}

// An error in the points file names the points file, not the frames.
TEST(TrackCli, APointsFileErrorNamesThePointsFile) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "points_error";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  for (int k = 0; k < 2; ++k)
    cv::imwrite((dir / "frames" / ("00000" + std::to_string(k) + ".png")).string(),
                speckle(96, 0.3 * k, 0.0));
  const std::string missing = (dir / "missing_points.csv").string();
  const std::string log = (dir / "log.txt").string();
  EXPECT_EQ(run("track " + (dir / "frames").string() + " --points " + missing + " --out " +
                (dir / "t.csv").string() + " 2>" + log),
            1);
  std::ifstream in(log);
  const std::string output((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(output.find(missing), std::string::npos) << output;
  EXPECT_EQ(output.find("frames:"), std::string::npos) << output;
}

// Points too near the frame's edge for a subset are not tracked, and the run says so (their status alone,
// "poor match", does not say why); a point inside is tracked.
TEST(TrackCli, PointsTooNearTheEdgeAreSaidNotTracked) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "points_edge";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  for (int k = 0; k < 2; ++k)
    cv::imwrite((dir / "frames" / ("00000" + std::to_string(k) + ".png")).string(),
                speckle(96, 0.3 * k, 0.0));
  std::ofstream(dir / "points.csv") << "x_px,y_px\n48,48\n2,2\n";
  const std::string log = (dir / "log.txt").string(), out = (dir / "t.csv").string();
  ASSERT_EQ(run("track " + (dir / "frames").string() + " --points " + (dir / "points.csv").string() +
                " --out " + out + " --quiet 2>" + log),
            0);
  std::ifstream in(log);
  const std::string output((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(output.find("warning: 1 of the given points lie within"), std::string::npos) << output;
  const tirstrain::CsvTable t = tirstrain::read_numeric_csv(out);
  int alive_at_1 = 0;
  for (std::size_t i = 0; i < t.rows(); ++i)
    if (t.column("frame")[i] == 1 && t.column("status")[i] < 10) {
      ++alive_at_1;
      EXPECT_NEAR(t.column("x_px")[i] - t.column("X_px")[i], 0.3, 0.02);
    }
  EXPECT_EQ(alive_at_1, 1);
}

// Straight parallel ridges carry no information along them: the track positions there are not measured,
// and the run says so (the count in the JSON), where a speckle's are all measured.
TEST(TrackCli, StraightRidgesSayTheDirectionAlongThemIsNotMeasured) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / "flow" / "straight_ridges";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  const double c = std::cos(std::numbers::pi / 6), s = std::sin(std::numbers::pi / 6);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 300.0);  // 0.5 % of full scale
  for (int k = 0; k < 3; ++k) {
    cv::Mat img(96, 96, CV_16U);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const double across = (x - 0.6 * k) * c + (y - 0.3 * k) * s;
        img.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(
            20000 + 15000 * std::cos(2 * std::numbers::pi * across / 16.0) + noise(rng));
      }
    cv::imwrite((dir / "frames" / ("00000" + std::to_string(k) + ".png")).string(), img);
  }
  const std::string log = (dir / "log.txt").string(), out = (dir / "t.csv").string();
  ASSERT_EQ(run("track " + (dir / "frames").string() + " --grid 16 --out " + out + " --quiet 2>" + log), 0);
  std::ifstream in(log);
  const std::string output((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(output.find("have a direction the texture does not determine"), std::string::npos) << output;
  std::ifstream json_file((dir / "t.json").string());
  const nlohmann::json report = nlohmann::json::parse(json_file);
  EXPECT_GT(report["unmeasured_direction_track_frames"].get<int>(), 0);
}

}  // namespace
