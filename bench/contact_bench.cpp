// Contact segmentation speed next to its accuracy: ms per frame at 640x512 and 1280x1024, for the reduced
// working resolution chosen automatically (f = floor(ridge period / 5.5 px)) and for full resolution, with
// the mask IoU against the exact truth of the rendered frame reported as a counter of the same run. The third
// argument is the pixel noise (per mille of full scale): at 80 the texture SNR falls below
// SegmenterOptions::border_average_snr and the edge search runs on the frame averaged along the border. The
// fourth is the preset (contact::SegmentationPreset): 0 accurate (the defaults), 1 fast, 2 balanced (the
// border band off), for their cost in the same run.
// Run: contact_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <cmath>

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
  tirstrain::test::TirScene scene = scene_for(width, height);
  scene.noise = static_cast<double>(state.range(2)) / 1000.0;
  const auto preset = state.range(3) == 1   ? tirstrain::contact::SegmentationPreset::fast
                      : state.range(3) == 2 ? tirstrain::contact::SegmentationPreset::balanced
                                            : tirstrain::contact::SegmentationPreset::accurate;
  const cv::Mat image = tirstrain::test::render_tir(scene);
  const cv::Mat truth = tirstrain::test::render_truth_mask(scene);
  SegmenterOptions options = tirstrain::contact::with_preset({}, preset);
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
  if (result.ellipse) {
    const tirstrain::contact::Ellipse& truth_ellipse = scene.contacts.front();
    state.counters["centre_px"] =
        std::hypot(result.ellipse->cx_px - truth_ellipse.cx_px, result.ellipse->cy_px - truth_ellipse.cy_px);
    state.counters["major_%"] = 100.0 * (result.ellipse->semi_major_px / truth_ellipse.semi_major_px - 1.0);
    state.counters["minor_%"] = 100.0 * (result.ellipse->semi_minor_px / truth_ellipse.semi_minor_px - 1.0);
  }
  state.counters["factor"] = segmenter.downsample();
  state.counters["SNR"] = result.texture_snr;
  state.counters["averaged"] = result.border_averaged ? 1.0 : 0.0;
  state.counters["ridge_labels"] = result.ridge_label_shift_px ? 1.0 : 0.0;
  state.SetLabel(std::to_string(width) + "x" + std::to_string(height) +
                 (downsample == 1 ? " full" : " reduced") + ", noise " + std::to_string(state.range(2) / 10) +
                 "." + std::to_string(state.range(2) % 10) + " %" +
                 (preset == tirstrain::contact::SegmentationPreset::fast       ? ", fast"
                  : preset == tirstrain::contact::SegmentationPreset::balanced ? ", balanced"
                                                                               : ", accurate"));
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
    ->Args({640, 0, 20, 0})
    ->Args({640, 1, 20, 0})
    ->Args({1280, 0, 20, 0})
    ->Args({1280, 1, 20, 0})
    ->Args({640, 0, 80, 0})
    ->Args({1280, 0, 80, 0})
    ->Args({640, 0, 20, 1})
    ->Args({640, 1, 20, 1})
    ->Args({1280, 0, 20, 1})
    ->Args({1280, 1, 20, 1})
    ->Args({640, 0, 80, 1})
    ->Args({1280, 0, 80, 1})
    ->Args({640, 0, 20, 2})
    ->Args({1280, 0, 20, 2})
    ->Args({640, 0, 80, 2})
    ->Args({1280, 0, 80, 2})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MeasurePeriod)->Arg(640)->Arg(1280)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
