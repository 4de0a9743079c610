// SPDX-License-Identifier: Apache-2.0
// Spatially varying dual-microfacet fit (Dai et al. 2009, Sec. 4): every point of the sample
// grid has a BTDF slice (Eq. 12 values for the dots of the scan); the map fit separates the
// diffuse term (Eq. 14), fits the dual-microfacet model per point (fit/dmf_point_fit.h), either
// for every point or for k-means representatives with Eq. 20-22 interpolation for the rest
// (fit/dmf_clustering.h), and gathers maps and per-stage timings.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/pixel_trace.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_clustering.h"
#include "thinslab/fit/dmf_point_fit.h"
#include "thinslab/fit/dmf_slice_spill.h"

namespace thinslab {

// Where the light seen at sample point x (on z = 0, seen from `camera_centre`) entered a slab of
// `thickness` and index `eta` (issue #23 section 5): the camera's ray refracted at the flat mean
// surface, followed down to the monitor-side face, x + t (d_xy / |d_z|) at z = -t; the specular
// path, which the lobe's peak follows whatever the roughness (docs/models/dual_microfacet_fit.md,
// "Slab thickness"). x itself when the thickness is 0.
Eigen::Vector3d SlabLightEntryPoint(const Eigen::Vector3d& x, const Eigen::Vector3d& camera_centre, double thickness,
                                    double eta);

// Eq. 12 measurements of the capture's validation dots (FrameRecord::validation: any dot
// position, never fitted), point-major as DmfSliceSet::value (value[p * num_dots() + v]).
struct DmfValidationDots {
  std::vector<Eigen::Vector2d> dot_px;          // Displayed positions [monitor px].
  std::vector<Eigen::Vector3d> positions;       // p_v from the fitted monitor geometry [m].
  std::vector<float> value, sigma;              // R [1/sr] and its standard deviation.
  int num_dots() const { return static_cast<int>(positions.size()); }
};

// Eq. 12 measurements of a whole sample grid, in the sample frame of docs/conventions.md
// (monitor at z = -d, camera on +z). Point p = (col, row) sits at
// grid_min_m + ((col + 0.5), (row + 0.5)) * pitch_m on z = 0.
struct DmfSliceSet {
  int width = 0, height = 0;
  Eigen::Vector2d grid_min_m = Eigen::Vector2d::Zero();
  double pitch_m = 0;
  int dots_nx = 0, dots_ny = 0;                 // Dot grid, row-major (x fastest).
  std::vector<Eigen::Vector3d> dot_positions;   // p_q, sample frame [m].
  double dot_cell_area_m2 = 0;                  // Monitor area per dot of the grid (for d omega).
  Eigen::Vector3d camera_centre = Eigen::Vector3d::Zero();  // Sample frame [m].
  // The slab: z = 0 is the face the camera sees, the light enters the face at z = -thickness.
  double glass_thickness_m = 0;
  double eta = 1.5;
  std::vector<float> value;   // R [1/sr], point-major: value[p * num_dots + q].
  std::vector<float> sigma;   // Its standard deviation, same layout (empty: unknown).
  // Set when the matrix is on disk (issue #29, over the memory budget): `value` and `sigma`
  // are empty and only the band of points the spill has loaded can be read
  // (ForEachPointBand; PointValues and Slice CHECK it).
  std::shared_ptr<DmfSliceSpill> spill;
  std::vector<uint8_t> train; // Per dot: 1 fitted, 0 held out.
  std::vector<uint8_t> point_status;  // Per point: DmfStatus from processing (kOk to fit).
  DmfValidationDots validation;       // Empty when the capture has no validation dot frames.

  int num_points() const { return width * height; }
  int num_dots() const { return static_cast<int>(dot_positions.size()); }
  // Point p's num_dots() values and sigmas (sigmas nullptr when unknown).
  const float* PointValues(int p) const;
  const float* PointSigmas(int p) const;
  Eigen::Vector3d PointPosition(int p) const;
  // SlabLightEntryPoint of point p.
  Eigen::Vector3d LightEntryPoint(int p) const;
  // Slice of point p in the optical frame (light side +z), rho_d by Eq. 14.
  DmfSlice Slice(int p) const;
  Status Check() const;
};

// body(first, count) for consecutive bands of points that together cover the grid: the whole
// grid at once when the slices are in memory, else each band loaded from the spill in turn
// (points outside the band cannot be read during its call). Stops at the first error.
Status ForEachPointBand(const DmfSliceSet& slices, const std::function<Status(int first, int count)>& body);

// The sample frame -> optical frame of optics/dual_microfacet_btdf.h: the 180-degree rotation
// about x, so that light from the monitor (z < 0) arrives from +z and the camera lies on -z.
inline Eigen::Vector3d SampleToOptical(const Eigen::Vector3d& v) { return Eigen::Vector3d(v.x(), -v.y(), -v.z()); }

// Which dots of the nx x ny grid a fit holds out to score its predictions (issue #23 section 4).
struct HoldOutPattern {
  // "checkerboard": (ix + iy) odd, every held-out dot between four fitted ones (interpolation);
  // "random": each dot with probability `fraction`, drawn from `seed`; "blocks": block x block
  // tiles of dots in a checkerboard of tiles, held-out dots up to block / 2 steps from a fitted
  // one (extrapolation, where a model's lobe shape matters most).
  std::string kind = "checkerboard";
  double fraction = 0.5;
  int block = 3;
  uint64_t seed = 1;
  bool Check(std::string* error) const;
};

// Half `half` (0 or 1) of the training dots of `train` (nx x ny grid, row-major): every other
// training dot along each row, so each half spans the whole monitor.
std::vector<uint8_t> SplitTrainingHalf(const std::vector<uint8_t>& train, int nx, int half);

// Error bars of alpha and the equivalent roughness from the split-half refits: the difference d
// of the two halves' estimates has variance 2 sigma_half^2 = 4 sigma^2 (a half has half the dots),
// so sigma^2 = d^2 / 4, pooled over the `min_samples` nearest split-fitted points of the map
// (one difference alone is a one-degree-of-freedom estimate: an error bar from it covers the
// error only half the time however right its expectation). The roughness's adds, in quadrature,
// half the difference of the point's GGX and Beckmann fits (the model-form part). Sets
// sigma_alpha and sigma_roughness of every point with an NDF; points beyond `max_radius` map
// pixels of any split-fitted point keep 0. Neither term sees a bias common to both halves
// (docs/stability.md, "Dual-microfacet alpha and equivalent roughness").
void PoolSplitHalfSigmas(int width, int height, int num_threads, std::vector<DmfPointFit>* fits, int min_samples = 8,
                         int max_radius = 16);

// 1 = fitted, 0 = held out: all 1 without `hold_out`, else `pattern`.
std::vector<uint8_t> HoldOutTrainMask(int nx, int ny, bool hold_out, const HoldOutPattern& pattern);

struct DmfMapFitOptions {
  DmfPointFitOptions point;
  bool cluster = true;
  DmfClusteringOptions clustering;
  // Also fit every directly fitted point from each half of its training dots (alternate training
  // dots along each dot row) for the noise part of the error bars of alpha and roughness.
  bool split_half = true;
  int num_threads = DefaultThreadCount();
  // Reports the per-point fits; returning false cancels the fit (core/progress.h).
  ProgressCallback progress;
  // One map point's measurements, iterations and result (`fit dmf --pixel X,Y`).
  PixelTrace trace;
  bool Check(std::string* error) const;
};

struct DmfMapTimings {
  double diffuse_s = 0, clustering_s = 0, representative_fit_s = 0, interpolation_s = 0, total_s = 0;
};

struct DmfMaps {
  int width = 0, height = 0, ndf_resolution = 0;
  double eta = 1.5;  // Slab index the maps were fitted with.
  std::vector<DmfPointFit> fits;  // One per point (log_ndf empty where nothing was fitted).
  int num_fitted = 0;             // Points fitted directly (representatives or all).
  DmfClustering clustering;       // Empty unless clustered.
  // D_j = exp(ln D_j) of every representative (clustering.representatives order, N*N cells each)
  // with a fitted NDF and k_s > 0, the terms of Eq. 20: computed once (CacheRepresentativeNdfs),
  // where every interpolated NDF took N*N exponentials per neighbour each time it was rebuilt
  // (about 20 % of the paper's workload). Empty: not cached, FitWithNdf exponentiates.
  std::vector<double> representative_ndf;
  DmfMapTimings timings;
  // Fills representative_ndf from the representatives' fits (on num_threads threads).
  void CacheRepresentativeNdfs(int num_threads);
  // Point p's fit with its log_ndf filled in (a copy): a fit that streamed its slices (issue #29)
  // keeps no log_ndf (N*N doubles each) for interpolated points (DmfPointFit::ndf_interpolated)
  // and this rebuilds it from the representatives.
  DmfPointFit FitWithNdf(int p) const;
  // Channels top_face_weight (Dai's alpha), smith_alpha, k_s, rho_d, log_rms_residual (ln RMS of
  // Eq. 15), status, measured_ndf_fraction, transmittance, equivalent_roughness, ndf_family
  // (NdfFamily code), rough_face (RoughFace code of alpha); finite everywhere (defaults where
  // status says nothing was fitted: roughness 0, family undecided, rough face both).
  Image ToImage(const EquivalentRoughnessOptions& roughness_options = EquivalentRoughnessOptions()) const;
};

// Streams the slices band by band when they are spilled (DmfSliceSet::spill): the same maps
// as in memory.
Status FitDualMicrofacetMaps(const DmfSliceSet& slices, const DmfMapFitOptions& options, DmfMaps* maps);

// Loads point p alone from the spill (a band of one point: one small read per dot, where its
// whole band took seconds at the paper's size); nothing when the slices are in memory.
Status LoadPoint(const DmfSliceSet& slices, int p);

// Relative RMS error over the held-out in-lobe dots of point p (HeldOutRelativeRms), -1 if none;
// p must be loaded (ForEachPointBand).
double DmfHeldOutError(const DmfSliceSet& slices, const DmfMaps& maps, int p, double lobe_fraction = 0.1);

}  // namespace thinslab
