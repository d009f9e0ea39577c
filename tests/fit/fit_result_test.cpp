// fit.csv / fit.h5 from a small result.h5 written here (no images): three frames — no contact, rest, partial
// slip from model/ — round-trip through read_result_for_fit, fit_result and write_fit_outputs; an --out that
// holds the result is refused and the result left as it was.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "fit/fit_result.hpp"
#include "model/cattaneo_mindlin.hpp"

namespace tirstrain::fit {
namespace {

namespace fs = std::filesystem;

constexpr double kPxPerMm = 52.0;

struct Written {
  double q_N = 0.0, limit_N = 0.0;
};

// Frame 0 without contact, frame 1 at rest, frame 2 sheared to Q = μP/2 towards 45°.
Written write_result(const std::string& dir) {
  fs::create_directories(dir);
  model::CattaneoMindlinParams p;
  p.normal_N = 2.0;
  p.tangential_N = 1.0;
  p.direction_rad = std::numbers::pi / 4.0;
  const model::CattaneoMindlin cm(p);
  const double a_px = cm.hertz().contact_radius_m * kPxPerMm * 1e3;
  const double cx = 320.0, cy = 256.0;
  std::vector<double> ref, pos0, pos1, pos2;
  for (double y = -a_px; y <= a_px; y += 18.0)
    for (double x = -a_px; x <= a_px; x += 18.0) {
      if (x * x + y * y > 0.95 * a_px * a_px) continue;
      const Vec2 u = cm.displacement_m(x / (kPxPerMm * 1e3), y / (kPxPerMm * 1e3));
      ref.insert(ref.end(), {cx + x, cy + y});
      pos0.insert(pos0.end(), {NAN, NAN});
      pos1.insert(pos1.end(), {cx + x, cy + y});
      pos2.insert(pos2.end(), {cx + x + u.x * kPxPerMm * 1e3, cy + y + u.y * kPxPerMm * 1e3});
    }
  const std::size_t k = ref.size() / 2;
  std::vector<double> pos = pos0;
  pos.insert(pos.end(), pos1.begin(), pos1.end());
  pos.insert(pos.end(), pos2.begin(), pos2.end());
  H5Writer h5(dir + "/result.h5");
  h5.write("/frames/t_s", std::vector<double>{0.0, 0.01, 0.02}, {3});
  const std::vector<double> ellipse = {0, 0, 0, 0, 0, cx, cy, a_px, a_px, 0.0, cx, cy, a_px, a_px, 0.0};
  h5.write("/contact/ellipse", ellipse, {3, 5});
  h5.write("/tracks/reference_px", ref, {k, 2});
  h5.write("/tracks/position_px", pos, {3, k, 2});
  // A force channel that starts after frame 0.
  h5.write("/channels/at_frames/tangential_force_N", std::vector<double>{0.0, 0.01, 0.98}, {3});
  h5.write("/channels/at_frames/normal_force_N", std::vector<double>{0.0, 2.0, 2.0}, {3});
  h5.write("/channels/at_frames/in_span", std::vector<std::uint8_t>{0, 1, 1}, {3});
  Scene scene;
  scene.px_per_mm = kPxPerMm;
  h5.attribute("/", "scene_yaml", scene_to_yaml(scene));
  h5.commit();
  return {1.0, 2.0};
}

std::vector<std::string> lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

TEST(FitResult, WritesCsvAndH5) {
  const std::string base = std::string(TIRSTRAIN_TEST_TMP) + "/fit_result_test";
  fs::remove_all(base);
  const Written truth = write_result(base + "/result");
  const ResultForFit r = read_result_for_fit(base + "/result");
  ASSERT_EQ(r.frames(), 3u);
  const FitRun fits = fit_result(r, RunOptions{});
  EXPECT_FALSE(fits.trial_limit.has_value());  // one loaded frame cannot measure the trial's μP
  write_fit_outputs(base + "/fit", r, fits, FitOptions{});

  const std::vector<std::string> csv = lines(base + "/fit/fit.csv");
  ASSERT_EQ(csv.size(), 4u);
  EXPECT_EQ(csv[0].rfind("frame,t_s,status,model,tracks,centre_x_px,centre_x_px_sd,", 0), 0u);
  EXPECT_EQ(csv[1].rfind("0,0,no_contact,,", 0), 0u) << csv[1];
  EXPECT_NE(csv[2].find(",ok,rest,"), std::string::npos) << csv[2];
  EXPECT_NE(csv[3].find(",ok,partial_slip,"), std::string::npos) << csv[3];

  const H5Reader h5(base + "/fit/fit.h5");
  const std::vector<std::int64_t> model = h5.read_integers("/fit/model");
  EXPECT_EQ(model, (std::vector<std::int64_t>{-1, 0, 2}));
  EXPECT_EQ(h5.read_integers("/fit/limit_from_trial"), (std::vector<std::int64_t>{0, 0, 0}));
  EXPECT_GT(h5.read_doubles("/fit/tracked_radius")[2], 0.8);           // tracks out to the contact's border
  EXPECT_TRUE(std::isnan(h5.read_doubles("/fit/tracked_radius")[1]));  // rest
  const std::vector<double> q = h5.read_doubles("/fit/tangential_N");
  EXPECT_NEAR(q[2], truth.q_N, 0.02 * truth.limit_N);
  EXPECT_NEAR(h5.read_doubles("/fit/direction_deg")[2], 45.0, 0.5);
  const std::vector<double> channel = h5.read_doubles("/fit/tangential_channel_N");
  EXPECT_TRUE(std::isnan(channel[0]));  // outside the channel's span
  EXPECT_EQ(channel[2], 0.98);
  // μ from the fitted μP and the measured normal load (the model's μ is 1).
  EXPECT_NEAR(h5.read_doubles("/fit/friction")[2], 1.0, 0.05);
  EXPECT_TRUE(std::isnan(h5.read_doubles("/fit/friction")[1]));  // rest: no μP
  H5Shape shape;
  h5.read_doubles("/fit/residual_px", &shape);
  EXPECT_EQ(shape, (H5Shape{3, r.tracks(), 2}));
  EXPECT_FALSE(fs::exists(base + "/fit.partial"));
  // Onset and t90 are frame 2; no full-slip frame, so no picture of one.
  EXPECT_GT(fs::file_size(base + "/fit/residual_onset.png"), 1000u);
  EXPECT_GT(fs::file_size(base + "/fit/c_q_vs_time.png"), 1000u);
  EXPECT_FALSE(fs::exists(base + "/fit/residual_full_slip.png"));
}

TEST(FitResult, RefusesAnOutputHoldingTheResult) {
  const std::string base = std::string(TIRSTRAIN_TEST_TMP) + "/fit_result_refuse";
  fs::remove_all(base);
  write_result(base + "/result");
  const auto before = fs::file_size(base + "/result/result.h5");
  const ResultForFit r = read_result_for_fit(base + "/result");
  const FitRun none{std::vector<FrameFit>(r.frames()), std::nullopt};
  EXPECT_THROW(write_fit_outputs(base + "/result", r, none, FitOptions{}), Error);
  EXPECT_THROW(write_fit_outputs(base, r, none, FitOptions{}), Error);
  try {  // inside the result folder, the next `process` there would refuse it
    write_fit_outputs(base + "/result/fit", r, none, FitOptions{});
    ADD_FAILURE() << "a fit inside the result folder was written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lies inside the result folder"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(base + "/result/fit"));
  EXPECT_EQ(fs::file_size(base + "/result/result.h5"), before);
  EXPECT_THROW(read_result_for_fit(base + "/nothing"), Error);
}

}  // namespace
}  // namespace tirstrain::fit
