// SPDX-License-Identifier: Apache-2.0
// Turns the raw frames of a shadow-map session into radiometrically linear, averaged,
// dark-subtracted images rectified onto the board plane (z = -board.distance_m in the sample
// frame), on the sample region grid of the manifest, so pixel (i, j) of every output is the
// board point below sample point (region_min + (i + 0.5, j + 0.5) * pitch).
#pragma once

#include <string>
#include <vector>

#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct ShadowMapPreparationOptions {
  // Each rectified pixel averages n x n board points, each taking the camera pixel it falls
  // in (area-weighted resampling).
  int supersample = 4;
  // Override of the manifest's board distance (metres); 0 = use the manifest.
  double board_distance_m = 0;
  // SESSION/calib/rig.json (camera intrinsics and pose) and response.json (linearisation).
  SessionCalibrationOptions calibration;
  // Also load and rectify SESSION/calib/flat_field.exr (into `flat`), for `fit tau --reference
  // flat`; off, the file is not read (a flat field of another camera cannot fail other fits).
  bool load_flat_field = false;
  // Also keep the averaged frames in camera pixels (RectifiedShadowMaps::camera_*), for
  // predictions imaged in the camera (`thinslab predict`).
  bool keep_camera_frames = false;
  // Also average alternate shadow frames (and reference frames, when there are >= 2) into two
  // halves (RectifiedShadowMaps::halves), for the split-half consistency of sigma_tau.
  bool split_halves = false;

  bool Check(std::string* error) const;
};

struct RectifiedShadowMaps {
  Image shadow;              // Mean DN per microsecond, contaminated sample.
  Image reference;           // Mean DN per microsecond, clean sample; empty if not captured.
  Image shadow_variance;     // Variance of `shadow` (DN/us)^2.
  Image reference_variance;  // Variance of `reference`.
  // The validation shadow frames (FrameRecord::validation, never fitted) averaged and rectified
  // like `shadow`; empty when the capture has none.
  Image validation_shadow, validation_shadow_variance;
  Image validation_saturated;  // 1 where a contributing raw validation pixel saturated.
  Image saturated;           // 1 where a contributing raw pixel saturated in any frame.
  // With keep_camera_frames: the averaged frames before rectification (camera pixels, DN/us),
  // the measured shadow's variance and saturation (the validation frames' when the capture has
  // them, else the fitted ones'; saturation also where the reference saturated).
  Image camera_reference, camera_reference_variance, camera_shadow, camera_shadow_variance, camera_shadow_saturated;
  Image outside;             // 1 where the board point is outside the camera image.
  // Side of the board square one camera pixel covers, per map pixel (calib/board_rectification.h).
  Image camera_footprint_m;
  // With split_halves and >= 2 shadow frames: the shadow of the even and of the odd frames (and
  // the reference likewise when it has >= 2 frames; else both halves hold the whole reference,
  // reference_shared), rectified as above. Empty otherwise.
  struct Half {
    Image shadow, shadow_variance, reference, reference_variance;
  };
  std::vector<Half> halves;
  bool halves_share_reference = false;
  // calib/flat_field.exr rectified (unitless, 0 where invalid); empty when the session has none.
  Image flat;
  Eigen::Vector2d region_min_m = Eigen::Vector2d::Zero();
  double pixel_pitch_m = 0;
  double board_distance_m = 0;
  int num_shadow_frames = 0;
  int num_reference_frames = 0;
  int num_dark_frames = 0;
  int num_validation_frames = 0;
  FrameNoiseModel noise;  // Of the camera's frames (calib/frame_noise.h), in summary.json.
  CameraInfo camera;                 // The manifest camera with the calibration applied.
  SessionCalibration calibration;    // What was applied.
};

Status PrepareShadowMaps(const std::string& session_dir, const Session& session,
                         const ShadowMapPreparationOptions& options, RectifiedShadowMaps* maps);

// The map grid PrepareShadowMaps rectifies onto: rig.sample's region at its pixel pitch (to the
// nearest whole pixel). `manifest` names the file in errors.
Status ShadowMapGridSize(const Session& session, const std::string& manifest, int* width, int* height);

}  // namespace thinslab
