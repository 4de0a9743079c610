// SPDX-License-Identifier: Apache-2.0
// FitDualMicrofacetPoint on BTDF slices measured by Monte Carlo photon tracing through a slab
// with two rough GGX faces (sim/rough_slab_photon_tracer.h: all internal bounces, Fresnel,
// Smith masking), never by the dual-microfacet formula, with noise and a dot grid as on the
// rig of Dai et al. Sec. 4.1.
#include "thinslab/fit/dmf_point_fit.h"

#include <gtest/gtest.h>

#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/sim/rough_slab_photon_tracer.h"

namespace thinslab {
namespace {

// Optical frame <-> the photon tracer's frame when photons enter from the camera side: the
// 180-degree rotation about x (an involution that keeps aligned anisotropic NDFs unchanged).
Eigen::Vector3d FlipAboutX(const Eigen::Vector3d& v) { return Eigen::Vector3d(v.x(), -v.y(), -v.z()); }

struct SliceCase {
  double alpha_top, alpha_bottom;  // GGX roughness of the light-side and camera-side faces.
};

// The slice R(i_q, o) at the sample centre of a 40 mm monitor distance rig with the camera 45
// degrees from the normal, an n x n dot grid, 2 % noise; every other dot held out.
DmfSlice MeasureSlice(const SliceCase& c, int n_dots, uint64_t seed, RoughSlabPhotonTracerResult* table_out = nullptr) {
  const double d = 0.04;
  const double theta = 45 * kPi / 180;
  // Sample frame: camera on +z, monitor at z = -d; optical frame: rotated about x.
  const Eigen::Vector3d o_sample(0, -std::sin(theta), std::cos(theta));
  const Eigen::Vector3d o = FlipAboutX(o_sample);
  // By reciprocity (air on both sides), rho(i, o) as a function of i is the exit histogram of
  // photons entering the camera-side face from o.
  RoughSlabPhotonTracerOptions tracer;
  tracer.eta = 1.5;
  tracer.alpha_top = c.alpha_bottom;
  tracer.alpha_bottom = c.alpha_top;
  tracer.wi = FlipAboutX(o);
  tracer.num_photons = 3000000;
  tracer.num_bins = 128;
  tracer.seed = seed;
  const RoughSlabPhotonTracerResult table = TraceRoughSlab(tracer);
  if (table_out) *table_out = table;

  DmfSlice slice;
  slice.o = o;
  std::mt19937_64 rng(seed + 7);
  std::normal_distribution<double> gauss;
  const double span = 0.12, pitch = span / (n_dots - 1);
  for (int iy = 0; iy < n_dots; ++iy) {
    for (int ix = 0; ix < n_dots; ++ix) {
      const Eigen::Vector3d p(-span / 2 + ix * pitch, d - span / 2 + iy * pitch, -d);
      const double r = p.norm();
      const Eigen::Vector3d i = FlipAboutX(p / r);
      const Eigen::Vector3d t = FlipAboutX(i);  // Exit direction in the tracer frame.
      const int col = std::min(table.num_bins - 1, static_cast<int>((t.x() + 1) / table.CellWidth()));
      const int row = std::min(table.num_bins - 1, static_cast<int>((t.y() + 1) / table.CellWidth()));
      const double rho = table.Btdf(row, col);
      const double sigma = 0.02 * rho + 1e-3;
      slice.i.push_back(i);
      slice.value.push_back(std::max(0.0, rho + sigma * gauss(rng)));
      slice.sigma.push_back(sigma);
      slice.solid_angle.push_back(pitch * pitch * (d / r) / (r * r));
      slice.train.push_back((ix + iy) % 2 == 0);
    }
  }
  slice.rho_d = EstimateDiffuse(slice, n_dots, n_dots);
  return slice;
}

// Relative L2 distance between the fitted NDF and a GGX of roughness alpha over the disk.
double NdfRelativeL2(const DmfPointFit& fit, const DmfNdfGrid& grid, double alpha) {
  const GgxDistribution truth(alpha);
  double num = 0, den = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (!grid.InDisk(cell)) continue;
    const double x = grid.CellCentre(cell % grid.n()), y = grid.CellCentre(cell / grid.n());
    const Eigen::Vector3d m(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y)));
    const double t = truth.D(m), f = std::exp(fit.log_ndf[cell]);
    num += Sqr(f - t);
    den += t * t;
  }
  return std::sqrt(num / den);
}

TEST(DmfPointFit, RoughTopGivesHighAlphaAndTheTopNdf) {
  const DmfNdfGrid grid(32);
  DmfPointFitOptions options;
  const DmfSlice slice = MeasureSlice({0.3, 0.001}, 24, 11);
  const DmfPointFit fit = FitDualMicrofacetPoint(slice, grid, options);
  const double ndf_error = NdfRelativeL2(fit, grid, 0.3);
  const double held_out = HeldOutRelativeRms(slice, 0.1, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
    return PredictDualMicrofacet(fit, grid, options.eta, i, o);
  });
  std::printf("rough top: alpha %.3f smith %.3f k_s %.3f iterations %d ndf L2 %.3f held-out rms %.3f\n", fit.alpha,
              fit.smith_alpha, fit.k_s, fit.alpha_iterations, ndf_error, held_out);
  EXPECT_EQ(fit.status, DmfStatus::kOk);
  EXPECT_GE(fit.alpha, 0.8);
  EXPECT_LT(ndf_error, 0.25);
  EXPECT_GT(held_out, 0);
  EXPECT_LT(held_out, 0.15);
}

TEST(DmfPointFit, RoughBottomGivesLowAlphaAndTheBottomNdf) {
  const DmfNdfGrid grid(32);
  DmfPointFitOptions options;
  const DmfSlice slice = MeasureSlice({0.001, 0.3}, 24, 12);
  const DmfPointFit fit = FitDualMicrofacetPoint(slice, grid, options);
  const double ndf_error = NdfRelativeL2(fit, grid, 0.3);
  const double held_out = HeldOutRelativeRms(slice, 0.1, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
    return PredictDualMicrofacet(fit, grid, options.eta, i, o);
  });
  std::printf("rough bottom: alpha %.3f smith %.3f k_s %.3f iterations %d ndf L2 %.3f held-out rms %.3f\n", fit.alpha,
              fit.smith_alpha, fit.k_s, fit.alpha_iterations, ndf_error, held_out);
  EXPECT_EQ(fit.status, DmfStatus::kOk);
  EXPECT_LE(fit.alpha, 0.2);
  EXPECT_LT(ndf_error, 0.25);
  EXPECT_LT(held_out, 0.15);
}

TEST(DmfPointFit, TwoSidedRoughPredictsHeldOutDots) {
  const DmfNdfGrid grid(32);
  DmfPointFitOptions options;
  const DmfSlice slice = MeasureSlice({0.2, 0.2}, 24, 13);
  const DmfPointFit fit = FitDualMicrofacetPoint(slice, grid, options);
  const double held_out = HeldOutRelativeRms(slice, 0.1, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
    return PredictDualMicrofacet(fit, grid, options.eta, i, o);
  });
  std::printf("two-sided: alpha %.3f smith %.3f k_s %.3f iterations %d held-out rms %.3f\n", fit.alpha,
              fit.smith_alpha, fit.k_s, fit.alpha_iterations, held_out);
  EXPECT_EQ(fit.status, DmfStatus::kOk);
  EXPECT_GT(fit.alpha, 0.2);
  EXPECT_LT(fit.alpha, 0.8);
  EXPECT_LT(held_out, 0.15);
}

TEST(DmfPointFit, NoLightGivesNoLobeStatusAndNoNan) {
  const DmfNdfGrid grid(16);
  DmfPointFitOptions options;
  options.ndf_resolution = 16;
  DmfSlice slice = MeasureSlice({0.3, 0.001}, 8, 14);
  for (double& v : slice.value) v = 0;
  const DmfPointFit fit = FitDualMicrofacetPoint(slice, grid, options);
  EXPECT_EQ(fit.status, DmfStatus::kNoLobe);
  EXPECT_TRUE(std::isfinite(fit.alpha));
  EXPECT_TRUE(std::isfinite(PredictDualMicrofacet(fit, grid, 1.5, slice.i[0], slice.o)));
}

}  // namespace
}  // namespace thinslab
