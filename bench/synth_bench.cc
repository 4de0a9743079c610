// SPDX-License-Identifier: Apache-2.0
// Synthesis time of contamination layers (issue #9, Gu et al. 2007 Sec. 5.3): quilting a
// dust prototype and the full three-layer synthesis from the bundled library, at 1024^2 and
// 4096^2 (single thread; the quilting is sequential in raster order).
//   build/bench/synth_bench --benchmark_out=docs/benchmarks/synth.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <string>

#include "thinslab/synth/layer_synthesis.h"
#include "thinslab/synth/prototype_library.h"

namespace thinslab {
namespace {

std::string LibraryDir() {
  const char* dir = std::getenv("THINSLAB_SOURCE_DIR");
  return std::string(dir ? dir : THINSLAB_BENCH_SOURCE_DIR) + "/data/prototypes";
}

const std::vector<Prototype>& Library() {
  static const std::vector<Prototype> library = [] {
    std::vector<Prototype> lib;
    const Status s = ReadPrototypeLibrary(LibraryDir(), &lib);
    CHECK(s.ok()) << s.message();
    return lib;
  }();
  return library;
}

const Prototype& Find(const std::string& category) {
  for (const auto& p : Library()) {
    if (p.category == category) return p;
  }
  LOG(FATAL) << "no " << category << " prototype in " << LibraryDir();
  return Library()[0];
}

void BM_QuiltDust(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  const Prototype& dust = Find("dust");
  QuiltingOptions options;
  QuiltingSummary summary;
  for (auto _ : state) {
    Image out;
    const Status s = QuiltTexture(dust.tau, size, size, options, &out, nullptr, &summary);
    CHECK(s.ok()) << s.message();
    benchmark::DoNotOptimize(out.data().data());
  }
  state.counters["patches"] = summary.patches;
  state.counters["Mpixel/s"] =
      benchmark::Counter(static_cast<double>(size) * size * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_SynthesizeLayer(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  SynthesisOptions options;
  options.width_px = options.height_px = size;
  for (const char* category : {"dust", "dirt", "lipid"}) {
    SynthLayerSpec spec;
    spec.prototype = Find(category).name;
    options.layers.push_back(spec);
  }
  SynthesisSummary summary;
  for (auto _ : state) {
    Image layer;
    const Status s = SynthesizeContamination(Library(), options, &layer, &summary);
    CHECK(s.ok()) << s.message();
    benchmark::DoNotOptimize(layer.data().data());
  }
  state.counters["dust_s"] = summary.layers[0].seconds;
  state.counters["dirt_s"] = summary.layers[1].seconds;
  state.counters["lipid_s"] = summary.layers[2].seconds;
}

BENCHMARK(BM_QuiltDust)->Arg(1024)->Arg(4096)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_SynthesizeLayer)->Arg(1024)->Arg(4096)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
