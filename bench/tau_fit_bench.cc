// SPDX-License-Identifier: Apache-2.0
// Tau-map throughput (pixels per second) for plain Gu Eq. 7 and the scattering-aware
// refinement, on an N x N rectified shadow map (board 1 mm, 80 um pitch, a ring pattern
// covering ~45 % of the area). Results: docs/benchmarks.md.
//   build/bench/tau_fit_bench --benchmark_out=docs/benchmarks/tau_fit.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <cmath>

#include "thinslab/fit/tau_fit.h"

namespace thinslab {
namespace {

RectifiedShadowMaps MakeData(int n) {
  RectifiedShadowMaps data;
  data.shadow = Image(n, n);
  data.reference = Image(n, n, 100.0f);
  data.shadow_variance = Image(n, n, 0.01f);
  data.reference_variance = Image(n, n, 0.01f);
  data.saturated = Image(n, n);
  data.outside = Image(n, n);
  data.pixel_pitch_m = 80e-6;
  data.board_distance_m = 1e-3;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double r = std::hypot(x - n / 2.0, y - n / 2.0) / n;
      const double tau = r < 0.38 ? 0.6 + 0.5 * std::cos(r * 200) : 0.0;
      data.shadow.at(x, y) = static_cast<float>(100.0 * std::exp(-tau));
    }
  }
  return data;
}

void RunFit(benchmark::State& state, bool refine, double smoothness) {
  const int n = static_cast<int>(state.range(0));
  const RectifiedShadowMaps data = MakeData(n);
  TauFitOptions options;
  options.refine_scattering = refine;
  options.smoothness_sigma_tau = smoothness;
  options.num_threads = 2;
  TauFitSummary summary;
  for (auto _ : state) {
    TauMaps maps;
    const Status status = FitTau(options, data, &maps, &summary);
    if (!status.ok()) state.SkipWithError(status.message().c_str());
    benchmark::DoNotOptimize(maps.tau.data().data());
  }
  state.counters["pixels_per_s"] =
      benchmark::Counter(static_cast<double>(n) * n, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["outer_iterations"] = summary.outer_iterations;
}

void BM_TauPlainEq7(benchmark::State& state) { RunFit(state, false, 0.0); }
void BM_TauRefinedClosedForm(benchmark::State& state) { RunFit(state, true, 0.0); }
void BM_TauRefinedCeresPrior(benchmark::State& state) { RunFit(state, true, 0.1); }

BENCHMARK(BM_TauPlainEq7)->Arg(512)->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TauRefinedClosedForm)->Arg(512)->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)
    ->UseRealTime()->Iterations(1);
BENCHMARK(BM_TauRefinedCeresPrior)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime()
    ->Iterations(1);

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
