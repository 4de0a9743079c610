// SPDX-License-Identifier: Apache-2.0
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/file.h"

namespace thinslab {

int RunDemo(int argc, char** argv) {
  SyntheticShadowSessionOptions sim;
  double board_distance_mm = 1.0;
  std::string tau_path, out_dir = "demo_out";
  OptionParser parser("demo");
  parser.AddString("out", &out_dir, "report folder (replaced if it exists)");
  AddSimShadowOptions(&parser, &sim, &board_distance_mm, &tau_path);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  sim.rig.board_distance_m = board_distance_mm * 1e-3;
  const std::string session_dir = JoinPath(out_dir, "session");
  Image tau;
  if (status.ok()) status = LoadOrGenerateTau(tau_path, sim.rig.seed, &tau);
  // DIR carries demo's stamp: its simulated session is replaced, a folder of the user's never.
  if (status.ok()) status = CheckReplaceableFolder(out_dir, "demo");
  NewFolderGuard new_output(status.ok() ? out_dir : std::string());
  if (status.ok()) {
    std::error_code ec;
    std::filesystem::remove_all(session_dir, ec);
    status = CreateDirectories(out_dir);
  }
  if (status.ok()) status = WriteFileAtomically(JoinPath(out_dir, kOutputStampName), OutputStampText("demo"));
  if (status.ok()) {
    std::cout << "simulating a shadow-map capture (" << tau.width() << "x" << tau.height()
              << " layer, board at " << board_distance_mm << " mm, albedo " << sim.rig.layer_albedo << ", g "
              << sim.rig.layer_g << ") ...\n";
    status = SynthesizeShadowMapSession(sim, tau, session_dir);
  }
  FitTauRun run;
  run.fit.layer_albedo = sim.rig.layer_albedo;
  run.fit.layer_g = sim.rig.layer_g;
  run.options_ini = parser.ToIni();
  TauFitSummary summary;
  TauComparison comparison;
  bool has_truth = false;
  const std::string report_dir = JoinPath(out_dir, "report");
  if (status.ok()) {
    std::cout << "fitting tau (Eq. 7 and the scattering-aware refinement) ...\n";
    status = FitTauPipeline(session_dir, report_dir, run, &summary, &comparison, &has_truth);
  }
  if (!status.ok()) return CommandFailed(status);
  new_output.Keep();
  std::cout << summary.BriefReport() << "\n";
  std::printf("accuracy against ground truth (pixels with 0.05 <= tau_true <= 1.5, n = %lld):\n",
              static_cast<long long>(comparison.refined.pixels));
  std::printf("  plain Gu Eq. 7:      RMS relative error %5.1f %%, mean bias %+5.1f %%\n",
              100 * comparison.plain.rms_relative, 100 * comparison.plain.mean_relative_bias);
  std::printf("  scattering-refined:  RMS relative error %5.1f %%, mean bias %+5.1f %%\n",
              100 * comparison.refined.rms_relative, 100 * comparison.refined.mean_relative_bias);
  std::cout << "report: " << report_dir << " (tau.exr, tau_falsecolor.png, truth_falsecolor.png, "
            << "error_falsecolor.png, comparison.json, summary.txt)\nsession: " << session_dir << "\n";
  return 0;
}

}  // namespace thinslab
