// SPDX-License-Identifier: Apache-2.0
// The region sample of the dot rig (sim/slab_sample.h): the adjoint Monte Carlo tables against
// Walter's rough dielectric composed with a flat face (Dai's rho_t / rho_b in the optical
// frame), reciprocity of a two-sided anisotropic table against a forward trace, the preset and
// option errors.
#include "thinslab/sim/slab_sample.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "thinslab/core/math.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

SlabSampleOptions OneRegion(const SlabMaterial& m, int64_t photons, int bins) {
  SlabSampleOptions o;
  SlabRegion r;
  r.name = "only";
  r.min_m = o.min_m;
  r.max_m = o.max_m;
  r.material = m;
  o.regions = {r};
  o.photons_per_region = photons;
  o.table_bins = bins;
  o.seed = 3;
  return o;
}

// Relative RMS of table vs model over in-lobe cells (model cell mean >= 10% of its peak, cells
// fully inside the disk), and the same for the table's standard errors (noise floor).
template <typename Model>
void CompareTable(const SlabBtdfTable& t, const Model& model, double* rel_rms, double* noise, int* cells) {
  const int n = t.bins;
  const double h = 2.0 / n;
  std::vector<double> m(n * n, 0.0);
  double peak = 0;
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      double sum = 0;
      constexpr int kSub = 4;
      for (int a = 0; a < kSub; ++a) {
        for (int b = 0; b < kSub; ++b) {
          const double x = -1 + (col + (b + 0.5) / kSub) * h, y = -1 + (row + (a + 0.5) / kSub) * h;
          const double s = 1 - x * x - y * y;
          if (s > 0) sum += model(Eigen::Vector3d(x, y, -std::sqrt(s)));
        }
      }
      m[row * n + col] = sum / (kSub * kSub);
      peak = std::max(peak, m[row * n + col]);
    }
  }
  double d2 = 0, m2 = 0, se2 = 0;
  *cells = 0;
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const double x = -1 + col * h, y = -1 + row * h;
      if (std::max(x * x, Sqr(x + h)) + std::max(y * y, Sqr(y + h)) >= 1) continue;
      const double v = m[row * n + col];
      if (v < 0.1 * peak) continue;
      ++*cells;
      d2 += Sqr(t.rho[row * n + col] - v);
      m2 += v * v;
      se2 += Sqr(t.std_error[row * n + col]);
    }
  }
  *rel_rms = std::sqrt(d2 / m2);
  *noise = std::sqrt(se2 / m2);
}

TEST(SlabSample, OneSidedTablesMatchWalterThroughAFlatFaceInTheOpticalFrame) {
  // The region's top (monitor-side) face rough: by reciprocity its table must be Dai's rho_t
  // (Walter's f_t through the rough face composed with the flat face) evaluated in the optical
  // frame, rho_t(i_opt, o_opt); rough bottom (camera side): rho_b. Tolerance as in
  // rough_slab_photon_tracer_test (3 %: multi-bounce light and noise); the swapped model fails.
  const Eigen::Vector3d camera(0.0, -0.7, 0.7);  // 45 degrees from the normal, ~1 m.
  const double kEta = 1.5, kAlpha = 0.3;
  const auto model = MakeDualMicrofacetBtdf(GgxDistribution(kAlpha), GgxDistribution(kAlpha), kEta);
  for (bool rough_top : {true, false}) {
    SlabMaterial m;
    const SlabFace rough{RoughSlabNdf::kGgx, kAlpha, kAlpha};
    (rough_top ? m.top : m.bottom) = rough;
    std::unique_ptr<SlabSample> sample;
    ASSERT_TRUE(SlabSample::Create(OneRegion(m, 1000000, 48), camera, &sample).ok());
    const SlabBtdfTable* t = sample->table(0);
    ASSERT_NE(t, nullptr);
    const Eigen::Vector3d o_opt = SlabSample::ToOpticalFrame(sample->ViewDirection(0));
    EXPECT_LT(o_opt.z(), 0);
    double rel, noise, rel_wrong, noise_wrong;
    int cells, cells_wrong;
    CompareTable(
        *t,
        [&](const Eigen::Vector3d& i) { return model.Eval(SlabSample::ToOpticalFrame(i), o_opt, rough_top ? 1.0 : 0.0); },
        &rel, &noise, &cells);
    CompareTable(
        *t,
        [&](const Eigen::Vector3d& i) { return model.Eval(SlabSample::ToOpticalFrame(i), o_opt, rough_top ? 0.0 : 1.0); },
        &rel_wrong, &noise_wrong, &cells_wrong);
    std::printf("rough %s: table vs %s rel RMS %.4f (noise %.4f, %d cells); the other configuration %.4f; T %.4f\n",
                rough_top ? "top" : "bottom", rough_top ? "rho_t" : "rho_b", rel, noise, cells, rel_wrong,
                t->transmitted);
    EXPECT_LT(rel, 0.03);
    EXPECT_GT(rel_wrong, 0.1);
    EXPECT_GT(cells, 50);
  }
}

TEST(SlabSample, TwoSidedAnisotropicTableIsReciprocalToAForwardTrace) {
  // Forward: light enters the top face from i (optical frame, the tracer's own orientation) and
  // the histogram is read at the camera's o_opt. Adjoint: the region's table at i. Both are
  // cell means of the same rho(i, o) (over different cells), so they agree within the noise and
  // the cells' curvature (both read bilinearly between cell centres); checked at several i
  // across the lobe.
  const Eigen::Vector3d camera(0.0, -0.7, 0.7);
  SlabMaterial m;
  m.top = {RoughSlabNdf::kGgx, 0.15, 0.4};
  m.bottom = {RoughSlabNdf::kBeckmann, 0.2, 0.2};
  std::unique_ptr<SlabSample> sample;
  ASSERT_TRUE(SlabSample::Create(OneRegion(m, 2000000, 32), camera, &sample).ok());
  const Eigen::Vector3d o = sample->ViewDirection(0);
  const Eigen::Vector3d o_opt = SlabSample::ToOpticalFrame(o);
  // Light directions around the straight-through one (i = -o) in the sample frame.
  for (const Eigen::Vector2d& offset : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.15, 0), Eigen::Vector2d(0, 0.2),
                                        Eigen::Vector2d(-0.1, -0.15)}) {
    Eigen::Vector3d i(-o.x() + offset.x(), -o.y() + offset.y(), 0);
    i.z() = -std::sqrt(1 - i.head<2>().squaredNorm());
    RoughSlabPhotonTracerOptions f;
    f.eta = m.eta;
    f.ndf_top = m.top.ndf;
    f.alpha_top = m.top.alpha_x;
    f.alpha_top_y = m.top.alpha_y;
    f.ndf_bottom = m.bottom.ndf;
    f.alpha_bottom = m.bottom.alpha_x;
    f.alpha_bottom_y = m.bottom.alpha_y;
    f.wi = SlabSample::ToOpticalFrame(i);
    f.num_photons = 1000000;
    f.num_bins = 32;
    f.seed = 9;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(f);
    // The forward histogram read like a table: bilinear between cell centres at o_opt.
    SlabBtdfTable ft;
    ft.bins = r.num_bins;
    for (int row = 0; row < r.num_bins; ++row) {
      for (int col = 0; col < r.num_bins; ++col) ft.rho.push_back(static_cast<float>(r.Btdf(row, col)));
    }
    const double h = r.CellWidth();
    const int col = static_cast<int>((o_opt.x() + 1) / h), row = static_cast<int>((o_opt.y() + 1) / h);
    const double forward = ft.Eval(o_opt), forward_se = r.BtdfStdError(row, col);
    const double adjoint = sample->Btdf(0, i);
    const double rel = std::abs(forward - adjoint) / adjoint;
    std::printf("i offset (%.2f, %.2f): forward %.4f +- %.4f, adjoint table %.4f (rel diff %.3f)\n", offset.x(),
                offset.y(), forward, forward_se, adjoint, rel);
    EXPECT_GT(adjoint, 0.05);
    // 4 sigma of the forward cell plus 8 % for the different cell footprints (measured 0.5-4 %).
    EXPECT_LT(std::abs(forward - adjoint), 4 * forward_se + 0.08 * adjoint);
  }
}

TEST(SlabSample, DefaultPresetTilesTheSampleWithTheRequiredRegions) {
  SlabSampleOptions o;
  o.regions = DefaultSlabRegions(o.min_m, o.max_m);
  EXPECT_TRUE(o.Check().ok()) << o.Check().message();
  ASSERT_GE(o.regions.size(), 6u);
  bool top_only = false, bottom_only = false, both = false, beckmann = false, aniso = false, smooth = false,
       diffuse = false;
  for (const SlabRegion& r : o.regions) {
    const SlabMaterial& m = r.material;
    top_only |= !m.top.IsFlat() && m.bottom.IsFlat();
    bottom_only |= m.top.IsFlat() && !m.bottom.IsFlat();
    both |= !m.top.IsFlat() && !m.bottom.IsFlat();
    beckmann |= m.top.ndf == RoughSlabNdf::kBeckmann || m.bottom.ndf == RoughSlabNdf::kBeckmann;
    aniso |= m.top.alpha_x != m.top.alpha_y || m.bottom.alpha_x != m.bottom.alpha_y;
    smooth |= m.IsSmooth();
    diffuse |= m.rho_d > 0;
    EXPECT_EQ(m.eta, 1.5);
  }
  EXPECT_TRUE(top_only && bottom_only && both && beckmann && aniso && smooth && diffuse);
  // Every sample point is in exactly one region; outside is -1.
  std::unique_ptr<SlabSample> sample;
  o.photons_per_region = 1000;
  ASSERT_TRUE(SlabSample::Create(o, Eigen::Vector3d(0, -0.7, 0.7), &sample).ok());
  EXPECT_EQ(sample->RegionIndexAt(Eigen::Vector2d(0.05, 0)), -1);
  EXPECT_EQ(sample->MaterialAt(Eigen::Vector2d(0, -0.05)), nullptr);
  EXPECT_EQ(sample->RegionIndexAt(Eigen::Vector2d(-0.039, -0.039)), 0);
  EXPECT_EQ(sample->RegionIndexAt(Eigen::Vector2d(0.039, 0.039)), 8);
  EXPECT_EQ(sample->region(6).name, "smooth");
  EXPECT_EQ(sample->table(6), nullptr);
  EXPECT_EQ(sample->Btdf(6, Eigen::Vector3d(0, 0.7, -0.7).normalized()), 0.0);
  // Flat slab transmittance: (1 - F) / (1 + F) = 0.9231 at normal incidence for eta 1.5.
  EXPECT_NEAR(SlabSample::FlatSlabTransmittance(1.0, 1.5), 0.96 / 1.04, 1e-12);
}

TEST(SlabSample, BadOptionsNameTheField) {
  const Eigen::Vector3d camera(0, -0.7, 0.7);
  std::unique_ptr<SlabSample> sample;
  SlabSampleOptions o;
  o.regions = DefaultSlabRegions(o.min_m, o.max_m);
  o.regions[2].material.top.alpha_x = 3;
  Status s = SlabSample::Create(o, camera, &sample);
  EXPECT_NE(s.message().find("regions[2] ('ggx_both').material.top"), std::string::npos) << s.message();
  o.regions = DefaultSlabRegions(o.min_m, o.max_m);
  o.regions.pop_back();
  s = SlabSample::Create(o, camera, &sample);
  EXPECT_NE(s.message().find("do not tile"), std::string::npos) << s.message();
  o.regions = DefaultSlabRegions(o.min_m, o.max_m);
  o.regions[1].min_m.x() -= 0.005;
  s = SlabSample::Create(o, camera, &sample);
  EXPECT_NE(s.message().find("overlaps"), std::string::npos) << s.message();
  o.regions = DefaultSlabRegions(o.min_m, o.max_m);
  o.table_bins = 2;
  EXPECT_NE(SlabSample::Create(o, camera, &sample).message().find("table_bins"), std::string::npos);
  o.table_bins = 64;
  o.regions[0].material.eta = 1.0;
  EXPECT_NE(SlabSample::Create(o, camera, &sample).message().find("eta"), std::string::npos);
  o.regions[0].material.eta = 1.5;
  EXPECT_NE(SlabSample::Create(o, Eigen::Vector3d(0, 0, -1), &sample).message().find("+z side"), std::string::npos);
}

}  // namespace
}  // namespace thinslab
