// Strain stage cost per frame next to its error: N tracks on a jittered lattice in a circle (1000, 3000,
// 10000), moved by a smooth analytic field with a known gradient (a quadratic displacement u(X) reaching
// 10–20 % strain), then per frame: Delaunay re-triangulation (the worst case: the live set changed), the
// per-triangle kinematics (F, exact Green–Lagrange, principal, rotations, increments, energy, stick labels)
// and the map rasterisation. Error: RMS of E (all three components) against the exact strain at each
// triangle's reference centroid — the discretisation error of constant-strain triangles at that spacing, with
// exact positions (tracking error is measured by `tirstrain bench`).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "core/tensor2.hpp"
#include "strain/deformation.hpp"
#include "strain/evolving_mesh.hpp"
#include "strain/normalised_map.hpp"

namespace {

using namespace tirstrain;

constexpr double kRadiusPx = 400.0;

// u = A X + B (X ⊗ X)/R: a gradient varying across the contact by about its own size.
Vec2 displacement(const Vec2& X) {
  const double x = X.x / kRadiusPx, y = X.y / kRadiusPx;
  return {kRadiusPx * (0.10 * x + 0.04 * y + 0.05 * x * x - 0.03 * x * y),
          kRadiusPx * (-0.02 * x - 0.06 * y + 0.04 * y * y + 0.02 * x * y)};
}
Gradient2 gradient(const Vec2& X) {
  const double x = X.x / kRadiusPx, y = X.y / kRadiusPx;
  return {0.10 + 0.10 * x - 0.03 * y, 0.04 - 0.03 * x, -0.02 + 0.02 * y, -0.06 + 0.08 * y + 0.02 * x};
}

struct Scene {
  std::vector<Vec2> reference, current, previous;
  std::vector<std::int32_t> alive;
};

Scene make_scene(int tracks) {
  // Lattice spacing giving `tracks` points in the circle, jittered by 15 % of the spacing.
  const double spacing = std::sqrt(3.14159265358979 * kRadiusPx * kRadiusPx / tracks);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jitter(-0.15 * spacing, 0.15 * spacing);
  Scene s;
  for (double y = -kRadiusPx; y <= kRadiusPx; y += spacing)
    for (double x = -kRadiusPx; x <= kRadiusPx; x += spacing) {
      const Vec2 X{x + jitter(rng), y + jitter(rng)};
      if (X.x * X.x + X.y * X.y > kRadiusPx * kRadiusPx) continue;
      const Vec2 u = displacement(X);
      s.reference.push_back(X);
      s.current.push_back({X.x + u.x, X.y + u.y});
      s.previous.push_back({X.x + 0.95 * u.x, X.y + 0.95 * u.y});
      s.alive.push_back(static_cast<std::int32_t>(s.alive.size()));
    }
  return s;
}

void BM_StrainFrame(benchmark::State& state) {
  const Scene s = make_scene(static_cast<int>(state.range(0)));
  const strain::StrainOptions settings;
  strain::NormalisedGrid grid;
  grid.cells = 65;
  grid.to_normalised = cv::Matx23d(1.0 / kRadiusPx, 0, 0, 0, 1.0 / kRadiusPx, 0);
  strain::FrameStrain result;
  std::size_t triangles = 0;
  for (auto _ : state) {
    // A fresh mesh each frame: the cost when births or retirements changed the live set.
    strain::EvolvingMesh mesh;
    mesh.update(s.alive, s.reference);
    strain::FrameInput input;
    input.triangles = mesh.active_triangles();
    input.reference_px = s.reference;
    input.current_px = s.current;
    input.previous_px = s.previous;
    input.dt_s = 0.01;
    input.plate_known = true;
    result = strain::compute_frame_strain(input, settings);
    std::vector<std::uint8_t> usable(result.status.size());
    for (std::size_t t = 0; t < usable.size(); ++t)
      usable[t] = result.status[t] == strain::TriangleStatus::kValid ? 1 : 0;
    const auto owner = strain::rasterise_triangles(grid, mesh.active_triangles(), s.reference, usable);
    benchmark::DoNotOptimize(owner.data());
    triangles = mesh.active_triangles().size();
    // Error against the exact strain at each triangle's reference centroid.
    if (state.iterations() == 0) {
      double sum2 = 0.0;
      long n = 0;
      for (std::size_t t = 0; t < triangles; ++t) {
        if (result.status[t] != strain::TriangleStatus::kValid) continue;
        const auto& tri = mesh.active_triangles()[t];
        const Vec2 c{(s.reference[static_cast<std::size_t>(tri[0])].x +
                      s.reference[static_cast<std::size_t>(tri[1])].x +
                      s.reference[static_cast<std::size_t>(tri[2])].x) /
                         3.0,
                     (s.reference[static_cast<std::size_t>(tri[0])].y +
                      s.reference[static_cast<std::size_t>(tri[1])].y +
                      s.reference[static_cast<std::size_t>(tri[2])].y) /
                         3.0};
        const Strain2 truth = green_lagrange(gradient(c));
        const Strain2& e = result.total[t];
        sum2 += (e.xx - truth.xx) * (e.xx - truth.xx) + (e.yy - truth.yy) * (e.yy - truth.yy) +
                (e.xy - truth.xy) * (e.xy - truth.xy);
        n += 3;
      }
      state.counters["strain_rms"] = std::sqrt(sum2 / static_cast<double>(n));
    }
  }
  state.counters["tracks"] = static_cast<double>(s.reference.size());
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["excluded"] = static_cast<double>(result.counts.excluded());
  state.counters["frames_per_s"] = benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_StrainFrame)->Arg(1000)->Arg(3000)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
