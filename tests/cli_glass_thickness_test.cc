// SPDX-License-Identifier: Apache-2.0
// Issue #23 section 5: `fit dmf` and rig.sample.glass_thickness_m. Light from a dot enters the
// slab's monitor-side face away from the point the camera sees on its other face; the fit models
// the specular path (the camera ray refracted at the flat mean surface, DmfSliceSet::
// LightEntryPoint). The captures come from a more complete forward model: the simulated rig
// moves each dot's light by the traced mean offsets of the photons that crossed the slab once,
// and spreads the few % that crossed it several times (internal reflections) over their own
// traced offsets (SlabSample::LightEntryPoint), through both rough faces.
//
// Test: a 3 mm slab (light enters 1.6 mm from the seen point, a third of the 20 x 20 grid's
// 4.8 mm dot step) fitted with the manifest's thickness gives per-region dual-microfacet alphas
// close to the same sample's thin capture; fitted as if thin (--glass-thickness-mm 0), they
// move towards the rough-top end.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/testing/json_file.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

void RunOk(const std::string& args) {
  const RunResult run = RunThinslab(args);
  ASSERT_EQ(run.exit_code, 0) << "thinslab " << args << "\n" << run.output;
}

// Median alpha per region with fitted points (comparison.json of a simulated capture's fit).
std::map<std::string, double> RegionAlphas(const std::string& fit_dir) {
  std::map<std::string, double> alphas;
  const nlohmann::json comparison = ReadJsonFile(fit_dir + "/comparison.json");
  for (const nlohmann::json& r : comparison["regions"]) {
    if (r["fitted"].get<int>() > 0) alphas[r["name"].get<std::string>()] = r["median_alpha"].get<double>();
  }
  return alphas;
}

TEST(CliGlassThickness, FitWithTheManifestThicknessMatchesTheThinSample) {
  TempDir dir;
  const std::string sim = " --grid-nx 20 --grid-ny 20 --photons-k 100 --table-bins 48";
  RunOk("sim dot-scan " + (dir / "thin") + sim);
  RunOk("sim dot-scan " + (dir / "thick") + sim + " --glass-thickness-mm 3");
  const std::string fit = " --hold-out true --pitch-mm 4 --out ";
  RunOk("fit dmf " + (dir / "thin") + fit + (dir / "fit_thin"));
  RunOk("fit dmf " + (dir / "thick") + fit + (dir / "fit_modelled"));
  RunOk("fit dmf " + (dir / "thick") + fit + (dir / "fit_as_thin") + " --glass-thickness-mm 0");
  EXPECT_DOUBLE_EQ(ReadJsonFile(dir / "fit_modelled/summary.json")["glass_thickness_m"].get<double>(), 3e-3);
  EXPECT_DOUBLE_EQ(ReadJsonFile(dir / "fit_as_thin/summary.json")["glass_thickness_m"].get<double>(), 0);

  const auto thin = RegionAlphas(dir / "fit_thin");
  const auto modelled = RegionAlphas(dir / "fit_modelled");
  const auto as_thin = RegionAlphas(dir / "fit_as_thin");
  double modelled_error = 0, as_thin_error = 0;
  int regions = 0;
  for (const auto& [name, alpha] : thin) {
    if (!modelled.count(name) || !as_thin.count(name)) continue;
    std::printf("%-14s alpha thin %.3f, 3 mm modelled %.3f, 3 mm as thin %.3f\n", name.c_str(), alpha,
                modelled.at(name), as_thin.at(name));
    modelled_error += std::abs(modelled.at(name) - alpha);
    as_thin_error += std::abs(as_thin.at(name) - alpha);
    ++regions;
  }
  ASSERT_GE(regions, 7);  // Every rough region of the default sample.
  modelled_error /= regions;
  as_thin_error /= regions;
  std::printf("mean |alpha - thin sample's|: thickness modelled %.3f, ignored %.3f\n", modelled_error, as_thin_error);
  EXPECT_LT(modelled_error, 0.06);
  EXPECT_GT(as_thin_error, 2 * modelled_error);
}

}  // namespace
}  // namespace thinslab
