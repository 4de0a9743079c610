// SPDX-License-Identifier: Apache-2.0
// The k-means acceleration of the dual-microfacet fit alone (fit/dmf_clustering.h, Dai et al.
// Sec. 4.3): ClusterSlices on synthetic slice shapes (nine materials, 256 shape nodes, 2 %
// noise) at 1 % representatives, against the number of points and the threads. The nearest
// centres and representatives are found through anchors (fit/nearest_rows.h), so the cost grows
// about as points^1.5 at a fixed fraction, not points x representatives; BM_FitProjection times
// the principal components alone. docs/benchmarks.md records the figures.
//   build/bench/dmf_clustering_bench --benchmark_filter=.
#include <benchmark/benchmark.h>

#include <random>

#include "thinslab/fit/dmf_clustering.h"

namespace thinslab {
namespace {

// Slice shapes of `points` points with `nodes` values: two of nine random materials mixed in a
// random share (a continuum of shapes, as at region borders), plus 2 % noise.
Eigen::MatrixXf MixtureShapes(int points, int nodes) {
  constexpr int kMaterials = 9;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uniform(0, 1);
  std::normal_distribution<float> noise(0, 0.02f);
  Eigen::MatrixXf materials(kMaterials, nodes);
  for (int m = 0; m < kMaterials; ++m) {
    for (int n = 0; n < nodes; ++n) materials(m, n) = uniform(rng);
  }
  Eigen::MatrixXf shapes(points, nodes);
  for (int p = 0; p < points; ++p) {
    const int a = p % kMaterials, b = (p / kMaterials) % kMaterials;
    const float t = uniform(rng);
    for (int n = 0; n < nodes; ++n) shapes(p, n) = t * materials(a, n) + (1 - t) * materials(b, n) + noise(rng);
  }
  return shapes;
}

void BM_ClusterSlices(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const Eigen::MatrixXf shapes = MixtureShapes(points, 256);
  const std::vector<uint8_t> valid(points, 1);
  DmfClusteringOptions options;
  options.num_threads = threads;
  for (auto _ : state) {
    const DmfClustering c = ClusterSlices(shapes, valid, options);
    benchmark::DoNotOptimize(c.weights.data());
    state.counters["representatives"] = static_cast<double>(c.representatives.size());
    state.counters["exhaustive"] = static_cast<double>(c.exhaustive_searches);
  }
  state.counters["points"] = points;
}
BENCHMARK(BM_ClusterSlices)
    ->ArgsProduct({{40000, 90000, 160000, 360000, 1440000}, {1, 2}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

// The principal components alone (DmfShapeClusterer::FitProjection): the subsample's 20 000
// shapes of `nodes` values each (1600 at the paper's 40 x 40 dots).
void BM_FitProjection(benchmark::State& state) {
  const int nodes = static_cast<int>(state.range(0));
  DmfClusteringOptions options;
  options.num_threads = static_cast<int>(state.range(1));
  const std::vector<uint8_t> valid(options.subsample, 1);
  const Eigen::MatrixXf shapes = MixtureShapes(options.subsample, nodes);
  for (auto _ : state) {
    DmfShapeClusterer clusterer(valid, options);
    clusterer.FitProjection(shapes);
  }
  state.counters["nodes"] = nodes;
}
BENCHMARK(BM_FitProjection)->ArgsProduct({{256, 1600}, {1, 2}})->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
