// The mesh that follows births and retirements, the normalised-map rasteriser and the strain settings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "core/error.hpp"
#include "core/scene.hpp"
#include "strain/evolving_mesh.hpp"
#include "strain/normalised_map.hpp"
#include "strain/settings.hpp"
#include "tests/support/expect_error.hpp"

namespace tirstrain::strain {
namespace {

std::vector<Vec2> lattice(int nx, int ny, double step) {
  std::vector<Vec2> points;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) points.push_back({i * step + 0.1 * j, j * step + 0.05 * i});
  return points;
}

TEST(EvolvingMesh, KeepsTriangleIdentityAwayFromARetiredVertex) {
  const std::vector<Vec2> points = lattice(6, 6, 10.0);
  std::vector<std::int32_t> alive(points.size());
  for (std::size_t i = 0; i < alive.size(); ++i) alive[i] = static_cast<std::int32_t>(i);
  EvolvingMesh mesh;
  EXPECT_TRUE(mesh.update(alive, points));
  const std::vector<Triangle> first = mesh.active_triangles();
  const std::vector<std::int32_t> first_ids = mesh.active();
  ASSERT_GE(first.size(), 2u * 5u * 5u);
  // Same live set: nothing is rebuilt.
  EXPECT_FALSE(mesh.update(alive, points));
  EXPECT_EQ(mesh.rebuilds(), 1);

  // Retire the vertex in the middle (id 14 = (2, 2)).
  const std::int32_t retired = 14;
  alive.erase(std::find(alive.begin(), alive.end(), retired));
  EXPECT_TRUE(mesh.update(alive, points));
  EXPECT_EQ(mesh.rebuilds(), 2);
  std::set<std::int32_t> now(mesh.active().begin(), mesh.active().end());
  int kept = 0, touching = 0;
  for (std::size_t t = 0; t < first.size(); ++t) {
    const bool touches = std::find(first[t].begin(), first[t].end(), retired) != first[t].end();
    if (touches) {
      ++touching;
      EXPECT_EQ(now.count(first_ids[t]), 0u);  // gone with its vertex
    } else {
      // Delaunay is local: a triangle not touching the removed vertex keeps its identity.
      EXPECT_EQ(now.count(first_ids[t]), 1u) << t;
      ++kept;
    }
  }
  EXPECT_GE(touching, 4);
  EXPECT_EQ(kept + touching, static_cast<int>(first.size()));
  for (const Triangle& t : mesh.active_triangles()) EXPECT_EQ(std::count(t.begin(), t.end(), retired), 0);
  // The union keeps every triangle ever used, with its vertices in track ids.
  EXPECT_EQ(mesh.triangles().size(), first.size() + (mesh.active().size() - static_cast<std::size_t>(kept)));
  for (std::size_t t = 0; t < mesh.active().size(); ++t)
    EXPECT_EQ(mesh.triangles()[static_cast<std::size_t>(mesh.active()[t])], mesh.active_triangles()[t]);
}

TEST(EvolvingMesh, DegenerateLiveSets) {
  const std::vector<Vec2> points = {{0, 0}, {10, 0}, {20, 0}, {5, 5}};
  EvolvingMesh mesh;
  const std::vector<std::int32_t> none;
  mesh.update(none, points);
  EXPECT_TRUE(mesh.active().empty());
  const std::vector<std::int32_t> collinear = {0, 1, 2};
  mesh.update(collinear, points);
  EXPECT_TRUE(mesh.active().empty());
  const std::vector<std::int32_t> three = {0, 1, 3};
  mesh.update(three, points);
  ASSERT_EQ(mesh.active().size(), 1u);
}

TEST(NormalisedMap, RasterisesEachCellToTheTriangleContainingIt) {
  // A square [-0.5, 0.5]^2 in normalised units split along its diagonal; identity normalisation.
  const std::vector<Vec2> points = {{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}};
  const std::vector<Triangle> triangles = {{0, 1, 2}, {0, 2, 3}};
  NormalisedGrid grid;
  grid.cells = 21;  // step 0.1
  grid.to_normalised = cv::Matx23d(1, 0, 0, 0, 1, 0);
  const std::vector<std::uint8_t> usable = {1, 1};
  const std::vector<std::int32_t> owner = rasterise_triangles(grid, triangles, points, usable);
  int covered = 0;
  for (int j = 0; j < 21; ++j)
    for (int i = 0; i < 21; ++i) {
      const double x = grid.coordinate(i), y = grid.coordinate(j);
      const std::int32_t o = owner[static_cast<std::size_t>(j * 21 + i)];
      const bool inside = std::abs(x) <= 0.5 + 1e-9 && std::abs(y) <= 0.5 + 1e-9;
      ASSERT_EQ(o >= 0, inside) << x << ", " << y;
      if (!inside) continue;
      ++covered;
      // Strictly below the diagonal y = x (in the first triangle's half) belongs to triangle 0.
      if (y < x - 1e-9) {
        EXPECT_EQ(o, 0);
      }
      if (y > x + 1e-9) {
        EXPECT_EQ(o, 1);
      }
    }
  EXPECT_EQ(covered, 11 * 11);
  // An unusable triangle leaves its cells empty.
  const std::vector<std::uint8_t> only_second = {0, 1};
  const std::vector<std::int32_t> half = rasterise_triangles(grid, triangles, points, only_second);
  EXPECT_EQ(std::count(half.begin(), half.end(), 0), 0);
  EXPECT_EQ(std::count(half.begin(), half.end(), 1), 11 * 12 / 2);
}

TEST(NormalisedMap, NanMeanIgnoresMissingCells) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const cv::Mat a = (cv::Mat_<double>(1, 3) << 1.0, nan, nan);
  const cv::Mat b = (cv::Mat_<double>(1, 3) << 3.0, 5.0, nan);
  const std::vector<cv::Mat> maps = {a, b};
  cv::Mat count;
  const cv::Mat mean = nan_mean(maps, &count);
  EXPECT_DOUBLE_EQ(mean.at<double>(0, 0), 2.0);
  EXPECT_DOUBLE_EQ(mean.at<double>(0, 1), 5.0);
  EXPECT_TRUE(std::isnan(mean.at<double>(0, 2)));
  EXPECT_DOUBLE_EQ(count.at<double>(0, 1), 1.0);
}

TEST(StrainOptions, ParsedStrictlyFromTheScene) {
  Scene scene;
  scene.file = "scene.yaml";
  scene.tissue.young_Pa = 2e6;
  scene.strain =
      SceneSection::parse("{mode: incremental, stick_tolerance_px: 0.3, overlay: exx, map_cells: 33}");
  const StrainStageOptions s = parse_strain_options(scene);
  EXPECT_EQ(s.mode, StrainMode::kIncremental);
  EXPECT_DOUBLE_EQ(s.strain.stick_tolerance_px, 0.3);
  EXPECT_DOUBLE_EQ(s.strain.young_Pa, 2e6);
  EXPECT_EQ(s.map_cells, 33);
  EXPECT_EQ(parse_strain_options(scene, "exact").mode, StrainMode::kExact);

  scene.strain = SceneSection::parse("{mode: exact, stick_tolerence_px: 0.3}");
  try {
    parse_strain_options(scene);
    FAIL() << "a misspelt key must be an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("strain.stick_tolerence_px"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("scene.yaml"), std::string::npos) << e.what();
  }
  scene.strain = SceneSection::parse("{mode: sum}");
  EXPECT_THROW(parse_strain_options(scene), Error);
}

// Options built in code are checked too; the error names the scene key.
TEST(StrainOptions, CheckNamesTheKeyOfAValueOutOfRange) {
  EXPECT_NO_THROW(StrainStageOptions{}.check());
  const auto key_of = [](const StrainStageOptions& o) {
    return testing::expect_error([&] { o.check(); }).context().key;
  };
  StrainStageOptions o;
  o.strain.quality.min_angle_deg = 70.0;
  EXPECT_EQ(key_of(o), "strain.min_angle_deg");
  o = {};
  o.stick_zone.extent = 1.5;
  EXPECT_EQ(key_of(o), "strain.stick_fit_extent");
  o = {};
  o.strain.poisson = 0.5;
  EXPECT_EQ(key_of(o), "tissue.nu");
  o = {};
  o.map_cells = 2;
  EXPECT_EQ(key_of(o), "strain.map_cells");
}

}  // namespace
}  // namespace tirstrain::strain
