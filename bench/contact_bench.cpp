// Contact segmentation speed next to its accuracy: ms per frame at 640x512 and 1280x1024, for the reduced
// working resolution chosen automatically (f = floor(ridge period / 5.5 px)) and for full resolution, with
// the mask IoU against the exact truth of the rendered frame reported as a counter of the same run.
// Run: contact_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "tests/contact/tir_render.hpp"

namespace {

using tirstrain::contact::ContactSegmenter;
using tirstrain::contact::SegmenterOptions;

tirstrain::test::TirScene scene_for(int width, int height) {
  tirstrain::test::TirScene scene;
  const double s = width / 640.0;
  scene.size = {width, height};
  scene.contacts = {{0.5 * width + 5.0, 0.5 * height - 3.0, 150.0 * s, 110.0 * s, 0.4}};
  scene.core_x = 0.47 * width;
  scene.core_y = 0.45 * height;
  return scene;
}

void BM_Segment(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0)), height = width * 4 / 5;
  const int downsample = static_cast<int>(state.range(1));
  const tirstrain::test::TirScene scene = scene_for(width, height);
  const cv::Mat image = tirstrain::test::render_tir(scene);
  const cv::Mat truth = tirstrain::test::render_truth_mask(scene);
  SegmenterOptions options;
  options.downsample = downsample;
  options.ridge_period_px = scene.period_px;  // as with a scene file; the spectrum is measured once per trial
  ContactSegmenter segmenter(options);
  tirstrain::contact::ContactResult result;
  for (auto _ : state) {
    result = segmenter.segment(image);
    benchmark::DoNotOptimize(result.area_mm2);
  }
  state.counters["IoU"] =
      tirstrain::contact::mask_iou(tirstrain::contact::rasterize_polygon(result.hull_px, scene.size), truth);
  state.counters["factor"] = segmenter.downsample();
  state.SetLabel(std::to_string(width) + "x" + std::to_string(height) +
                 (downsample == 1 ? " full" : " reduced"));
}

// Period measured from the spectrum (first frame of a trial without a scene period).
void BM_MeasurePeriod(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0)), height = width * 4 / 5;
  const cv::Mat image = tirstrain::test::render_tir(scene_for(width, height));
  for (auto _ : state) {
    ContactSegmenter segmenter;
    benchmark::DoNotOptimize(segmenter.segment(image).ridge_period_px);
  }
}

}  // namespace

BENCHMARK(BM_Segment)
    ->Args({640, 0})
    ->Args({640, 1})
    ->Args({1280, 0})
    ->Args({1280, 1})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MeasurePeriod)->Arg(640)->Arg(1280)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
