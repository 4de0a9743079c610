// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/tau_memory.h"

#include <algorithm>
#include <cstdio>

#include "thinslab/fit/tau_prediction.h"

namespace thinslab {
namespace {

constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;
// Measured 2026-12-07 (docs/benchmarks.md, "fit tau: memory"): the frames stage peaked at 250 MB
// for 1.92 M camera pixels and 0.36 M points; the fit at 198 B per point with the split halves
// (385 MB at 1.44 M points, 1242 MB at 5.76 M) and 123 B without (807 MB at 5.76 M).
constexpr double kFixedBytes = 100.0 * 1024 * 1024;
constexpr double kFramesBytesPerCameraPixel = 75;
constexpr double kFramesBytesPerPoint = 60;
constexpr double kFitBytesPerPoint = 130, kFitBytesPerPointWithHalves = 200;
// OpenCV's DFT convolution holds about three float planes of the map padded by the kernel.
constexpr double kConvolutionPlanes = 3;

}  // namespace

double TauFitMemoryEstimate::total_bytes() const {
  return fixed_bytes + std::max(frames_bytes, fit_bytes + kernel_bytes);
}

std::string TauFitMemoryEstimate::Text() const {
  char text[160];
  std::snprintf(text, sizeof(text), "%.2f GiB (frames %.2f, fit %.2f, scattering kernels %.2f)", total_bytes() / kGiB,
                frames_bytes / kGiB, fit_bytes / kGiB, kernel_bytes / kGiB);
  return text;
}

TauFitMemoryEstimate EstimateTauFitMemory(int width, int height, int64_t camera_pixels, double board_distance_m,
                                          double pixel_pitch_m, const TauFitOptions& options, bool split_halves) {
  TauFitMemoryEstimate e;
  const double points = static_cast<double>(width) * height;
  e.fixed_bytes = kFixedBytes;
  e.frames_bytes = kFramesBytesPerCameraPixel * static_cast<double>(camera_pixels) + kFramesBytesPerPoint * points;
  e.fit_bytes = (split_halves ? kFitBytesPerPointWithHalves : kFitBytesPerPoint) * points;
  if (options.refine_scattering && options.layer_albedo > 0 && board_distance_m > 0 && pixel_pitch_m > 0) {
    const double side =
        2.0 * BoardKernelRadiusPx(LayerScatterGeometry(options, board_distance_m, pixel_pitch_m, width, height)) + 1;
    const double nodes = static_cast<double>(LayerScatterNodes(options).size());
    e.kernel_bytes = sizeof(float) * (nodes * side * side + kConvolutionPlanes * (width + side) * (height + side));
  }
  return e;
}

}  // namespace thinslab
