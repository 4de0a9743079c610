// SPDX-License-Identifier: Apache-2.0
// The k-means acceleration of the dual-microfacet fit alone (fit/dmf_clustering.h, Dai et al.
// Sec. 4.3): ClusterSlices on synthetic slice shapes (nine materials, 256 shape nodes, 2 %
// noise) at 1 % representatives, against the number of points and the threads. Its cost grows
// as points x representatives (the assignment and the Eq. 20 neighbour search), so quadratically
// at a fixed fraction; docs/benchmarks.md records the figures.
//   build/bench/dmf_clustering_bench --benchmark_filter=.
#include <benchmark/benchmark.h>

#include <random>

#include "thinslab/fit/dmf_clustering.h"

namespace thinslab {
namespace {

void BM_ClusterSlices(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  constexpr int kNodes = 256, kMaterials = 9;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uniform(0, 1);
  std::normal_distribution<float> noise(0, 0.02f);
  Eigen::MatrixXf materials(kMaterials, kNodes);
  for (int m = 0; m < kMaterials; ++m) {
    for (int n = 0; n < kNodes; ++n) materials(m, n) = uniform(rng);
  }
  Eigen::MatrixXf shapes(points, kNodes);
  for (int p = 0; p < points; ++p) {
    // Two materials mixed in a random share: a continuum of shapes, as at region borders.
    const int a = p % kMaterials, b = (p / kMaterials) % kMaterials;
    const float t = uniform(rng);
    for (int n = 0; n < kNodes; ++n) shapes(p, n) = t * materials(a, n) + (1 - t) * materials(b, n) + noise(rng);
  }
  const std::vector<uint8_t> valid(points, 1);
  DmfClusteringOptions options;
  options.num_threads = threads;
  for (auto _ : state) {
    const DmfClustering c = ClusterSlices(shapes, valid, options);
    benchmark::DoNotOptimize(c.weights.data());
    state.counters["representatives"] = static_cast<double>(c.representatives.size());
  }
  state.counters["points"] = points;
}
BENCHMARK(BM_ClusterSlices)
    ->ArgsProduct({{40000, 90000, 160000, 360000}, {1, 2}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
