// Throughput of the analytic Cattaneo–Mindlin field: evaluate() (displacement, gradient, Green–Lagrange
// strain, principal strains, energy density) per second, for points in the stick zone, the slip annulus,
// outside the contact, and a mix of the three. Points are precomputed so only the model is timed.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "model/cattaneo_mindlin.hpp"

namespace {

using tirstrain::model::CattaneoMindlin;
using tirstrain::model::CattaneoMindlinParams;

CattaneoMindlin make_model(bool radial) {
  CattaneoMindlinParams p;
  p.normal_N = 1.0;
  p.tangential_N = 0.5;  // c ≈ 0.79a
  p.radius_m = 0.01;
  p.young_Pa = 1.0e6;
  p.poisson = 0.4;
  p.friction = 1.0;
  p.direction_rad = 0.3;  // the general (rotated) path
  p.hertz_radial = radial;
  return CattaneoMindlin(p);
}

enum Region : int { kStick = 0, kSlip = 1, kOutside = 2, kMixed = 3 };

// 4096 points uniformly in area within the region's radial band (outside: a < r < 3a), at fixed seed.
std::vector<double> make_points(const CattaneoMindlin& m, int region) {
  const double a = m.hertz().contact_radius_m;
  const double c = m.stick_radius_m();
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> xy;
  constexpr int kPoints = 4096;
  xy.reserve(2 * kPoints);
  for (int i = 0; i < kPoints; ++i) {
    const int band = region == kMixed ? i % 3 : region;
    const double lo = band == kStick ? 0.0 : band == kSlip ? c : a;
    const double hi = band == kStick ? c : band == kSlip ? a : 3.0 * a;
    const double r = std::sqrt(lo * lo + unit(rng) * (hi * hi - lo * lo));
    const double ang = 2.0 * std::numbers::pi * unit(rng);
    xy.push_back(r * std::cos(ang));
    xy.push_back(r * std::sin(ang));
  }
  return xy;
}

void BM_Evaluate(benchmark::State& state) {
  const CattaneoMindlin m = make_model(state.range(1) != 0);
  const std::vector<double> xy = make_points(m, static_cast<int>(state.range(0)));
  const std::size_t n = xy.size() / 2;
  for (auto _ : state) {
    double sink = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto s = m.evaluate(xy[2 * i], xy[2 * i + 1]);
      sink += s.energy_density_J_m3 + s.principal.e1 + s.displacement_m.x;
    }
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(n));
  static const char* const names[] = {"stick", "slip annulus", "outside (a..3a)", "mixed"};
  state.SetLabel(std::string(names[state.range(0)]) + (state.range(1) != 0 ? " +radial" : ""));
}
BENCHMARK(BM_Evaluate)->ArgsProduct({{kStick, kSlip, kOutside, kMixed}, {0, 1}});

void BM_Displacement(benchmark::State& state) {
  const CattaneoMindlin m = make_model(false);
  const std::vector<double> xy = make_points(m, kMixed);
  const std::size_t n = xy.size() / 2;
  for (auto _ : state) {
    double sink = 0.0;
    for (std::size_t i = 0; i < n; ++i) sink += m.displacement_m(xy[2 * i], xy[2 * i + 1]).x;
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(n));
  state.SetLabel("mixed, displacement only");
}
BENCHMARK(BM_Displacement);

}  // namespace

BENCHMARK_MAIN();
