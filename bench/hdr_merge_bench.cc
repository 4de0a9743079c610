// SPDX-License-Identifier: Apache-2.0
// HDR merge rate: thinslab's MergeExposureBracket against OpenCV's cv::MergeDebevec on a
// 16-Mpixel (4096 x 4096), 5-exposure stack. OpenCV's merge accepts only 8-bit images
// (CV_Assert(depth == CV_8U) in modules/photo/src/merge.cpp), so it runs on the 8-bit version of
// the stack; thinslab merges the 16-bit stack (and, for a like-for-like figure, the 8-bit one
// with OpenCV's weights and log-domain mean). Results: docs/benchmarks.md.
#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/photo.hpp>

#include <cmath>
#include <cstdint>
#include <memory>

#include "thinslab/calib/hdr_merge.h"

namespace thinslab {
namespace {

constexpr int kSize = 4096;
const double kExposures[] = {100, 400, 1600, 6400, 25600};

// A gamma-2.2 camera seeing a log ramp over 4 decades with hashed (deterministic) noise;
// values are integer raw DN, black level 0.
struct Stack {
  int bit_depth;
  std::vector<Image> frames;
  std::vector<cv::Mat> cv_frames;  // 8-bit only.
  CameraResponse response;

  explicit Stack(int bits) : bit_depth(bits) {
    const double max_dn = (1 << bits) - 1;
    for (double t : kExposures) {
      Image frame(kSize, kSize);
      for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
          const double radiance = std::pow(10.0, -4.0 + 4.0 * ((x + y) % kSize) / kSize) / kExposures[0];
          uint32_t h = static_cast<uint32_t>(x * 73856093u) ^ static_cast<uint32_t>(y * 19349663u) ^
                       static_cast<uint32_t>(t * 83492791.0);
          h ^= h >> 13;
          h *= 0x5bd1e995u;
          h ^= h >> 15;
          const double noise = 1.0 + 0.01 * ((h & 0xffff) / 32768.0 - 1.0);
          const double s = std::min(1.0, radiance * t * noise);
          frame.at(x, y) = static_cast<float>(std::round(max_dn * std::pow(s, 1 / 2.2)));
        }
      }
      if (bits == 8) {
        cv::Mat m(kSize, kSize, CV_8U);
        for (int y = 0; y < kSize; ++y) {
          for (int x = 0; x < kSize; ++x) m.at<uint8_t>(y, x) = static_cast<uint8_t>(frame.at(x, y));
        }
        cv_frames.push_back(m);
      }
      frames.push_back(std::move(frame));
    }
    response.method = "debevec";
    response.bit_depth = bits;
    response.saturation_dn = max_dn;
    response.reference_dn = max_dn / 2;
    const int knots = 256;
    for (int j = 0; j < knots; ++j) {
      const double z = max_dn * j / (knots - 1);
      response.knots_dn.push_back(z);
      response.linear_dn.push_back(std::max(1e-3, max_dn * std::pow(z / max_dn, 2.2)));
    }
  }
  std::vector<HdrFrame> Bracket() const {
    std::vector<HdrFrame> out;
    for (size_t k = 0; k < frames.size(); ++k) {
      HdrFrame f(&frames[k], kExposures[k]);
      f.bit_depth = bit_depth;
      out.push_back(f);
    }
    return out;
  }
};

const Stack& Stack16() {
  static const auto* stack = new Stack(16);
  return *stack;
}
const Stack& Stack8() {
  static const auto* stack = new Stack(8);
  return *stack;
}

void Report(benchmark::State& state) {
  state.counters["Mpx_per_s"] = benchmark::Counter(static_cast<double>(kSize) * kSize * 1e-6,
                                                   benchmark::Counter::kIsIterationInvariantRate);
}

// Default merge of a 16-bit stack: inverse-variance weights through a 256-knot response.
void BM_Thinslab16BitInverseVariance(benchmark::State& state) {
  const Stack& stack = Stack16();
  HdrMergeOptions options;
  options.saturation_dn = 65535;
  options.response = &stack.response;
  options.num_threads = static_cast<int>(state.range(0));
  HdrImage hdr;
  for (auto _ : state) {
    const Status status = MergeExposureBracket(stack.Bracket(), options, &hdr);
    if (!status.ok()) state.SkipWithError(status.message().c_str());
    benchmark::DoNotOptimize(hdr.radiance.data().data());
  }
  Report(state);
}
BENCHMARK(BM_Thinslab16BitInverseVariance)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The 16-bit stack with Debevec's hat weights and log-domain mean.
void BM_Thinslab16BitDebevecLog(benchmark::State& state) {
  const Stack& stack = Stack16();
  HdrMergeOptions options;
  options.saturation_dn = 65535;
  options.response = &stack.response;
  options.weighting = HdrWeighting::kHat;
  options.log_domain = true;
  options.num_threads = static_cast<int>(state.range(0));
  HdrImage hdr;
  for (auto _ : state) {
    const Status status = MergeExposureBracket(stack.Bracket(), options, &hdr);
    if (!status.ok()) state.SkipWithError(status.message().c_str());
    benchmark::DoNotOptimize(hdr.radiance.data().data());
  }
  Report(state);
}
BENCHMARK(BM_Thinslab16BitDebevecLog)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Like for like with OpenCV: the 8-bit stack, OpenCV's triangle weights, log-domain mean.
void BM_Thinslab8BitOpenCvEquivalent(benchmark::State& state) {
  const Stack& stack = Stack8();
  HdrMergeOptions options;
  options.saturation_dn = 255;
  options.response = &stack.response;
  options.weighting = HdrWeighting::kHat;
  options.log_domain = true;
  for (int z = 0; z < 256; ++z) options.weight_table.push_back(z < 128 ? z + 1.0 : 256.0 - z);
  options.num_threads = static_cast<int>(state.range(0));
  HdrImage hdr;
  for (auto _ : state) {
    const Status status = MergeExposureBracket(stack.Bracket(), options, &hdr);
    if (!status.ok()) state.SkipWithError(status.message().c_str());
    benchmark::DoNotOptimize(hdr.radiance.data().data());
  }
  Report(state);
}
BENCHMARK(BM_Thinslab8BitOpenCvEquivalent)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// cv::MergeDebevec (OpenCV 4.6) on the 8-bit stack, with the same response, OpenCV threads = arg.
void BM_OpenCvMergeDebevec8Bit(benchmark::State& state) {
  const Stack& stack = Stack8();
  cv::setNumThreads(static_cast<int>(state.range(0)));
  cv::Mat response(256, 1, CV_32F);
  for (int z = 0; z < 256; ++z) response.at<float>(z) = static_cast<float>(stack.response.Linearize(z));
  std::vector<float> times(std::begin(kExposures), std::end(kExposures));
  cv::Ptr<cv::MergeDebevec> merge = cv::createMergeDebevec();
  cv::Mat hdr;
  for (auto _ : state) {
    merge->process(stack.cv_frames, hdr, times, response);
    benchmark::DoNotOptimize(hdr.data);
  }
  Report(state);
}
BENCHMARK(BM_OpenCvMergeDebevec8Bit)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace thinslab

BENCHMARK_MAIN();
