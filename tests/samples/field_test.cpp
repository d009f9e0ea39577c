// The applied fields: per-pixel inversion, truth against the analytic model, and the load history.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "model/cattaneo_mindlin.hpp"
#include "samples/trial.hpp"
#include "test_support.hpp"

namespace tirstrain::samples {
namespace {

using testing::clean_scene;
using testing::config_of;

// Largest |X + u(X) - x| over every pixel of a frame, recomputed here with the field's forward map.
double forward_error_px(const Trial& trial, int frame) {
  double reported = 0.0;
  const cv::Mat map = trial.inverse_map(frame, &reported);
  const FrameField field = trial.field(frame);
  double worst = 0.0;
  for (int y = 0; y < map.rows; ++y) {
    for (int x = 0; x < map.cols; ++x) {
      const cv::Vec2d X = map.at<cv::Vec2d>(y, x);
      const Vec2 u = field.displacement_px({X[0], X[1]});
      worst = std::max(worst, std::hypot(X[0] + u.x - x, X[1] + u.y - y));
    }
  }
  EXPECT_LE(reported, 1e-6);
  return worst;
}

TEST(SamplesField, ForwardMapOfInvertedCoordinatesReproducesEveryPixel) {
  // Cattaneo–Mindlin in partial slip (frame 1) and full slip (frame 2), a 50 % uniaxial stretch, a pure
  // shear, and a rigid rotation + translation: every pixel to 1e-6 px.
  YAML::Node cm = clean_scene(192, 192, 3, 20.0);
  YAML::Node stretch = clean_scene(160, 128, 2, 10.0);
  stretch["synthesis"]["loading"] =
      YAML::Load("{field: affine, gradient: [0.5, 0, 0, 0], translation_px: [2.5, -1.25]}");
  YAML::Node shear = clean_scene(160, 128, 2, 10.0);
  shear["synthesis"]["loading"] = YAML::Load("{field: affine, gradient: [0, 0.2, 0.2, 0]}");
  YAML::Node rigid = clean_scene(160, 128, 2, 10.0);
  rigid["synthesis"]["loading"] = YAML::Load("{field: rigid, rotation_deg: 12, translation_px: [9.3, -4.1]}");
  const std::pair<const char*, YAML::Node> scenes[] = {
      {"cattaneo_mindlin", cm}, {"stretch", stretch}, {"shear", shear}, {"rigid", rigid}};
  for (const auto& [name, scene] : scenes) {
    const Trial trial(config_of(scene));
    for (int frame = 1; frame < trial.frames(); ++frame) {
      const double error = forward_error_px(trial, frame);
      std::printf("[ measured ] %s frame %d: max forward-map error %.3g px\n", name, frame, error);
      EXPECT_LE(error, 1e-6) << name << " frame " << frame;
    }
  }
}

TEST(SamplesField, CattaneoMindlinFramesSpanPartialAndFullSlip) {
  const Trial trial(config_of(clean_scene(192, 192, 3, 20.0)));
  EXPECT_FALSE(trial.load(1).full_slip);
  EXPECT_GT(trial.load(1).tangential_N, 0.1);
  EXPECT_TRUE(trial.load(2).full_slip);
}

// The contact is centred in what a pattern band along one edge leaves free, on every edge; a band that does
// not span the image (not along an edge) leaves the image centre.
TEST(SamplesField, ContactCentredBesideTheBandOnEveryEdge) {
  struct Case {
    const char* roi;
    double x, y;
  };
  for (const Case& c : {Case{"[0, 0, 160, 20]", 79.5, 69.5}, Case{"[0, 100, 160, 20]", 79.5, 49.5},
                        Case{"[0, 0, 24, 120]", 91.5, 59.5}, Case{"[136, 0, 24, 120]", 67.5, 59.5},
                        Case{"[40, 0, 60, 20]", 79.5, 59.5}}) {
    YAML::Node root = clean_scene(160, 120, 2, 100.0);
    root["reference_pattern"]["roi_px"] = YAML::Load(c.roi);
    const Trial trial(config_of(root));
    EXPECT_DOUBLE_EQ(trial.history().contact_centre_px().x, c.x) << c.roi;
    EXPECT_DOUBLE_EQ(trial.history().contact_centre_px().y, c.y) << c.roi;
  }
}

TEST(SamplesField, TruthStrainEqualsModelStrainAtTheSameReferencePoints) {
  const SynthConfig cfg = config_of(clean_scene(192, 192, 3, 20.0));
  const Trial trial(cfg);
  const double px_per_m = cfg.scene.px_per_mm * 1000.0;
  const Vec2 centre = trial.history().contact_centre_px();
  double worst_strain = 0.0, worst_displacement_px = 0.0;
  for (int frame = 1; frame < trial.frames(); ++frame) {
    const LoadState load = trial.load(frame);
    model::CattaneoMindlinParams p;
    p.normal_N = 1.0;
    p.tangential_N = load.tangential_N;
    p.radius_m = 0.01;
    p.young_Pa = 1.0e6;
    p.poisson = 0.4;
    p.friction = 1.0;
    p.direction_rad = 1.5 * M_PI;
    const model::CattaneoMindlin model(p);
    const GridTruth truth = trial.grid_truth(frame);
    const auto& gx = trial.grid_x_px();
    const auto& gy = trial.grid_y_px();
    for (std::size_t j = 0; j < gy.size(); ++j) {
      for (std::size_t i = 0; i < gx.size(); ++i) {
        const std::size_t k = j * gx.size() + i;
        const model::FieldSample s =
            model.evaluate((gx[i] - centre.x) / px_per_m, (gy[j] - centre.y) / px_per_m);
        worst_strain = std::max({worst_strain, std::abs(truth.strain[3 * k] - s.strain.xx),
                                 std::abs(truth.strain[3 * k + 1] - s.strain.yy),
                                 std::abs(truth.strain[3 * k + 2] - s.strain.xy)});
        worst_displacement_px = std::max(
            {worst_displacement_px, std::abs(truth.displacement_px[2 * k] - s.displacement_m.x * px_per_m),
             std::abs(truth.displacement_px[2 * k + 1] - s.displacement_m.y * px_per_m)});
      }
    }
  }
  std::printf("[ measured ] truth vs model: strain %.3g, displacement %.3g px\n", worst_strain,
              worst_displacement_px);
  EXPECT_LE(worst_strain, 1e-15);
  EXPECT_LE(worst_displacement_px, 1e-9);
}

TEST(SamplesField, StickZoneMovesWithThePlate) {
  // Displacement-controlled plate: while the contact sticks, the Mindlin rigid shift equals the plate's
  // displacement and every stick-zone point carries exactly that displacement.
  YAML::Node scene = clean_scene(192, 192, 6, 100.0);
  const Trial trial(config_of(scene));
  const double px_per_m = 52000.0;
  int checked = 0;
  for (int frame = 1; frame < trial.frames(); ++frame) {
    const LoadState load = trial.load(frame);
    if (load.full_slip) continue;
    const FrameField field = trial.field(frame);
    ASSERT_NE(field.model(), nullptr);
    const double shift_px = field.model()->rigid_shift_m() * px_per_m;
    EXPECT_NEAR(shift_px, std::hypot(load.plate_px.x, load.plate_px.y), 1e-9);
    const GridTruth truth = trial.grid_truth(frame);
    for (std::size_t k = 0; k < truth.in_stick.size(); ++k) {
      if (!truth.in_stick[k]) continue;
      EXPECT_NEAR(truth.displacement_px[2 * k], load.plate_px.x, 1e-9);
      EXPECT_NEAR(truth.displacement_px[2 * k + 1], load.plate_px.y, 1e-9);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(SamplesField, EllipticalContactTruthIsTheChainRuleOfTheCircularField) {
  YAML::Node scene = clean_scene(192, 160, 2, 20.0);
  scene["synthesis"]["contact"] =
      YAML::Load("{shape: ellipse, normal_N: 1.0, semi_axes_mm: [1.6, 1.1], angle_deg: 30}");
  const Trial trial(config_of(scene));
  const FrameField field = trial.field(1);
  ASSERT_NE(field.model(), nullptr);
  // Central differences of the exact displacement agree with the stored gradient away from r = c and r = a.
  double worst = 0.0;
  const double h = 1e-3;
  for (double x = 40; x < 160; x += 7.3) {
    for (double y = 30; y < 130; y += 6.1) {
      const Vec2 m = field.model_point_m({x, y});
      const double r = std::hypot(m.x, m.y);
      const double a = trial.history().contact_radius_m(), c = field.model()->stick_radius_m();
      if (std::abs(r - a) < 0.05 * a || std::abs(r - c) < 0.05 * a) continue;
      const FieldValue v = field.evaluate({x, y});
      const Vec2 xp = field.displacement_px({x + h, y}), xm = field.displacement_px({x - h, y});
      const Vec2 yp = field.displacement_px({x, y + h}), ym = field.displacement_px({x, y - h});
      worst = std::max({worst, std::abs((xp.x - xm.x) / (2 * h) - v.gradient.xx),
                        std::abs((yp.x - ym.x) / (2 * h) - v.gradient.xy),
                        std::abs((xp.y - xm.y) / (2 * h) - v.gradient.yx),
                        std::abs((yp.y - ym.y) / (2 * h) - v.gradient.yy)});
    }
  }
  EXPECT_LE(worst, 1e-6);
}

}  // namespace
}  // namespace tirstrain::samples
