// SPDX-License-Identifier: Apache-2.0
// End to end on the simulated CRT dot rig (sim/synthesize_dot_scan_session.h): a sample of nine
// regions (GGX and Beckmann, one- and two-sided, anisotropic, smooth, diffuse) whose images are
// made by Monte Carlo photon tracing through both rough faces plus the sensor model, acquired by
// the unchanged dot-scan session, processed (dot geometry, HDR, rectification, Eq. 12) and
// fitted with the dual-microfacet model; every other dot is held out.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/math.h"
#include "thinslab/fit/dmf_evaluation.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_model_ladder.h"
#include "thinslab/fit/dmf_processing.h"
#include "thinslab/fit/single_interface_fit.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"
#include "tests/testing/run_thinslab.h"

namespace thinslab {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return -1;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct RegionStats {
  std::vector<double> alpha, ndf_error, held_out, held_out_ggx;
  std::vector<int> points;
};

class DmfEndToEnd : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: tests/e2e_dmf_cli_ladder_test runs this suite's binary too, possibly
    // at the same time (ctest -j), and each removes its folder at the start and the end.
    dir_ = new std::string(
        (std::filesystem::temp_directory_path() / ("thinslab_e2e_dmf_" + std::to_string(getpid()))).string());
    std::filesystem::remove_all(*dir_);
    SyntheticDotScanOptions sim;
    sim.session.grid_nx = 20;
    sim.session.grid_ny = 20;
    result_ = new SyntheticDotScanResult;
    const Status s = SynthesizeDotScanSession(sim, *dir_, result_);
    ASSERT_TRUE(s.ok()) << s.message();
    DmfProcessingOptions processing;
    processing.pitch_m = 0.004;  // 20 x 20 points on the 80 mm sample.
    processing.hold_out = true;
    slices_ = new DmfSliceSet;
    report_ = new DmfProcessingReport;
    const Status p = PrepareDotScanSlices(*dir_, processing, slices_, report_);
    ASSERT_TRUE(p.ok()) << p.message();
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
    delete result_;
    delete slices_;
    delete report_;
    delete unclustered_;
  }

  // Per-region statistics over points at least one grid cell from the region borders.
  static std::map<std::string, RegionStats> Stats(const DmfMaps& maps, bool with_ggx) {
    std::map<std::string, RegionStats> stats;
    const DmfNdfGrid grid(maps.ndf_resolution);
    DmfPointFitOptions point;
    const SlabSample& sample = *result_->sample;
    for (int p = 0; p < slices_->num_points(); ++p) {
      const Eigen::Vector3d x = slices_->PointPosition(p);
      const int region = sample.RegionIndexAt(x.head<2>());
      if (region < 0) continue;
      const SlabRegion& r = sample.region(region);
      const double margin = slices_->pitch_m;
      if (x.x() < r.min_m.x() + margin || x.x() > r.max_m.x() - margin || x.y() < r.min_m.y() + margin ||
          x.y() > r.max_m.y() - margin) {
        continue;
      }
      RegionStats& s = stats[r.name];
      s.points.push_back(p);
      const DmfPointFit& f = maps.fits[p];
      if (f.log_ndf.empty()) continue;
      s.alpha.push_back(f.alpha);
      const SlabFace& rough = r.material.bottom.IsFlat() ? r.material.top : r.material.bottom;
      if (r.material.top.IsFlat() != r.material.bottom.IsFlat()) {
        const DmfTruthFace face{rough.ndf == RoughSlabNdf::kGgx ? "ggx" : "beckmann", rough.alpha_x, rough.alpha_y,
                                false};
        s.ndf_error.push_back(NdfRelativeL2(f, grid, face));
      }
      s.held_out.push_back(DmfHeldOutError(*slices_, maps, p));
      if (with_ggx) {
        const DmfSlice slice = slices_->Slice(p);
        const SingleInterfaceFit g = FitSingleInterfaceGgx(slice, point);
        s.held_out_ggx.push_back(HeldOutRelativeRms(slice, 0.1, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
          return PredictSingleInterface(g, point.eta, i, o);
        }));
      }
    }
    return stats;
  }

  // Median over the interior points of each region of Dai's Eq. 14 applied to the noiseless
  // true R = rho_d + k_s rho (the photon-traced tables of the ground truth) at the same dots and
  // training mask: what Eq. 14 itself returns, without noise or calibration errors. On rough
  // regions without a diffuse term it is not 0: the lowest 3 x 3 mean above 5 % of the mean R
  // lies in the lobe's tails.
  static std::map<std::string, double> Eq14OnTrueR(const std::map<std::string, RegionStats>& stats) {
    const SlabSample& sample = *result_->sample;
    std::map<std::string, double> out;
    for (const auto& [name, st] : stats) {
      std::vector<double> rho_d;
      for (int p : st.points) {
        const Eigen::Vector3d x = slices_->PointPosition(p);
        const int region = sample.RegionIndexAt(x.head<2>());
        DmfSlice slice = slices_->Slice(p);
        const Eigen::Vector3d view = (slices_->camera_centre - x).normalized();
        for (int q = 0; q < slices_->num_dots(); ++q) {
          slice.value[q] = sample.Transmission(region, (slices_->dot_positions[q] - x).normalized(), view);
        }
        rho_d.push_back(EstimateDiffuse(slice, slices_->dots_nx, slices_->dots_ny));
      }
      out[name] = Median(rho_d);
    }
    return out;
  }

  static std::string* dir_;
  static SyntheticDotScanResult* result_;
  static DmfSliceSet* slices_;
  static DmfProcessingReport* report_;
  static DmfMaps* unclustered_;
};
DmfMaps* DmfEndToEnd::unclustered_ = nullptr;
std::string* DmfEndToEnd::dir_ = nullptr;
SyntheticDotScanResult* DmfEndToEnd::result_ = nullptr;
DmfSliceSet* DmfEndToEnd::slices_ = nullptr;
DmfProcessingReport* DmfEndToEnd::report_ = nullptr;

TEST_F(DmfEndToEnd, UnclusteredFitRecoversRegions) {
  DmfMapFitOptions options;
  options.cluster = false;
  DmfMaps maps;
  const Status s = FitDualMicrofacetMaps(*slices_, options, &maps);
  ASSERT_TRUE(s.ok()) << s.message();
  std::printf("processing %.2f s, fit %.2f s (%d points)\n", report_->total_s, maps.timings.total_s, maps.num_fitted);
  const auto stats = Stats(maps, true);
  for (const auto& [name, st] : stats) {
    std::printf("%-14s points %3zu fitted %3zu alpha %.3f ndf L2 %.3f held-out %.3f ggx held-out %.3f\n", name.c_str(),
                st.points.size(), st.alpha.size(), Median(st.alpha), Median(st.ndf_error), Median(st.held_out),
                Median(st.held_out_ggx));
  }
  // The library comparison (what `thinslab fit dmf` writes to comparison.json) reads the same
  // regions from ground_truth/truth.json.
  std::vector<DmfTruthRegion> truth;
  ASSERT_TRUE(ReadDmfTruth(*dir_, &truth).ok());
  const std::map<std::string, double> eq14_on_truth = Eq14OnTrueR(stats);
  std::map<std::string, DmfRegionAccuracy> accuracy;
  for (const DmfRegionAccuracy& a : CompareDmfWithTruth(*slices_, maps, truth)) {
    EXPECT_EQ(a.fitted, static_cast<int>(stats.at(a.name).alpha.size())) << a.name;
    if (a.fitted > 0) {
      EXPECT_DOUBLE_EQ(a.median_alpha, Median(stats.at(a.name).alpha)) << a.name;
    }
    std::printf("%-14s k_s %.3f (true %.2f), rho_d %.4f (true %.3f, Eq. 14 on the true R %.4f)\n", a.name.c_str(),
                a.median_k_s, a.true_k_s, a.median_rho_d, a.true_rho_d, eq14_on_truth.at(a.name));
    accuracy[a.name] = a;
  }
  // Dai Sec. 3: alpha near 1 for a rough top, near 0 for a rough bottom.
  for (const char* name : {"ggx_top", "beckmann_top", "ggx_aniso_top"}) EXPECT_GE(Median(stats.at(name).alpha), 0.8) << name;
  EXPECT_LE(Median(stats.at("ggx_bottom").alpha), 0.2);
  // NDF against the true face NDF, per region: measured median plus about 25-30 %
  // (ggx_aniso_top, the worst: its wide 0.4 axis has tails beyond the dots, kept at the earlier
  // bound 0.4, 16 % above measured).
  const std::map<std::string, double> max_ndf_error = {
      {"ggx_top", 0.34},        // Measured 0.265 (0.298 before the rig's L_q fix of 2026-12-03).
      {"ggx_bottom", 0.29},     // Measured 0.224 (0.271).
      {"beckmann_top", 0.15},   // Measured 0.114 (0.185).
      {"ggx_aniso_top", 0.40},  // Measured 0.350 (0.344).
  };
  for (const auto& [name, bound] : max_ndf_error) EXPECT_LT(Median(stats.at(name).ndf_error), bound) << name;
  // Diffuse term (Eq. 14). Where the slab has one (rho_d 0.05 /sr; every dot sees it, so the
  // minimum of Eq. 14 is that floor) it is recovered within 0.015 /sr (measured 0.0469; Eq. 14
  // on the noiseless true R gives 0.0500: the minimum over noisy 3 x 3 means is biased low).
  EXPECT_NEAR(accuracy.at("diffuse").median_rho_d, accuracy.at("diffuse").true_rho_d, 0.015);
  // Without a diffuse term Eq. 14 does not give 0 but the lobe tails' level: measured
  // 0.024-0.068 /sr (ggx_bottom the highest), under 1 % of the lobe peaks (6-11 /sr), as high as
  // the diffuse region's true 0.05, so rho_d cannot tell a diffuse term of that size from tails.
  // Asserted: below 0.09 /sr (measured max 0.0682), and within 0.006 /sr of Eq. 14 on the true R
  // (measured differences 0.0000-0.0053, the largest ggx_mixed), i.e. the floor is Eq. 14's,
  // not noise or calibration.
  for (const char* name :
       {"ggx_top", "ggx_bottom", "ggx_both", "beckmann_top", "beckmann_both", "ggx_aniso_top", "ggx_mixed"}) {
    ASSERT_EQ(accuracy.at(name).true_rho_d, 0) << name;
    EXPECT_LT(accuracy.at(name).median_rho_d, 0.09) << name;
    EXPECT_NEAR(accuracy.at(name).median_rho_d, eq14_on_truth.at(name), 0.006) << name;
  }
  // k_s (Eq. 13, the projected integral of the unnormalised D) where the virtual configuration
  // of Dai Fig. 2 is the true slab (one rough face): within 0.7-1.3 x the true k_s (measured
  // ratios below; docs/models/dual_microfacet_fit.md: 0.75-1.3). The light that the fitted lobe
  // does not model (the halo of internal reflections, the Laplacian-extrapolated tails) is what
  // moves it. Not asserted on the two-sided regions, where k_s absorbs the mismatch of the Eq. 11
  // interpolation (measured 1.058 ggx_both, 1.185 beckmann_both, 0.843 ggx_mixed).
  for (const char* name : {
           "ggx_top",        // Measured k_s 0.815 (true 1).
           "ggx_bottom",     // 0.801 (true 1).
           "beckmann_top",   // 1.016 (true 1).
           "ggx_aniso_top",  // 1.022 (true 1).
           "diffuse",        // 0.713 (true 0.8): ratio 0.891.
       }) {
    const DmfRegionAccuracy& a = accuracy.at(name);
    EXPECT_GE(a.median_k_s, 0.7 * a.true_k_s) << name;
    EXPECT_LE(a.median_k_s, 1.3 * a.true_k_s) << name;
  }
  // Held-out in-lobe error: measured 0.028-0.066 on the isotropic regions, 0.151 on the
  // anisotropic one (whose 0.4 axis has tails beyond the dots). Before the rig's L_q fix of
  // 2026-12-03 every region read 0.09-0.22 (a 12 % RMS per-dot error of the simulated rig).
  for (const char* name : {"ggx_top", "ggx_bottom", "ggx_both", "beckmann_top", "beckmann_both", "diffuse", "ggx_mixed"}) {
    EXPECT_LT(Median(stats.at(name).held_out), 0.09) << name;
  }
  EXPECT_LT(Median(stats.at("ggx_aniso_top").held_out), 0.2);
  // Dai Fig. 5: where both faces are equally rough the dual-microfacet model predicts held-out
  // dots better than a single rough GGX interface (measured ratios 0.21 ggx_both, 0.08
  // beckmann_both). (Where one face dominates, ggx_mixed, the
  // single interface is as good: docs/models/dual_microfacet_fit.md has the figures.)
  for (const char* name : {"ggx_both", "beckmann_both"}) {
    EXPECT_LT(Median(stats.at(name).held_out), 0.8 * Median(stats.at(name).held_out_ggx)) << name;
  }
  // The smooth region has no resolvable lobe: it says so instead of inventing an NDF.
  int smooth_flagged = 0;
  for (int p : stats.at("smooth").points) {
    const DmfStatus status = maps.fits[p].status;
    smooth_flagged += status == DmfStatus::kSpecular || status == DmfStatus::kNoLobe;
  }
  std::printf("smooth region: %d of %zu points flagged specular or no lobe\n", smooth_flagged,
              stats.at("smooth").points.size());
  EXPECT_GT(smooth_flagged, static_cast<int>(stats.at("smooth").points.size()) * 3 / 4);
  // No NaN anywhere.
  const Image image = maps.ToImage();
  for (float v : image.data()) ASSERT_TRUE(std::isfinite(v));
  unclustered_ = new DmfMaps(maps);
}

// Issue #8 on the dot-scan rungs: the simplest model within noise of the best on held-out
// dots. One-sided isotropic GGX regions need no more than a single rough GGX interface, the
// smooth region is an attenuator, the anisotropic region needs the tabulated NDF.
TEST_F(DmfEndToEnd, ModelLadderFitsNoMoreThanTheRegionNeeds) {
  std::vector<DmfTruthRegion> truth;
  ASSERT_TRUE(ReadDmfTruth(*dir_, &truth).ok());
  LadderOptions options;
  const DmfNdfGrid grid(options.point.ndf_resolution);
  std::map<std::string, std::map<int, int>> votes;
  std::map<std::string, std::vector<LadderResult>> results;
  std::map<std::string, double> params_saved, seconds_saved;
  for (const DmfTruthRegion& r : truth) {
    int taken = 0;  // 12 interior points per region keep the sanitizer run short.
    for (int p = 0; p < slices_->num_points() && taken < 12; ++p) {
      const Eigen::Vector3d x = slices_->PointPosition(p);
      const double margin = slices_->pitch_m;
      if (x.x() < r.min_m.x() + margin || x.x() > r.max_m.x() - margin || x.y() < r.min_m.y() + margin ||
          x.y() > r.max_m.y() - margin) {
        continue;
      }
      ++taken;
      results[r.name].push_back(FitLadder(slices_->Slice(p), grid, options));
      const LadderResult& l = results[r.name].back();
      ++votes[r.name][l.chosen_rung()];
      if (l.chosen >= 0) {
        params_saved[r.name] += l.parameters[2] - l.parameters[l.chosen];
        seconds_saved[r.name] += l.seconds[2] - l.seconds[l.chosen];
      }
    }
  }
  // The region (one material) is the pixel cluster: its points' held-out dots are pooled.
  std::map<std::string, int> chosen;
  for (const auto& [name, v] : votes) {
    std::vector<const LadderResult*> group;
    bool all_specular = true;
    for (const LadderResult& l : results.at(name)) {
      group.push_back(&l);
      all_specular = all_specular && l.specular;
    }
    const int k = ChooseLadderRung(group, options.significance_sigmas);
    chosen[name] = all_specular ? 0 : k >= 0 ? kLadderRungIds[k] : -1;
    std::printf("%-14s region rung %d; per-point rungs (votes):", name.c_str(), chosen[name]);
    for (const auto& [rung, n] : v) std::printf(" %d (%d)", rung, n);
    std::printf("; per point, parameters saved %.0f, fit time saved %.2f s\n", params_saved[name],
                seconds_saved[name]);
    std::vector<double> held[kNumLadderRungs];
    int beckmann_single = 0, beckmann_analytic = 0;
    for (const LadderResult& l : results.at(name)) {
      for (int j = 0; j < kNumLadderRungs; ++j) {
        if (l.held_out[j] >= 0) held[j].push_back(l.held_out[j]);
      }
      beckmann_single += l.single.ok && l.single.family == MicrofacetFamily::kBeckmann;
      beckmann_analytic += l.analytic.ok && l.analytic.family == MicrofacetFamily::kBeckmann;
    }
    std::printf("%-14s median held-out rung 3 %.3f, 4 %.3f, 5 %.3f; Beckmann family chosen by rung 3 at %d, rung 4 at %d "
                "of %zu points\n",
                name.c_str(), Median(held[0]), Median(held[1]), Median(held[2]), beckmann_single, beckmann_analytic,
                results.at(name).size());
    // Rung 3 tells the family of a one-sided slab (measured: Beckmann at 12 of 12 beckmann_top
    // points, GGX at 11 and 12 of 12 on ggx_top and ggx_bottom).
    if (name == "beckmann_top") {
      EXPECT_GE(beckmann_single, 10) << name;
    } else if (name == "ggx_top" || name == "ggx_bottom") {
      EXPECT_LE(beckmann_single, 2) << name;
    }
  }
  // Smooth: an attenuator. Anisotropic: only the tabulated NDF. Isotropic regions: a small model
  // (measured: ggx_bottom 3; ggx_top, ggx_both, ggx_mixed, beckmann_top, diffuse 4;
  // beckmann_both 5, where rung 4 predicts the held-out dots at 0.073 against 0.030:
  // docs/models/model_ladder.md).
  EXPECT_EQ(chosen["smooth"], 0);
  EXPECT_EQ(chosen["ggx_aniso_top"], 5);
  for (const char* name : {"ggx_top", "ggx_bottom", "ggx_both", "ggx_mixed", "beckmann_top", "diffuse"}) {
    EXPECT_TRUE(chosen[name] == 3 || chosen[name] == 4) << name << " chose rung " << chosen[name];
  }

  // BIC (the documented alternative) on the same points: 716 NDF cells cost 716 ln n, so it never
  // takes the tabulated NDF here, not even where the held-out dots need it (ggx_aniso_top).
  for (const auto& [name, v] : votes) {
    if (name == "smooth") continue;
    std::vector<const LadderResult*> group;
    for (const LadderResult& l : results.at(name)) group.push_back(&l);
    const int k = ChooseLadderRung(group, options.significance_sigmas, LadderCriterion::kBic);
    std::printf("%-14s BIC rung %d\n", name.c_str(), k >= 0 ? kLadderRungIds[k] : -1);
    ASSERT_GE(k, 0) << name;
    EXPECT_LE(kLadderRungIds[k], 4) << name;
  }

  // The choice in the maps (ReplaceWithLadderRung): a point of a rung-3 or rung-4 region, its
  // tabulated fit replaced by the chosen analytic model sampled on the NDF grid with k_s refitted,
  // predicts its held-out dots as well as the analytic model itself.
  int replaced = 0;
  for (const auto& [name, rung] : chosen) {
    if (rung != 3 && rung != 4) continue;
    const int index = rung == 3 ? 0 : 1;
    int taken = 0;
    for (int p = 0; p < slices_->num_points() && taken < static_cast<int>(results.at(name).size()); ++p) {
      const Eigen::Vector3d x = slices_->PointPosition(p);
      const DmfTruthRegion& r = *std::find_if(truth.begin(), truth.end(), [&](const DmfTruthRegion& t) { return t.name == name; });
      const double margin = slices_->pitch_m;
      if (x.x() < r.min_m.x() + margin || x.x() > r.max_m.x() - margin || x.y() < r.min_m.y() + margin ||
          x.y() > r.max_m.y() - margin) {
        continue;
      }
      const LadderResult& l = results.at(name)[taken++];
      if (l.specular || l.held_out[index] < 0 || l.tabulated.log_ndf.empty()) continue;
      const DmfSlice slice = slices_->Slice(p);
      DmfPointFit fit = l.tabulated;
      ASSERT_TRUE(ReplaceWithLadderRung(l, index, slice, grid, AnalyticRungOptions(options), &fit)) << name;
      const double held_out = HeldOutRelativeRms(slice, options.lobe_fraction, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
        return PredictDualMicrofacet(fit, grid, options.point.eta, i, o);
      });
      EXPECT_NEAR(held_out, l.held_out[index], 0.15 * l.held_out[index] + 0.01) << name << " point " << p;
      EXPECT_TRUE(std::isfinite(fit.k_s) && fit.k_s > 0) << name;
      ++replaced;
    }
  }
  EXPECT_GE(replaced, 24);
}

// Issue #8 through the binary: `thinslab fit dmf --ladder` on the same capture chooses per region
// (2 x 2 point tiles pooled) as the library ladder above does, and maps.exr holds the choice:
// rung-3 points carry alpha 0 or 1 (one rough face) and their held-out error stays that of the
// rung's model.
TEST_F(DmfEndToEnd, CliLadderChoosesPerRegionAndTheMapsHoldTheChoice) {
  const std::string out = *dir_ + "/fit/ladder";  // Outputs go under the capture's fit/.
  const RunResult run = RunThinslab("fit dmf " + *dir_ +
                                    " --pitch-mm 4 --hold-out true --cluster-fraction 0 --ladder true --ladder-tile 2 "
                                    "--out " + out);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Image rungs, maps;
  ASSERT_TRUE(ReadExr(out + "/ladder.exr", &rungs).ok());
  ASSERT_TRUE(ReadExr(out + "/maps.exr", &maps).ok());
  ASSERT_EQ(rungs.width(), slices_->width);
  ASSERT_EQ(rungs.height(), slices_->height);
  EXPECT_EQ(maps.attributes().at("ladder_applied"), "true");
  std::vector<DmfTruthRegion> truth;
  ASSERT_TRUE(ReadDmfTruth(*dir_, &truth).ok());
  std::map<std::string, int> chosen;
  for (const DmfTruthRegion& r : truth) {
    std::map<int, int> counts;
    for (int p = 0; p < slices_->num_points(); ++p) {
      const Eigen::Vector3d x = slices_->PointPosition(p);
      const double margin = slices_->pitch_m;
      if (x.x() < r.min_m.x() + margin || x.x() > r.max_m.x() - margin || x.y() < r.min_m.y() + margin ||
          x.y() > r.max_m.y() - margin) {
        continue;
      }
      const int rung = static_cast<int>(rungs.at(p % rungs.width(), p / rungs.width(), rungs.ChannelIndex("rung")));
      ++counts[rung];
      if (rung == 3) {
        const float alpha = maps.at(p % maps.width(), p / maps.width(), maps.ChannelIndex("top_face_weight"));
        EXPECT_TRUE(alpha == 0 || alpha == 1) << r.name << " point " << p << " alpha " << alpha;
      }
    }
    int majority = -1;
    for (const auto& [rung, n] : counts) {
      if (majority < 0 || n > counts[majority]) majority = rung;
    }
    chosen[r.name] = majority;
    std::printf("CLI ladder %-14s majority rung %d:", r.name.c_str(), majority);
    for (const auto& [rung, n] : counts) std::printf(" %d (%d)", rung, n);
    std::printf("\n");
  }
  // Measured: smooth 0; ggx_top 3 (15; 10 on 4), ggx_bottom 3 (20), diffuse 3 (16; 4 on 4),
  // ggx_both 4 (21; 4 on 5), beckmann_top 4 (18; 2 on 3), ggx_mixed 4 (25); beckmann_both and
  // ggx_aniso_top 5.
  EXPECT_EQ(chosen["smooth"], 0);
  EXPECT_EQ(chosen["ggx_aniso_top"], 5);
  for (const char* name : {"ggx_top", "ggx_bottom", "ggx_both", "ggx_mixed", "beckmann_top", "diffuse"}) {
    EXPECT_TRUE(chosen[name] == 3 || chosen[name] == 4) << name << " chose rung " << chosen[name];
  }
  for (float v : maps.data()) ASSERT_TRUE(std::isfinite(v));
}

// Dai Sec. 4.3: fitting only k-means representatives and interpolating the rest (Eqs. 20-22)
// stays close to fitting every point.
TEST_F(DmfEndToEnd, ClusteredFitStaysCloseToUnclustered) {
  ASSERT_NE(unclustered_, nullptr) << "runs after UnclusteredFitRecoversRegions";
  DmfMapFitOptions options;
  options.cluster = true;
  options.clustering.fraction = 0.1;  // About 40 representatives for 400 points (1 % of 600 x 600 in the benchmark).
  options.clustering.min_representatives = 4;
  DmfMaps maps;
  const Status s = FitDualMicrofacetMaps(*slices_, options, &maps);
  ASSERT_TRUE(s.ok()) << s.message();
  std::vector<double> clustered, unclustered;
  for (int p = 0; p < slices_->num_points(); ++p) {
    if (maps.fits[p].log_ndf.empty() || unclustered_->fits[p].log_ndf.empty()) continue;
    const double c = DmfHeldOutError(*slices_, maps, p), u = DmfHeldOutError(*slices_, *unclustered_, p);
    if (c < 0 || u < 0) continue;
    clustered.push_back(c);
    unclustered.push_back(u);
  }
  std::printf("clustered: %d fitted of %zu, held-out median %.3f vs unclustered %.3f, fit %.2f s vs %.2f s\n",
              maps.num_fitted, clustered.size(), Median(clustered), Median(unclustered), maps.timings.total_s,
              unclustered_->timings.total_s);
  EXPECT_LT(maps.num_fitted, 0.15 * slices_->num_points());
  EXPECT_LT(Median(clustered), Median(unclustered) + 0.05);
  const Image image = maps.ToImage();
  for (float v : image.data()) ASSERT_TRUE(std::isfinite(v));

  // Issue #29's speed-ups compute the same numbers, bit for bit. (1) The Eq. 20 NDFs built from
  // the cached linear representatives equal those exponentiated each time.
  ASSERT_FALSE(maps.representative_ndf.empty());
  DmfMaps uncached = maps;
  uncached.representative_ndf.clear();
  int rebuilt = 0;
  for (int p = 0; p < slices_->num_points(); ++p) {
    if (maps.fits[p].status != DmfStatus::kInterpolated) continue;
    uncached.fits[p].log_ndf.clear();  // As a streamed fit keeps it.
    uncached.fits[p].ndf_interpolated = true;
    ASSERT_EQ(uncached.FitWithNdf(p).log_ndf, maps.fits[p].log_ndf) << p;
    ++rebuilt;
  }
  EXPECT_GT(rebuilt, slices_->num_points() / 2);
  // (2) The held-out pass's per-point errors are DmfHeldOutError's, flagged points included, and
  // the ground-truth comparison given them writes what it writes predicting them itself.
  std::vector<DmfTruthRegion> truth;
  ASSERT_TRUE(ReadDmfTruth(*dir_, &truth).ok());
  std::vector<DmfValidationError> held_out;
  std::vector<double> errors;
  ASSERT_TRUE(EvaluateHeldOutDots(*slices_, maps, truth, 0.1, 2, &held_out, ProgressCallback(), &errors).ok());
  ASSERT_EQ(errors.size(), static_cast<size_t>(slices_->num_points()));
  int flagged_scored = 0;
  for (int p = 0; p < slices_->num_points(); ++p) {
    ASSERT_EQ(errors[p], DmfHeldOutError(*slices_, maps, p)) << p;
    const DmfStatus st = maps.fits[p].status;
    flagged_scored += errors[p] >= 0 && st != DmfStatus::kOk && st != DmfStatus::kInterpolated;
  }
  EXPECT_GT(flagged_scored, 0);
  std::vector<DmfRegionAccuracy> given, predicted;
  ASSERT_TRUE(CompareDmfWithTruth(*slices_, maps, truth, 0.5, &given, ProgressCallback(), &errors).ok());
  ASSERT_TRUE(CompareDmfWithTruth(*slices_, maps, truth, 0.5, &predicted).ok());
  EXPECT_EQ(DmfComparisonJson(given), DmfComparisonJson(predicted));
}

// The same at the defaults of DmfMapFitOptions (Dai's 1 % of the points, raised to
// min_representatives = 64: here 64 of the 364 fittable points).
TEST_F(DmfEndToEnd, ClusteredFitAtDefaultsStaysCloseToUnclustered) {
  ASSERT_NE(unclustered_, nullptr) << "runs after UnclusteredFitRecoversRegions";
  const DmfMapFitOptions options;
  ASSERT_TRUE(options.cluster);
  DmfMaps maps;
  const Status s = FitDualMicrofacetMaps(*slices_, options, &maps);
  ASSERT_TRUE(s.ok()) << s.message();
  std::vector<double> clustered, unclustered;
  for (int p = 0; p < slices_->num_points(); ++p) {
    if (maps.fits[p].log_ndf.empty() || unclustered_->fits[p].log_ndf.empty()) continue;
    const double c = DmfHeldOutError(*slices_, maps, p), u = DmfHeldOutError(*slices_, *unclustered_, p);
    if (c < 0 || u < 0) continue;
    clustered.push_back(c);
    unclustered.push_back(u);
  }
  std::sort(clustered.begin(), clustered.end());
  std::sort(unclustered.begin(), unclustered.end());
  const auto quantile = [](const std::vector<double>& v, double f) { return v[static_cast<size_t>(f * (v.size() - 1))]; };
  std::printf("clustered at defaults: %d representatives of %zu points, held-out median %.3f vs %.3f unclustered, "
              "90th percentile %.3f vs %.3f, fit %.2f s vs %.2f s\n",
              maps.num_fitted, clustered.size(), Median(clustered), Median(unclustered), quantile(clustered, 0.9),
              quantile(unclustered, 0.9), maps.timings.total_s, unclustered_->timings.total_s);
  EXPECT_EQ(maps.num_fitted, options.clustering.min_representatives);
  // Eq. 20 interpolation from the 4 nearest representatives, on slice shapes aligned in
  // u = i_xy + o_xy (fit/dmf_slice_shape.h): measured median held-out error 0.060 vs 0.047
  // unclustered (1.28 x), 90th percentile 0.138 vs 0.099 (1.39 x). With dot-indexed shapes it
  // was 0.071 (1.51 x) and 0.186 (1.88 x): 136 of 230 interpolated points had a representative
  // of another region among their neighbours (now 139 of 243, with a mean weight of 0.16 instead
  // of 0.24). Until 2026-12-03 the simulated rig's per-dot L_q was 12 % RMS wrong
  // (sim/screen_footprint.h); that error (held-out 0.17 everywhere) hid the interpolation's, and
  // these bounds were 1.15 x and 1.3 x on it. The interpolation's remaining cost is a known gap
  // (docs/known_gaps.md).
  EXPECT_LE(Median(clustered), 1.45 * Median(unclustered));
  EXPECT_LE(quantile(clustered, 0.9), 1.6 * quantile(unclustered, 0.9));
  const Image image = maps.ToImage();
  for (float v : image.data()) ASSERT_TRUE(std::isfinite(v));
}

}  // namespace
}  // namespace thinslab

namespace thinslab {
namespace {

// Bad input: each case a clear error naming what is wrong, never a partial or NaN map.
class DmfBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (std::filesystem::temp_directory_path() /
            ("thinslab_dmf_bad_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name())))
               .string();
    std::filesystem::remove_all(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  Status Process(const SyntheticDotScanOptions& sim) {
    const Status s = SynthesizeDotScanSession(sim, dir_);
    if (!s.ok()) return s;
    return Prepare();
  }
  Status Prepare() {
    DmfSliceSet slices;
    DmfProcessingReport report;
    DmfProcessingOptions options;
    options.pitch_m = 0.008;
    return PrepareDotScanSlices(dir_, options, &slices, &report);
  }
  static SyntheticDotScanOptions Small() {
    SyntheticDotScanOptions sim;
    sim.session.grid_nx = 6;
    sim.session.grid_ny = 6;
    sim.sample.photons_per_region = 20000;
    return sim;
  }
  std::string dir_;
};

TEST_F(DmfBadInput, TooFewDots) {
  SyntheticDotScanOptions sim = Small();
  sim.session.grid_nx = 3;
  sim.session.grid_ny = 3;
  const Status s = Process(sim);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("at least 4 x 4"), std::string::npos) << s.message();
}

TEST_F(DmfBadInput, DotPositionsMissing) {
  ASSERT_TRUE(SynthesizeDotScanSession(Small(), dir_).ok());
  const std::string manifest = dir_ + "/session.json";
  std::ifstream in(manifest);
  nlohmann::json j = nlohmann::json::parse(in);
  in.close();
  for (auto& f : j["frames"]) {
    if (f["kind"] == "dot" && f.contains("light")) f["light"].erase("dot_px");
  }
  std::ofstream(manifest) << j.dump(1);
  const Status s = Prepare();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("dot_px"), std::string::npos) << s.message();
}

TEST_F(DmfBadInput, NoAllDotsFrame) {
  SyntheticDotScanOptions sim = Small();
  sim.session.capture_all_dots = false;
  const Status s = Process(sim);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("all_dots"), std::string::npos) << s.message();
}

TEST_F(DmfBadInput, SaturatedStack) {
  SyntheticDotScanOptions sim = Small();
  sim.rig.dot_radiance *= 1000;  // Every exposure of the bracket saturates.
  const Status s = Process(sim);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("saturat"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
