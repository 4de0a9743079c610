// SPDX-License-Identifier: Apache-2.0
// `thinslab preview` of a dual-microfacet fit (export/slab_preview.h): laws of the rendering on
// fits made here with GGX NDFs on Dai's grid (a smooth and a rough region, a point without a fit):
// under a uniform backlight each point shows its directional transmittance (at most clean glass's,
// the quadrature converged); over a checkerboard the contrast falls with roughness from clean
// glass's (nearly smooth) to none (alpha 0.5); an unfitted point is clean glass.
#include "thinslab/export/slab_preview.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/export/preview_run.h"
#include "thinslab/fit/dmf_ndf_grid.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

constexpr int kResolution = 32;
constexpr int kPoints = 40;  // Along x, 0.1 mm apart: 4 checker squares of 1 mm.
constexpr double kPitchM = 1e-4;

DmfPointFit GgxPoint(double alpha) {
  const DmfNdfGrid grid(kResolution);
  const GgxDistributionT<double> ggx(alpha);
  DmfPointFit f;
  f.status = DmfStatus::kOk;
  f.alpha = 1;  // Rough on the monitor side only.
  f.smith_alpha = alpha;
  f.k_s = 1;
  f.rho_d = 0;
  f.log_ndf.assign(grid.num_cells(), DmfNdfGrid::kLogEpsilon);
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (grid.unknown(cell) < 0) continue;
    const double x = grid.CellCentre(cell % kResolution), y = grid.CellCentre(cell / kResolution);
    const Eigen::Vector3d h(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y)));
    f.log_ndf[cell] = std::log(std::max(1e-300, ggx.D(h)));
  }
  const double norm = std::log(grid.ProjectedIntegral(f.log_ndf));
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (grid.unknown(cell) >= 0) f.log_ndf[cell] -= norm;
  }
  return f;
}

// Row 0: smooth (alpha 0.1), row 1: rough (0.5), row 2: no fit.
DmfFitOnDisk ThreeRegionFit() {
  DmfFitOnDisk fit;
  fit.maps.width = kPoints;
  fit.maps.height = 3;
  fit.maps.ndf_resolution = kResolution;
  fit.maps.eta = 1.5;
  fit.pitch_m = kPitchM;
  fit.grid_min_m = Eigen::Vector2d(0, 0.25e-3);  // Inside one checker row.
  const DmfPointFit smooth = GgxPoint(0.1), rough = GgxPoint(0.5);
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < kPoints; ++col) {
      fit.maps.fits.push_back(row == 0 ? smooth : row == 1 ? rough : DmfPointFit());
    }
  }
  return fit;
}

// Contrast (std / mean) of channel `channel` along row `row`.
double RowContrast(const Image& view, int channel, int row) {
  Image one(view.width(), 1, {"v", "mask"});
  for (int x = 0; x < view.width(); ++x) {
    one.at(x, 0, 0) = view.at(x, row, channel);
    one.at(x, 0, 1) = 1;
  }
  return CheckerContrast(one, 0, 1);
}

TEST(SlabPreview, UniformBacklightShowsEachPointsTransmittanceAtMostCleanGlasssAndConverged) {
  const DmfFitOnDisk fit = ThreeRegionFit();
  SlabPreviewOptions options;
  options.dark_square = 1;  // Uniform.
  Image coarse, fine;
  ASSERT_TRUE(RenderSlabPreview(fit, options, &coarse).ok());
  options.directions = 96;
  ASSERT_TRUE(RenderSlabPreview(fit, options, &fine).ok());
  const double clean = coarse.at(0, 0, 1);
  EXPECT_NEAR(clean, Sqr(1 - 0.04), 1e-6);  // Two faces of eta 1.5 at normal incidence.
  for (int row = 0; row < 2; ++row) {
    const double t = coarse.at(kPoints / 2, row, 0);
    EXPECT_GT(t, 0.5 * clean) << "row " << row;
    EXPECT_LT(t, 1.02 * clean) << "row " << row;  // A rough slab transmits no more than clean glass.
    EXPECT_NEAR(fine.at(kPoints / 2, row, 0), t, 0.03 * t) << "row " << row << ": quadrature not converged";
  }
  EXPECT_EQ(coarse.at(0, 2, 0), coarse.at(0, 2, 1));  // No fit: clean glass.
  EXPECT_EQ(coarse.at(0, 2, 2), 0.0f);
  EXPECT_EQ(coarse.at(0, 0, 2), 1.0f);
}

// A blur of angular spread s at distance d acts on the checkerboard (period P = 2 mm) like a
// Gaussian of width s d: the first harmonic keeps exp(-2 pi^2 (s d)^2 / P^2). One rough face of
// GGX alpha deviates the light by about (eta - 1) alpha: alpha 0.05 keeps ~0.9 of the clean
// glass's contrast at d = 5 mm, alpha 0.5 under 0.01.
TEST(SlabPreview, CheckerboardContrastFallsWithRoughnessFromCleanGlasssToNone) {
  SlabPreviewOptions options;
  options.directions = 256;  // Cells of 0.008 in the projected disk: finer than alpha 0.05's lobe.
  std::vector<double> contrast;
  double clean = 0;
  for (double alpha : {0.05, 0.1, 0.5}) {
    DmfFitOnDisk fit = ThreeRegionFit();
    for (DmfPointFit& f : fit.maps.fits) {
      if (!f.log_ndf.empty()) f = GgxPoint(alpha);
    }
    Image view;
    ASSERT_TRUE(RenderSlabPreview(fit, options, &view).ok());
    contrast.push_back(RowContrast(view, 0, 0));
    clean = RowContrast(view, 1, 0);
    EXPECT_NEAR(RowContrast(view, 0, 2), clean, 1e-6);  // No fit: clean glass.
  }
  EXPECT_NEAR(clean, 0.45 / 0.55, 0.01);  // Squares of 1 and 0.1, equal areas: std / mean.
  EXPECT_GT(contrast[0], 0.7 * clean);
  EXPECT_LT(contrast[0], 1.01 * clean);
  EXPECT_GT(contrast[0], contrast[1]);
  EXPECT_GT(contrast[1], contrast[2]);
  EXPECT_LT(contrast[2], 0.1 * clean);
  std::cout << "checker contrast: clean " << clean << ", GGX alpha 0.05 / 0.1 / 0.5: " << contrast[0] << " / "
            << contrast[1] << " / " << contrast[2] << "\n";
}

TEST(SlabPreview, OptionsAreCheckedByName) {
  const DmfFitOnDisk fit = ThreeRegionFit();
  SlabPreviewOptions options;
  options.directions = 2;
  Image view;
  const Status status = RenderSlabPreview(fit, options, &view);
  EXPECT_NE(status.message().find("SlabPreviewOptions::directions (--directions)"), std::string::npos)
      << status.message();
}

}  // namespace
}  // namespace thinslab
