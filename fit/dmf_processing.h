// SPDX-License-Identifier: Apache-2.0
// Image processing of a CRT dot scan into BTDF slices (Dai et al. 2009, Sec. 4.1), streaming
// one dot's exposure bracket at a time:
//  1. dot geometry and radiance L_q from the all-dots frame taken without the sample
//     (calib/dot_geometry.h: sub-pixel centroids back-projected to the monitor plane), or from
//     calib/rig.json when `thinslab calib dots` wrote its monitor section;
//  2. per dot: HDR merge of its bracket with the dark bracket subtracted (calib/hdr_merge.h),
//     rectified onto the sample grid (calib/board_rectification.h) at supersample^2 points
//     per grid cell, not the cell average (which would blur the lobe by the cell's spread of
//     lighting directions);
//  3. Eq. 12, with the emitter's cosine explicit (a monitor pixel of radiance L_q and area A
//     has intensity L_q A cos_e towards the sample point):
//        R(x, i_q, o) = I_q(x) r^2 / (L_q A cos_e (z . i_q)),
//     the lighting direction i_q(x) = (p_q - x) / |p_q - x| and the view direction from x to
//     the calibrated camera centre (per point, not one o_c for all: it costs nothing).
// Only the slice matrix (points x dots floats) is kept in memory.
#pragma once

#include <string>
#include <vector>

#include "thinslab/calib/dot_geometry.h"
#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session_recovery.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_map_fit.h"

namespace thinslab {

struct DmfProcessingOptions {
  double pitch_m = 0;          // Sample grid pitch; 0 = the manifest's sample pixel pitch.
  // Radius of a displayed dot [monitor px] (A of Eq. 12, L_q, the detection windows); 0 = the
  // manifest's rig.monitor.dot_radius_px, else 2 (ResolveDotRadiusPx).
  double dot_radius_px = 0;
  bool hold_out = false;       // Hold out dots from the fit, in `hold_out_pattern`.
  HoldOutPattern hold_out_pattern;
  // A point whose dot frames saturated in every exposure for more than this fraction of its
  // in-lobe dots is flagged saturated; more than `max_saturated_points` of such points is an error.
  double max_saturated_dots = 0.02;
  double max_saturated_points = 0.5;
  int supersample = 2;         // Rectification sub-samples per grid pixel and axis.
  // Slab thickness [m] (where each dot's light enters, DmfSliceSet::LightEntryPoint); < 0 = the
  // manifest's rig.sample.glass_thickness_m. eta: the slab's index for it; 0 = rig.sample.glass_ior.
  double glass_thickness_m = -1;
  double eta = 0;
  DotGeometryOptions dot_geometry;
  // SESSION/calib/rig.json (camera intrinsics, pose and, from `thinslab calib dots`, the dot
  // positions and radiances, which then replace step 1) and response.json (linearisation).
  SessionCalibrationOptions calibration;
  // A capture whose acquisition did not complete (core/session_recovery.h) is refused unless
  // kAccept (`fit dmf --allow-incomplete`); its journaled frames are read either way.
  IncompleteCapture incomplete_capture = IncompleteCapture::kRefuse;
  // Reports the dots' frames as they are merged into slices (Eq. 12); returning false cancels
  // (core/progress.h).
  ProgressCallback progress;
  // Memory budget of the whole chain, processing and fit (issue #29, `fit dmf --max-memory`);
  // 0 = none. When the slice matrix and the fit's per-point state would exceed it
  // (PlanDmfMemory), the matrix goes to an unlinked file in `spill_dir` and the fit streams it
  // in bands of points sized to the budget.
  double max_memory_bytes = 0;
  std::string spill_dir;
  // > 0: stream whatever the budget, in bands of at most this many points (whole grid rows; at
  // least one row). For checking the streamed path on small grids.
  int stream_band_points = 0;
  // Non-empty: the option of the fit that follows that cannot run streamed (`--ladder`); a grid
  // over the budget is then refused before any frame is read.
  std::string streaming_refused_by;
  int fit_ndf_resolution = 32;   // Of the fit that follows (its NDFs' memory).
  double fit_cluster_fraction = 0.01;  // Of the fit that follows (1 = every point fitted directly).
  // Threads of the dot frames' Eq. 12 loop; up to two of them merge two brackets at once.
  int num_threads = DefaultThreadCount();
  bool Check(std::string* error) const;
};

// How the chain fits in the memory budget: in memory, or streamed in bands of `band_points`.
// Estimates in bytes, from the sizes of what the chain keeps (docs/benchmarks.md compares them
// with the measured peaks).
struct DmfMemoryPlan {
  bool streamed = false;
  int band_points = 0;
  double in_memory_bytes = 0;   // Estimated peak of the whole chain in memory.
  double streamed_bytes = 0;    // Estimated peak streamed, with the chosen band.
  double spill_file_bytes = 0;  // On disk when streamed.
};
// Error when even a band of one grid row does not fit the budget.
Status PlanDmfMemory(int num_points, int grid_width, int num_dots, int num_validation_dots, double camera_pixels,
                     const DmfProcessingOptions& options, DmfMemoryPlan* plan);

struct DmfProcessingReport {
  int num_dots = 0, grid_nx = 0, grid_ny = 0, num_frames = 0, num_exposures = 0;
  Rigid3d cam_from_sample;  // The camera pose the slices were rectified with.
  double dot_rms_residual_m = 0;
  // The grid-scale check of the monitor distance (DotGeometryResult): the distance error that
  // remains, its statistical sigma, the correction applied (dot_geometry.refine_distance or
  // `calib dots --refine-distance`), and MonitorDistanceWarning's text ("" = none).
  double dot_distance_error_m = 0, dot_distance_error_sigma_m = 0, dot_distance_correction_m = 0;
  std::string dot_distance_warning;
  // The longest-exposure dark frame with the sample (display black), rectified onto the sample
  // grid: its median over the grid points as a share of the camera's range, and a warning when
  // that exceeds kMaxDarkFractionOfRange. A display's black level (or ambient light) seen
  // through the sample takes that share of the range from the dots' lobes, and its shot noise
  // hides their tails, so they read narrower than they are (docs/known_gaps.md).
  double dark_exposure_us = 0, dark_fraction_of_range = 0;
  std::string dark_level_warning;
  // Does the camera apply the exposures it reports (calib/exposure_check.h)? Measured on the
  // brackets of up to kDotsExposureChecked dots spread over the scan (about as costly as their
  // merges), per exposure the factor from the dot that compared the most pixels
  // (CombineExposureChecks). Its Warning() is `exposure_warning`: Eq. 12 then scales each exposure's share of a lobe by a different wrong
  // factor (`calib hdr --exposures measured` measures the factors; docs/models/radiometric_calibration.md).
  ExposureCheck exposure_check;
  std::string exposure_warning;
  double median_dot_radiance = 0;  // L_q [DN/us].
  double glass_thickness_m = 0;    // The thickness the fit used.
  Rigid3d sample_from_monitor;     // The monitor pose the dots were placed with (refined in-plane).
  double monitor_pixel_pitch_m = 0;
  // The dot radius used and where it came from: "option", "manifest", "default" (assumed 2 px:
  // the caller warns) or the calib/rig.json that holds the dot calibration.
  double dot_radius_px = 0;
  std::string dot_radius_source;
  // Dots placed from the fitted monitor geometry instead of a centroid (outside the camera's
  // view, not found, or cut by the image border; DotRecord::placed_from_geometry), of which cut by
  // the border (DotRecord::clipped). Their L_q is the median.
  int dots_placed_from_geometry = 0, dots_clipped = 0;
  int dots_found_by_grid_prior = 0;  // Measured where the matched grid puts them (DotGeometryResult).
  int saturated_points = 0, outside_points = 0;
  double geometry_s = 0, merge_s = 0, total_s = 0;
  size_t slice_bytes = 0;  // Memory of the slice matrix (streamed: of one band).
  DmfMemoryPlan memory;    // In memory or streamed (spill file size, band).
  SessionCalibration calibration;  // What was applied.
  std::string dot_geometry_source;  // The all-dots frame used, or the rig.json file.
  CaptureCompleteness capture;      // What was read.
  FrameNoiseModel noise;            // Of the dot frames (calib/frame_noise.h), in summary.json.
};

inline constexpr double kMaxDarkFractionOfRange = 0.2;
// `fit dmf --max-memory` default (issue #29).
inline constexpr double kDefaultMaxMemoryGiB = 2.0;
inline constexpr int kDotsExposureChecked = 16;

// Dot geometry and L_q from the capture's all-dots frames without the sample (Dai et al. Sec. 4.1):
// the longest exposure with no saturated dot, else the shortest in which the dots are found
// (`response`: linearisation, nullptr = linear). *source_file: the frame used. Errors: no
// all-dots frame, no frame in which the dots are found, every dot saturated.
Status MeasureAllDotsGeometry(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                              const CameraResponse* response, const std::vector<Eigen::Vector2d>& displayed,
                              const DotGeometryOptions& options, DotGeometryResult* geometry, std::string* source_file);

Status PrepareDotScanSlices(const std::string& session_dir, const DmfProcessingOptions& options, DmfSliceSet* slices,
                            DmfProcessingReport* report);

}  // namespace thinslab
