// Throughput of the signals/ hot paths in samples per second: zero-phase filtering (the paper's 4th-order
// 80 Hz low-pass and the 15–500 Hz band-pass), Welch PSD and H1/coherence, and RQA of a 10^4-sample series
// (D = 3, fixed recurrence rate 5 %: threshold search + bitset + line histograms), and reading an HDF5
// channel file with and without the read in a child process first (signals/isolated_read.hpp). Each benchmark
// also reports an accuracy counter against known truth so speed and error are read together.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>

#include "core/h5_file.hpp"
#include "signals/channels.hpp"
#include "signals/filter.hpp"
#include "signals/rqa.hpp"
#include "signals/spectral.hpp"

namespace ts = tirstrain::signals;

namespace {

std::vector<double> noisy_sine(std::size_t n, double fs, double f) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 0.1);
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(2 * std::numbers::pi * f * i / fs) + g(rng);
  return x;
}

void BM_FiltfiltLowpass80(benchmark::State& state) {
  const double fs = 1000.0;
  const auto x = noisy_sine(static_cast<std::size_t>(state.range(0)), fs, 10.0);
  const ts::ButterworthSpec spec{ts::FilterType::lowpass, 4, 80.0, 0.0, fs};
  const auto sos = ts::butterworth_sos(spec);
  for (auto _ : state) benchmark::DoNotOptimize(ts::filtfilt(sos, x));
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

void BM_FiltfiltBandpass15to500(benchmark::State& state) {
  const double fs = 5000.0;
  const auto x = noisy_sine(static_cast<std::size_t>(state.range(0)), fs, 120.0);
  const auto sos = ts::butterworth_sos({ts::FilterType::bandpass, 4, 15.0, 500.0, fs});
  for (auto _ : state) benchmark::DoNotOptimize(ts::filtfilt(sos, x));
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

void BM_WelchPsd(benchmark::State& state) {
  const double fs = 1000.0;
  const auto x = noisy_sine(static_cast<std::size_t>(state.range(0)), fs, 50.0);
  ts::PowerSpectrum p;
  for (auto _ : state) benchmark::DoNotOptimize(p = ts::welch(x, fs, {.segment = 1000}));
  // Sine power A²/2 = 0.5 recovered from the main lobe (error counter, relative).
  double power = 0.0;
  for (std::size_t k = 45; k <= 55; ++k) power += p.psd[k];
  state.counters["sine_power_rel_err"] = std::abs(power - 0.5) / 0.5;
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

void BM_TransferEstimate(benchmark::State& state) {
  const double fs = 1000.0;
  const auto x = noisy_sine(static_cast<std::size_t>(state.range(0)), fs, 50.0);
  std::vector<double> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = 0.5 * x[i] + (i ? 0.3 * x[i - 1] : 0.0);
  for (auto _ : state) benchmark::DoNotOptimize(ts::transfer_estimate(x, y, fs, {.segment = 1024}));
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

void BM_Rqa(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(2 * std::numbers::pi * i / 100.0);
  ts::RqaMeasures m;
  for (auto _ : state) {
    const auto e = ts::delay_embed(x, 3, 25);
    const double eps = ts::threshold_for_recurrence_rate(e, 0.05, ts::RecurrenceNorm::euclidean);
    m = ts::rqa_measures(ts::line_histograms(ts::recurrence_matrix(e, eps, ts::RecurrenceNorm::euclidean)));
    benchmark::DoNotOptimize(m);
  }
  state.counters["determinism"] = m.determinism;  // truth: ~1 for a sine
  state.counters["rr_abs_err"] = std::abs(m.recurrence_rate - 0.05);
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

void BM_RqaFixedThreshold(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::vector<double> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(2 * std::numbers::pi * i / 100.0);
  for (auto _ : state) {
    const auto e = ts::delay_embed(x, 3, 25);
    benchmark::DoNotOptimize(
        ts::rqa_measures(ts::line_histograms(ts::recurrence_matrix(e, 0.1, ts::RecurrenceNorm::euclidean))));
  }
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK(BM_FiltfiltLowpass80)->Arg(1 << 20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FiltfiltBandpass15to500)->Arg(1 << 20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WelchPsd)->Arg(1 << 20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_TransferEstimate)->Arg(1 << 20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Rqa)->Arg(10000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RqaFixedThreshold)->Arg(10000)->Unit(benchmark::kMillisecond);

// A channel file of n samples at 1 kHz (t_s, normal_N, tangential_N), read whole; argument 1: read in a
// child process first (the default), 0: in this process only. max_abs_error: read against written (0).
void BM_ReadChannelsHdf5(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::string path =
      (std::filesystem::temp_directory_path() / ("signals_bench_" + std::to_string(n) + ".h5")).string();
  std::vector<double> t(n), normal = noisy_sine(n, 1000.0, 2.0), tangential = noisy_sine(n, 1000.0, 3.0);
  for (std::size_t i = 0; i < n; ++i) t[i] = static_cast<double>(i) / 1000.0;
  {
    tirstrain::H5Writer out(path);
    out.write("/t_s", t, {n});
    out.write("/normal_N", normal, {n});
    out.write("/tangential_N", tangential, {n});
    out.commit();
  }
  ts::ChannelReadOptions options;
  options.read_in_child_first = state.range(1) != 0;
  double error = 0.0;
  for (auto _ : state) {
    const ts::ChannelTable table = ts::read_channels(path, options);
    const std::vector<double>& read = table.column("normal_N");
    error = 0.0;
    for (std::size_t i = 0; i < n; ++i) error = std::max(error, std::abs(read[i] - normal[i]));
    benchmark::DoNotOptimize(error);
  }
  state.counters["max_abs_error"] = error;
  state.counters["samples_per_s"] =
      benchmark::Counter(static_cast<double>(n) * state.iterations(), benchmark::Counter::kIsRate);
  std::filesystem::remove(path);
}

BENCHMARK(BM_ReadChannelsHdf5)->Args({1 << 20, 0})->Args({1 << 20, 1})->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
