// SPDX-License-Identifier: Apache-2.0
// CRT/monitor dot geometry (Dai et al. 2009, Section 4.1): "Dot positions are determined by
// capturing an image without the material sample. The dots are displayed simultaneously,
// detected in the image, and then projected to the 3D plane (x, y, d)." and "The color and
// intensity of the monitor is measured by directly capturing its output" (L_q in Eq. 12).
//
// Steps:
//  1. the nominal geometry's scale: how a monitor pixel maps into the image at the grid's centre
//     (a dot's image size, the dots' spacing in the image);
//  2. a local background (grey opening of the frame with a window larger than a dot's image, so
//     a frame mostly lit by a dense grid keeps its gaps as background) and the noise from
//     differences of neighbouring dark pixels;
//  3. dots as local maxima of the frame smoothed by a kernel shaped like a dot's image (a convex
//     disc blurred by a Gaussian is unimodal, so touching dots keep separate maxima), one per
//     displayed spacing;
//  4. intensity-weighted sub-pixel centroids and fluxes over a window around each dot, pixels
//     shared by neighbouring windows split by the nearest dot;
//  5. matching to the displayed grid by a homography (monitor px -> undistorted image) fitted
//     with RANSAC, seeded both from the nominal rig geometry and from the four corners of the
//     dots' convex hull (the better hypothesis wins);
//  6. the grid as a prior: every displayed dot the homography puts inside the frame is measured
//     at its predicted place (windows split among all dots, found or not), so a dot missed by
//     step 3 is refined, not lost;
//  7. back-projection of each centroid's camera ray to the monitor plane (3D position in the
//     sample frame); the dot's radiance as its integrated signal divided by its projected area;
//     residuals against the displayed grid after a fitted in-plane rigid correction of the
//     monitor pose. Dots outside the view, not found or cut by the border are placed from it.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct DotGeometryOptions {
  double dot_radius_px = 2.0;        // Radius of a displayed dot, monitor px (window sizes, L_q's area).
  // Detection (issue #23: dense grids whose all-dots frame is mostly lit, dots 1.3 diameters
  // apart that touch in the image). A dot is a local maximum of the frame smoothed by a kernel
  // shaped like a dot's image, above a local background, at least
  double threshold_sigma = 8;        // this many noise sigmas above the background,
  double threshold_fraction = 0.25;  // this fraction of the brightest dot's height,
  double min_peak_fraction = 0.2;    // and this fraction of the median dot's height;
  int min_blob_area_px = 2;          // with at least this many (smoothed) pixels above the threshold.
  // Two maxima closer than this fraction of the displayed dots' spacing (measured on the screen,
  // through the nominal geometry) are one dot.
  double peak_separation_fraction = 0.45;
  int window_margin_px = 3;          // Centroid/flux window: a dot's image radius plus this.
  // Side of the local background's window [camera px]; 0 = twice the window's half-size plus 1.
  int background_window_px = 0;
  double match_gate_fraction = 0.35; // Match radius as a fraction of the local dot spacing in the image.
  // Move the monitor plane along its normal until the back-projected grid has the displayed
  // pitch (DotGeometryResult::grid_scale 1): measures d from the one all-dots view, to the
  // precision the camera calibration allows (docs/models/geometric_calibration.md, 3.7). Off by
  // default: with d measured to better than that, the manifest's d is the better value.
  bool refine_distance = false;
  Status Check() const;
};

struct DotRecord {
  Eigen::Vector2d dot_px = Eigen::Vector2d::Zero();  // Displayed position, monitor px (centres +0.5).
  bool detected = false;
  Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();  // Camera image, thinslab px.
  Eigen::Vector3d position_in_sample_m = Eigen::Vector3d::Zero();  // Back-projected onto the monitor plane.
  // L_q: mean radiance over the dot in camera units, i.e. DN/us that a camera pixel entirely
  // covered by the dot would record (black level and background removed).
  double radiance_dn_per_us = 0;
  bool saturated = false;  // Some pixel of the dot reached saturation_dn: radiance unusable.
  // Found, but its window reaches the image border: its centroid and flux are cut, so it enters
  // no estimate (pose correction, grid scale, L_q) and is placed from the geometry.
  bool clipped = false;
  // Position from the fitted monitor geometry (sample_from_monitor and the displayed position),
  // not from a centroid: dots outside the camera's view, not found, or clipped. Such a dot's
  // L_q is the median of the measured ones (issue #23).
  bool placed_from_geometry = false;
  double residual_m = 0;   // |position - fitted grid position| on the monitor plane.
  // Centroid and L_q of this dot can be used.
  bool measured() const { return detected && !clipped; }
};

struct DotGeometryResult {
  std::vector<DotRecord> dots;          // One per displayed dot, in display order.
  Rigid3d sample_from_monitor;          // Nominal monitor pose refined in-plane (rotation about the
                                        // monitor normal and translation in the plane).
  double rms_residual_m = 0, max_residual_m = 0;
  double in_plane_correction_m = 0;     // Size of the in-plane shift applied to the nominal pose.
  double in_plane_correction_rad = 0;
  double homography_rms_px = 0;         // Fit of the matched centroids by the grid homography.
  // The grid's scale on the plane: back-projected spacing / displayed spacing (least squares).
  double grid_scale = 1;
  // How much further from the camera the plane used is than the one the grid's scale says,
  // h (1 - 1/grid_scale) along the plane normal [m] (> 0: the monitor distance d is too large),
  // and its statistical sigma (residual scatter only; the camera calibration adds a systematic
  // part). Without refine_distance: of the manifest's plane; with it: what remains (~0).
  double distance_error_m = 0, distance_error_sigma_m = 0;
  double camera_to_plane_m = 0;     // h: the camera centre's distance to the plane used.
  double distance_correction_m = 0; // refine_distance: how far the plane was moved (> 0: towards the camera).
  int num_blobs = 0, num_matched = 0, num_unmatched_blobs = 0;
  int num_clipped = 0;  // Matched dots cut by the image border (DotRecord::clipped).
  // Dots the local maxima missed but measured where the matched grid puts them (step 6).
  int num_found_by_grid_prior = 0;
  double background_dn_per_us = 0, noise_dn_per_us = 0;  // Median local background; its noise.
};

// `frame_dn`: the all-dots frame in DN with the black level already removed (session_io
// LoadFrame), `exposure_us` its exposure, `raw_saturation_dn` the saturation threshold in the
// same units (saturation_dn - black_level_dn). `camera` carries intrinsics, distortion and
// cam_from_sample; `monitor` the nominal monitor geometry; `displayed_dots_px` the grid shown.
Status CalibrateDotGeometry(const Image& frame_dn, double exposure_us, double saturation_dn, const CameraInfo& camera,
                            const MonitorInfo& monitor, const std::vector<Eigen::Vector2d>& displayed_dots_px,
                            const DotGeometryOptions& options, DotGeometryResult* result);

// Non-empty when the grid's scale says the monitor plane used is off by more than a single view
// measures: |distance_error_m| above kMonitorDistanceWarningM and 5 statistical sigmas. Names
// the amount and the way on (--refine-distance, `fit dmf --refine-monitor-distance`).
// kMonitorDistanceWarningM is 5x the systematic error the grid scale showed through a chessboard-
// calibrated camera (0.046 mm; calib/dot_geometry_test, WholeCalibrationChainFromChessboardViews).
inline constexpr double kMonitorDistanceWarningM = 0.25e-3;
std::string MonitorDistanceWarning(double distance_error_m, double distance_error_sigma_m);

// The radius of the displayed dots [monitor px]: `option_px` when > 0 (--dot-radius-px), else the
// manifest's rig.monitor.dot_radius_px (format 1.4), else kDefaultDotRadiusPx. `*source` says
// which ("option", "manifest", "default"); with "default" the caller warns (L_q and the A of Eq.
// 12 scale with the radius squared, their product with the radius not at all, so a wrong radius
// only shows in the radiance values and their saturation checks).
inline constexpr double kDefaultDotRadiusPx = 2.0;
double ResolveDotRadiusPx(double option_px, const MonitorInfo& monitor, std::string* source);

// Point where the camera ray through thinslab pixel `pixel` meets the monitor plane, sample
// frame. False if the ray is parallel to the plane or the plane is behind the camera.
bool BackProjectToMonitor(const CameraInfo& camera, const Rigid3d& sample_from_monitor, const Eigen::Vector2d& pixel,
                          Eigen::Vector3d* x_in_sample);

}  // namespace thinslab
