// SPDX-License-Identifier: Apache-2.0
// `thinslab preview FITDIR OUT` (export/preview_run.h runs it; this file parses its options): a
// fitted material in a canonical scene, rendered with thinslab's own models.
#include <iostream>

#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/export/preview_run.h"

namespace thinslab {

int RunPreviewFit(int argc, char** argv) {
  PreviewRun run;
  double checker_mm = run.slab.checker_m * 1e3, distance_mm = run.slab.backlight_distance_m * 1e3;
  OptionParser parser("preview");
  parser.AddPositional("FITDIR", &run.fit_dir, "a `fit dmf`, `fit tau` or `synth layer` output folder");
  parser.AddPositional("OUT", &run.out_dir, "output folder (preview.png, preview.json; preview.exr for a dot scan)");
  parser.AddDouble("checker-mm", &checker_mm, "dot scans: side of a checker square [mm]");
  parser.AddDouble("backlight-distance-mm", &distance_mm,
                   "dot scans: distance of the checkerboard below the sample [mm]");
  parser.AddDouble("dark-square", &run.slab.dark_square, "dot scans: radiance of the dark squares (bright: 1)");
  parser.AddInt("max-size-px", &run.slab.max_size_px, "dot scans: map points sampled per side, at most");
  parser.AddInt("directions", &run.slab.directions, "dot scans: cells per side of the light-direction grid");
  parser.AddInt("threads", &run.slab.threads, "threads (0: all cores)");
  parser.AddInt("panel-scale", &run.panel_scale, "dot scans: pixels per map point in preview.png (0: a ~320-px panel)");
  parser.AddString("phase", &run.layer.phase_dir, "layers: a `fit phase` folder for g and the layer model");
  parser.AddDouble("g", &run.layer.g, "layers: HG g (-9: the fit's)");
  parser.AddDouble("albedo", &run.layer.albedo, "layers: single-scattering albedo (-9: the fit's)");
  parser.AddDouble("n2", &run.layer_n2, "layers: refractive index of the contaminant");
  parser.AddDouble("glass-eta", &run.layer.glass_eta, "layers: refractive index of the pane");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.slab.checker_m = checker_mm * 1e-3;
  run.slab.backlight_distance_m = distance_mm * 1e-3;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = PreviewFit(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

}  // namespace thinslab
