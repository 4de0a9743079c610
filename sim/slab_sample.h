// SPDX-License-Identifier: Apache-2.0
// The sample of the simulated CRT dot rig (Dai et al. 2009, Sec. 4.1; docs/models/dot_scan_rig.md):
// a thin non-absorbing slab on the plane z = 0 of the sample frame, a rectangle divided into
// rectangular regions, each with its own rough top and bottom interface (GGX or Beckmann,
// anisotropic), index eta, diffuse term rho_d and specular scale k_s.
//
// CONVENTIONS (the fitter relies on them):
// - "top" is the face towards the monitor (z < 0 side, where the light enters); "bottom" is the
//   face towards the camera (z > 0 side).
// - Optical frame of the BTDF = sample frame rotated 180 degrees about x,
//   v_opt = (v.x, -v.y, -v.z) (ToOpticalFrame): the light direction i (from the sample point to
//   the dot) then has i_opt.z > 0 and the view direction o (to the camera) has o_opt.z < 0, as in
//   optics/dual_microfacet_btdf.h. alpha_x is along sample x, alpha_y along sample y (the
//   rotation keeps both axes up to sign, which the even NDFs ignore).
// - The measured quantity per dot is R(x, i, o) = rho_d + k_s rho(x, i, o) [1/sr] (Dai Eq. 13).
//
// The BTDF rho of a rough region is NOT the dual-microfacet formula: it is a Monte Carlo table
// from sim/rough_slab_photon_tracer.h. The slab is in air on both sides, so rho(i, o) = rho(o, i)
// (the whole air-to-air slab is reciprocal: each interface obeys f_t(i, o) / eta_o^2 =
// f_t(o, i) / eta_i^2 and the eta factors of a path cancel). The table for a region's view
// direction o is therefore traced ADJOINT: photons enter the camera-side (bottom) face from o,
// the tracer's "top" face being the region's bottom face and its "bottom" face the region's top
// face, in the sample frame itself (entry side +z), and the exit directions t (t.z < 0) are
// histogrammed on the orthographic (t.x, t.y) grid; the cell value (cell-mean BTDF, 1/sr) is
// rho(i = t, o). One view direction is traced per region (from the region centre to the camera
// centre); within a region the view direction varies by ~1 degree, which the lookups with o
// follow by shifting the table (Btdf(idx, i, o)).
// Smooth regions (every alpha < kSmoothAlpha) have no table: the camera sees the monitor straight
// through the (infinitely thin) slab, attenuated by the flat-slab transmittance with all
// internal reflections, (1 - F) / (1 + F), F the unpolarised Fresnel reflectance at the view angle.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/status.h"
#include "thinslab/sim/rough_slab_photon_tracer.h"
#include "thinslab/core/parallel.h"

namespace thinslab {

// Faces with alpha_x and alpha_y below this are flat; a region with both faces flat is smooth.
constexpr double kSmoothSlabAlpha = 0.01;

struct SlabFace {
  RoughSlabNdf ndf = RoughSlabNdf::kGgx;
  double alpha_x = 0.001;  // Along sample x, unitless [1e-3, 2].
  double alpha_y = 0.001;  // Along sample y.
  bool IsFlat() const { return alpha_x < kSmoothSlabAlpha && alpha_y < kSmoothSlabAlpha; }
};

struct SlabMaterial {
  SlabFace top;     // Towards the monitor: the light enters here.
  SlabFace bottom;  // Towards the camera.
  double eta = 1.5;  // Slab index over air, > 1.
  double rho_d = 0;  // Diffuse (multiple-scattering) BTDF [1/sr], added as a constant (Dai Eq. 13).
  double k_s = 1;    // Scale of the refractive BTDF (Dai Eq. 13).
  bool IsSmooth() const { return top.IsFlat() && bottom.IsFlat(); }
};

struct SlabRegion {
  std::string name;
  Eigen::Vector2d min_m = Eigen::Vector2d::Zero();  // Rectangle on the sample, sample-frame metres.
  Eigen::Vector2d max_m = Eigen::Vector2d::Zero();
  SlabMaterial material;
  Eigen::Vector2d Centre() const { return 0.5 * (min_m + max_m); }
};

struct SlabSampleOptions {
  // The sample rectangle on z = 0 (default 0.08 m x 0.08 m centred at the origin).
  Eigen::Vector2d min_m = Eigen::Vector2d(-0.04, -0.04);
  Eigen::Vector2d max_m = Eigen::Vector2d(0.04, 0.04);
  // Regions; they must tile the rectangle exactly (inside it, no overlaps, areas summing to it).
  // Empty = DefaultSlabRegions(min_m, max_m).
  std::vector<SlabRegion> regions;
  int64_t photons_per_region = 400000;  // Photons traced per rough region.
  // Slab thickness [m]: the camera-side face is z = 0, the monitor-side face z = -thickness. The
  // BTDF tables are the infinitely thin slab's; the thickness moves where each dot's light
  // enters (SlabSample::LightEntryPoint). Smooth regions' direct view is not displaced.
  double thickness_m = 0;
  int table_bins = 64;                  // N x N cells of the orthographic exit-direction table.
  int max_interactions = 64;
  int num_threads = DefaultThreadCount();  // Regions traced in parallel (each has its own seed: deterministic).
  uint64_t seed = 1;

  Status Check() const;  // Errors name SlabSampleOptions::<field> (and the region).
};

// The default preset: a 3 x 3 grid over [min_m, max_m], row-major from (min x, min y):
//   ggx_top (GGX 0.3 top, flat bottom), ggx_bottom (flat top, GGX 0.3 bottom),
//   ggx_both (GGX 0.2 / 0.2), beckmann_top (Beckmann 0.3 top), beckmann_both (Beckmann 0.2 / 0.2),
//   ggx_aniso_top (GGX 0.15 x 0.4 top), smooth (0.001 both), diffuse (GGX 0.25 top,
//   rho_d 0.05 /sr, k_s 0.8), ggx_mixed (GGX 0.1 top, 0.3 bottom); eta 1.5 everywhere.
std::vector<SlabRegion> DefaultSlabRegions(const Eigen::Vector2d& min_m, const Eigen::Vector2d& max_m);

// Monte Carlo BTDF of one region for its traced view direction.
struct SlabBtdfTable {
  Eigen::Vector3d view_direction = Eigen::Vector3d::UnitZ();  // o, sample frame (o.z > 0).
  int bins = 0;
  // Cell-mean BTDF [1/sr] rho(i, o), i in the sample frame (i.z < 0): cell (row, col) at
  // row * bins + col covers i.x in [-1 + col h, -1 + (col + 1) h), i.y likewise along row,
  // h = 2 / bins.
  std::vector<float> rho;
  std::vector<float> std_error;  // Poisson standard error of each cell [1/sr].
  // Where the light of a cell's direction entered the monitor-side face, relative to where it
  // leaves the camera-side face, per unit slab thickness. The light that crossed the slab once:
  // its cell mean offset (the table's mean where the cell has none) and its share of the cell's
  // light. The rest (internal reflections, a few %) spreads over tens of thicknesses: it enters
  // at kMultipleParts offsets, the means of equal-count slices of all its photons sorted by the
  // offset's length, each with an equal part of the rest of the cell's light.
  static constexpr int kMultipleParts = 4;
  std::vector<Eigen::Vector2f> offset_once;
  std::vector<float> share_once;
  Eigen::Vector2f offset_multiple[kMultipleParts];
  double transmitted = 0, reflected = 0, masked = 0, capped = 0;  // Tracer fractions.
  int64_t photons = 0;
  uint64_t seed = 0;

  // Bilinear interpolation between cell centres (clamped at the grid border) at (i.x, i.y);
  // 0 for i.z >= 0.
  double Eval(const Eigen::Vector3d& i_sample) const;
};

class SlabSample {
 public:
  // Validates, then traces one table per rough region for the view direction from the region
  // centre to `camera_centre_in_sample`.
  static Status Create(const SlabSampleOptions& options, const Eigen::Vector3d& camera_centre_in_sample,
                       std::unique_ptr<SlabSample>* out);

  const SlabSampleOptions& options() const { return options_; }
  int num_regions() const { return static_cast<int>(options_.regions.size()); }
  const SlabRegion& region(int idx) const { return options_.regions[idx]; }
  bool Contains(const Eigen::Vector2d& x_m) const;
  // Index of the region containing sample point x (half-open rectangles [min, max)), -1 outside.
  int RegionIndexAt(const Eigen::Vector2d& x_m) const;
  // The region material at x; nullptr outside the sample.
  const SlabMaterial* MaterialAt(const Eigen::Vector2d& x_m) const;
  // Traced view direction of region idx (sample frame, towards the camera).
  const Eigen::Vector3d& ViewDirection(int idx) const { return view_directions_[idx]; }
  // Table of region idx; nullptr for smooth regions.
  const SlabBtdfTable* table(int idx) const { return tables_[idx].get(); }
  // rho(x, i, o) [1/sr] of region idx at its traced o, without rho_d and k_s; i in the sample
  // frame, unit, pointing from the sample to the light (i.z < 0). 0 for smooth regions.
  double Btdf(int idx, const Eigen::Vector3d& i_sample) const;
  // Where part `part` of the light that leaves the camera-side face at x (z = 0) towards o
  // entered the monitor-side face, coming from direction i (sample frame, i.z < 0), and that
  // part's share of the (i, o) cell's light: part 0 crossed the slab once, parts 1..
  // kMultipleParts several times (SlabBtdfTable). x plus the thickness times the part's offset,
  // at z = -thickness. x and share 1 for part 0 (0 for the rest) of smooth regions or a zero
  // thickness.
  static constexpr int kEntryParts = 1 + SlabBtdfTable::kMultipleParts;
  Eigen::Vector3d LightEntryPoint(int idx, const Eigen::Vector3d& x, const Eigen::Vector3d& i_sample,
                                  const Eigen::Vector3d& o_sample, int part, double* share) const;
  // R = rho_d + k_s rho (Dai Eq. 13) [1/sr].
  double Transmission(int idx, const Eigen::Vector3d& i_sample) const;
  // The same at view direction o (sample frame, unit, towards the camera): the table looked up
  // at i shifted by the change of view in projected coordinates, i_xy + (o_xy - o_c,xy), o_c the
  // traced ViewDirection(idx). A thin slab with parallel faces transmits straight through at
  // i = -o, so its lobe moves with the view; the change of the lobe's shape over the ~1.5 degrees
  // the view varies across a region is second order. Without the shift every point of a region
  // would show the lobe of the region centre, displaced by up to ~1 degree from where the point's
  // own view puts it (a per-point model error of ~4 % RMS that only a free-form NDF can absorb).
  double Btdf(int idx, const Eigen::Vector3d& i_sample, const Eigen::Vector3d& o_sample) const;
  double Transmission(int idx, const Eigen::Vector3d& i_sample, const Eigen::Vector3d& o_sample) const;
  double tracing_seconds() const { return tracing_seconds_; }

  // Transmittance of a flat non-absorbing slab with all internal reflections (incoherent):
  // (1 - F) / (1 + F), F = unpolarised Fresnel reflectance at |cos_theta| (optics/fresnel.h).
  static double FlatSlabTransmittance(double cos_theta, double eta);
  static Eigen::Vector3d ToOpticalFrame(const Eigen::Vector3d& v_sample) {
    return Eigen::Vector3d(v_sample.x(), -v_sample.y(), -v_sample.z());
  }

 private:
  SlabSample() = default;
  SlabSampleOptions options_;
  std::vector<Eigen::Vector3d> view_directions_;
  std::vector<std::unique_ptr<SlabBtdfTable>> tables_;
  double tracing_seconds_ = 0;
};

}  // namespace thinslab
