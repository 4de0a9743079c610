// SPDX-License-Identifier: Apache-2.0
// Synthetic chessboard photographs for camera-calibration tests: a planar board seen by an
// OpenCV pinhole camera with Brown-Conrady distortion, area-integrated over n x n sub-samples per
// pixel (the distortion is inverted per sub-sample, so straight edges bend as on a real lens),
// blurred by a Gaussian optical PSF and passed through the sensor model (shot and read noise,
// quantisation, clipping). Geometry is exact; the calibration code never sees this renderer's
// internals, only the raw frames.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/sim/sensor_model.h"

namespace thinslab {

// Board frame: the board is the plane z = 0; inner corner (i, j) (i < inner_cols along x,
// j < inner_rows along y) is at (i, j, 0) * square_m, the order OpenCV's object points use.
// The squares span [-1, inner_cols] x [-1, inner_rows] squares; square (a, b) is black when
// a + b is even, so square (-1, -1) is black; a white margin of `margin_squares` surrounds them.
struct SimChessboardOptions {
  int inner_cols = 9;
  int inner_rows = 6;
  double square_m = 0.025;
  double margin_squares = 0.75;
  double black_radiance = 0.06;   // Relative radiances of the printed squares, the margin
  double white_radiance = 0.85;   // (white) and the background behind the board.
  double background_radiance = 0.35;
  double blur_sigma_px = 0.6;     // Gaussian PSF, camera pixels (0 = none).
  int render_supersample = 4;
  double electrons_per_radiance = 25000;  // Electrons of a pixel seeing radiance 1 (exposure folded in).
  SimSensorOptions sensor;        // Default below: 8-bit like the JPEGs calibration tools expect.
  SimChessboardOptions() {
    sensor.bit_depth = 8;
    sensor.black_level_dn = 0;
    sensor.full_well_e = 25000;
    sensor.read_noise_e = 20;
  }
  Status Check() const;
};

// Renders raw DN (integers stored as float) of the board seen by `camera` (intrinsics and
// distortion; camera.cam_from_sample is cam_from_board).
Status RenderChessboardView(const SimChessboardOptions& options, const CameraInfo& camera, uint64_t seed,
                            Image* raw_dn);

// `count` varied poses (cam_from_board) that keep the whole board, plus half a square, inside
// the image of `camera`: distances and tilts up to `max_tilt_deg` about both board axes, drawn
// from a seeded generator. Errors if no valid pose is found for some view.
Status MakeChessboardViewPoses(const SimChessboardOptions& options, const CameraInfo& camera, int count,
                               double max_tilt_deg, uint64_t seed, std::vector<Rigid3d>* cam_from_board);

// Separable Gaussian blur of every channel (edge pixels clamp); sigma 0 returns the input.
Image BlurGaussian(const Image& image, double sigma_px);

}  // namespace thinslab
