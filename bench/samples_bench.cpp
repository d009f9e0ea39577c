// Rendering throughput of the synthetic trial generator (frames/s) on the default scene: the generator is on
// every accuracy test's critical path. Also reports the worst forward-map residual of the rendered frames.
#include <benchmark/benchmark.h>

#include <string>

#include "samples/synth_config.hpp"
#include "samples/trial.hpp"

namespace {

using tirstrain::samples::Trial;

const Trial& default_trial() {
  static const Trial trial(tirstrain::samples::load_synth_config(std::string(TIRSTRAIN_SOURCE_DIR) +
                                                                 "/samples/scenes/default.yaml"));
  return trial;
}

void BM_RenderDefaultFrame(benchmark::State& state) {
  const Trial& trial = default_trial();
  int frame = 0;
  for (auto _ : state) {
    cv::Mat image = trial.apply_sensor(trial.render_clean(frame), frame);
    benchmark::DoNotOptimize(image.data);
    frame = (frame + 1) % trial.frames();
  }
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  double residual_px = 0.0;
  trial.inverse_map(trial.frames() - 1, &residual_px);
  state.counters["max_inverse_residual_px"] = residual_px;
}
BENCHMARK(BM_RenderDefaultFrame)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_GridTruthDefaultFrame(benchmark::State& state) {
  const Trial& trial = default_trial();
  for (auto _ : state) benchmark::DoNotOptimize(trial.grid_truth(trial.frames() - 1).strain.data());
}
BENCHMARK(BM_GridTruthDefaultFrame)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
