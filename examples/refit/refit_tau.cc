// SPDX-License-Identifier: Apache-2.0
// refit_tau CAPTURE OUT [ALBEDO]: fits the optical thickness map of a shadow-map capture with
// thinslab's pipeline and prints what a lab script would log. The same fit as
// `thinslab fit tau CAPTURE --out OUT --albedo ALBEDO`.
#include <cstdlib>
#include <iostream>

#include "thinslab/pipeline/tau_pipeline.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: refit_tau CAPTURE OUT [ALBEDO]\n";
    return 2;
  }
  thinslab::FitTauRun run;
  if (argc > 3) run.fit.layer_albedo = std::atof(argv[3]);
  run.options_ini = "# refit_tau example\n";
  thinslab::TauFitSummary summary;
  thinslab::TauComparison comparison;
  bool has_truth = false;
  const thinslab::Status status = thinslab::FitTauPipeline(argv[1], argv[2], run, &summary, &comparison, &has_truth);
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
  std::cout << summary.BriefReport() << "\n";
  if (has_truth) std::cout << "ground truth: " << comparison.ToJson();
  return summary.IsUsable() ? 0 : 1;
}
