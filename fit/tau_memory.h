// SPDX-License-Identifier: Apache-2.0
// The peak memory of `fit tau` (issue #29), estimated before any frame is read so that a map the
// budget (`--max-memory`) or the machine cannot hold is refused up front, naming the need. The
// fit keeps every map point resident (the scattered light of Gu Eq. 6 is a convolution over the
// whole layer at every fixed-point iteration), so the need grows with the points; this is a
// budget check, not streaming.
//
// The terms were measured with /usr/bin/time on simulated captures (docs/benchmarks.md, "fit
// tau: memory"; 1600 x 1200 camera, 600^2 to 2400^2 map points, boards at 1 and 10 mm) and are
// set a little above them:
//  - fixed: the program, its libraries and buffers;
//  - frames: reading, averaging and rectifying the camera frames (per camera pixel) with the
//    rectified maps and split halves (per map point);
//  - fit: the fixed point's per-point state (doubles for m, its sigma, tau, the scattered light,
//    ...), the maps and, with the split-half check, a half's fit beside the whole one's maps;
//  - kernels: the Eq. 6 kernel bank (one float square per tau node) and the convolution's
//    workspace (OpenCV's DFT of the map padded by the kernel).
// The frames' and the fit's peaks do not overlap; the kernels come with the fit.
#pragma once

#include <cstdint>
#include <string>

#include "thinslab/fit/tau_fit.h"

namespace thinslab {

struct TauFitMemoryEstimate {
  double fixed_bytes = 0, frames_bytes = 0, fit_bytes = 0, kernel_bytes = 0;
  double total_bytes() const;
  std::string Text() const;  // "1.25 GiB (frames 0.26, fit 1.12, scattering kernels 0.09)".
};

// A width x height map of `pixel_pitch_m` from a camera of `camera_pixels`, the board at
// `board_distance_m`; `split_halves`: the split-half check's two more fits.
TauFitMemoryEstimate EstimateTauFitMemory(int width, int height, int64_t camera_pixels, double board_distance_m,
                                          double pixel_pitch_m, const TauFitOptions& options, bool split_halves);

}  // namespace thinslab
