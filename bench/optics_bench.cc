// SPDX-License-Identifier: Apache-2.0
// Evaluations per second of the forward models in optics/ (issue #3). Each benchmark evaluates
// the model over a fixed, varied set of direction pairs so branch prediction sees real data.
//   build/bench/optics_bench --benchmark_out=docs/benchmarks/optics.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/dirty_glass_layer.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/henyey_greenstein.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/optics/thin_slab.h"
#include "thinslab/optics/walter_btdf.h"

namespace thinslab {
namespace {

constexpr int kPairs = 1024;

// Pairs (wi above, wo below or above) of unit directions.
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> DirectionPairs(bool transmission) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  auto dir = [&](double sign) {
    const double z = 0.05 + 0.95 * uni(rng), phi = 2 * kPi * uni(rng), r = std::sqrt(1 - z * z);
    return Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), sign * z);
  };
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pairs;
  for (int k = 0; k < kPairs; ++k) pairs.emplace_back(dir(1), dir(transmission ? -1 : 1));
  return pairs;
}

template <typename F>
void RunPairs(benchmark::State& state, bool transmission, F eval) {
  const auto pairs = DirectionPairs(transmission);
  double sink = 0;
  for (auto _ : state) {
    for (const auto& [wi, wo] : pairs) sink += eval(wi, wo);
  }
  benchmark::DoNotOptimize(sink);
  state.SetItemsProcessed(state.iterations() * kPairs);
}

void BM_HenyeyGreenstein(benchmark::State& state) {
  RunPairs(state, false, [](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
    return HenyeyGreenstein(wi.dot(wo), 0.8);
  });
}

void BM_GuEq6SingleScatter(benchmark::State& state) {
  RunPairs(state, true, [](const Eigen::Vector3d&, const Eigen::Vector3d& wo) {
    return LayerSingleScatterRadiance(0.3, -wo.z(), 0.3, 0.8);
  });
}

void BM_GuLayerBtdf(benchmark::State& state) {
  DirtyGlassLayer<double> layer;
  RunPairs(state, true, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return layer.Bsdf(wi, wo); });
}

void BM_FrisvadThinSlab(benchmark::State& state) {
  ThinSlab<double> slab;
  RunPairs(state, true, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
    return slab.TransmittedBsdf(wi.z(), -wo.z(), wi.dot(-wo));
  });
}

void BM_WalterGgxBtdf(benchmark::State& state) {
  const WalterRoughDielectric<GgxDistribution> bsdf(GgxDistribution(0.3), 1.5);
  RunPairs(state, true, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return bsdf.Eval(wi, wo); });
}

void BM_WalterBeckmannBrdf(benchmark::State& state) {
  const WalterRoughDielectric<BeckmannDistribution> bsdf(BeckmannDistribution(0.3), 1.5);
  RunPairs(state, false, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return bsdf.Eval(wi, wo); });
}

void BM_WalterGgxSample(benchmark::State& state) {
  const WalterRoughDielectric<GgxDistribution> bsdf(GgxDistribution(0.3), 1.5);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const auto pairs = DirectionPairs(false);
  double sink = 0;
  for (auto _ : state) {
    for (const auto& pair : pairs) {
      WalterBsdfSample<double> sample;
      if (bsdf.Sample(pair.first, uni(rng), uni(rng), uni(rng), &sample)) sink += sample.pdf;
    }
  }
  benchmark::DoNotOptimize(sink);
  state.SetItemsProcessed(state.iterations() * kPairs);
}

void BM_DualMicrofacetGgx(benchmark::State& state) {
  const DualMicrofacetBtdf<GgxDistribution> btdf(GgxDistribution(0.3), GgxDistribution(0.3), 1.5);
  RunPairs(state, true, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return btdf.Eval(wi, wo, 0.5); });
}

void BM_DualMicrofacetTabulated(benchmark::State& state) {
  const DualMicrofacetBtdf<TabulatedNdf, GgxDistribution> btdf(
      TabulatedNdf::FromDistribution(GgxDistribution(0.3), 32), GgxDistribution(0.3), 1.5);
  RunPairs(state, true, [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return btdf.Eval(wi, wo, 0.5); });
}

BENCHMARK(BM_HenyeyGreenstein);
BENCHMARK(BM_GuEq6SingleScatter);
BENCHMARK(BM_GuLayerBtdf);
BENCHMARK(BM_FrisvadThinSlab);
BENCHMARK(BM_WalterGgxBtdf);
BENCHMARK(BM_WalterBeckmannBrdf);
BENCHMARK(BM_WalterGgxSample);
BENCHMARK(BM_DualMicrofacetGgx);
BENCHMARK(BM_DualMicrofacetTabulated);

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
