// SPDX-License-Identifier: Apache-2.0
// What a dual-microfacet fit predicts for a light state it was not fitted to (issue #23
// section 4, `thinslab predict`): the image the capture's camera would record through the
// sample lit by one monitor dot at any position, from the fit's own outputs (maps.exr, the NDF
// atlas, summary.json), so a fit can be checked against any measurement after the fact.
//
// Per camera pixel: the ray meets the sample plane at x; the map point under x holds the fitted
// model (alpha, Smith roughness, k_s, rho_d and the tabulated NDF); the dot at p_q (placed by the
// monitor pose the fit used) lights it through the slab's entry point x_b
// (SlabLightEntryPoint), so Eq. 12 read backwards gives the pixel's radiance
//   I = R(x, i_q, o) L_q A cos_e cos_i / |p_q - x_b|^2   [DN/us, the HDR merge's unit],
// L_q the fit's median dot radiance, A the dot's area.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_map_fit.h"

namespace thinslab {

struct DmfFitOnDisk {
  DmfMaps maps;                 // log_ndf from the atlas tile of the point, or of the nearest stored one.
  int atlas_stride = 1;         // 1: every point's own NDF.
  Eigen::Vector2d grid_min_m = Eigen::Vector2d::Zero();
  double pitch_m = 0;
  double glass_thickness_m = 0;
  Rigid3d sample_from_monitor;
  double monitor_pixel_pitch_m = 0;
  double dot_intensity = 0;     // L_q A [DN/us m^2]: median dot radiance times the dot's area.
  double dot_radiance = 0;      // L_q [DN/us]: the fit's median dot radiance.
  double dot_radius_m = 0;      // The dot's radius on the monitor.
};

// Reads FIT_DIR/maps.exr, ndf_atlas.exr and summary.json of `thinslab fit dmf`; errors name the
// file and what is missing (fits written before the summary held the monitor pose are refused
// with the way on: fit again).
Status ReadDmfFit(const std::string& fit_dir, DmfFitOnDisk* fit);

// Channels "predicted" (DN/us) and "valid" (1 where the pixel sees a map point with a fitted
// model) of the camera image lit by the dot at `dot_px` [monitor px].
Image PredictDotImage(const DmfFitOnDisk& fit, const CameraInfo& camera, const Eigen::Vector2d& dot_px);

// Prediction against a measurement (HDR radiance and variance in the camera, DN/us): over the
// valid pixels in the lobe (measured at or above `lobe_fraction` of the largest valid one),
// sqrt(sum (pred - meas)^2 / sum meas^2) and beside it sqrt(sum var / sum meas^2).
struct DotPredictionError {
  int pixels = 0;
  double relative_rms = -1, noise_relative_rms = -1;
};
DotPredictionError ComparePrediction(const Image& prediction, const Image& radiance, const Image& variance,
                                     double lobe_fraction = 0.1);

}  // namespace thinslab
