// SPDX-License-Identifier: Apache-2.0
// `thinslab export mitsuba|pbrt|blender FITDIR OUT` (export/export_run.h runs it; this file
// parses its options): a `fit dmf`, `fit tau` or `synth layer` folder as a renderer's scene.
#include <iostream>

#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/export/export_run.h"

namespace thinslab {

namespace {

int RunExportTo(const std::string& renderer, int argc, char** argv) {
  ExportRun run;
  run.renderer = renderer;
  ExportOptions& o = run.options;
  OptionParser parser("export " + renderer);
  parser.AddPositional("FITDIR", &run.fit_dir, "a `fit dmf`, `fit tau` or `synth layer` output folder");
  parser.AddPositional("OUT", &run.out_dir, "output folder (the scene, its textures, export.json)");
  parser.AddDouble("slab-thickness-mm", &o.slab_thickness_mm,
                   "slab thickness [mm] (-1: the fit's glass thickness, 1 mm where that is 0)");
  parser.AddDouble("min-alpha", &o.min_alpha, "roughness floor of every face (smooth faces, unfitted points)");
  parser.AddDouble("layer-thickness-mm", &o.layer_thickness_mm,
                   "geometric thickness of an exported layer [mm] (its optical thickness stays tau)");
  parser.AddDouble("glass-thickness-mm", &o.glass_thickness_mm, "thickness of the pane under a layer [mm]");
  parser.AddDouble("glass-eta", &o.glass_eta, "refractive index of the pane under a layer");
  parser.AddString("phase", &o.phase_dir, "a `fit phase` folder: the layer's g and model from its ladder choice");
  parser.AddDouble("g", &o.g, "the layer's HG g (-9: the fit's)");
  parser.AddDouble("albedo", &o.albedo, "the layer's single-scattering albedo (-9: the fit's)");
  parser.AddDouble("backlight-distance-mm", &o.backlight_distance_mm,
                   "distance of the backlight plane below the sample [mm] (-1: the fit's monitor, else 20 mm)");
  parser.AddInt("image-width", &o.image_width, "rendered image width [px]");
  parser.AddInt("image-height", &o.image_height, "rendered image height [px]");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = ExportFit(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

int RunExportMitsuba(int argc, char** argv) { return RunExportTo("mitsuba", argc, argv); }
int RunExportPbrt(int argc, char** argv) { return RunExportTo("pbrt", argc, argv); }
int RunExportBlender(int argc, char** argv) { return RunExportTo("blender", argc, argv); }

}  // namespace

const std::vector<Subcommand>& ExportSubcommands() {
  static const std::vector<Subcommand> table = {
      {"mitsuba", RunExportMitsuba, "FITDIR OUT", "a Mitsuba 3 scene (scene.xml, textures, the layer's .vol grid)"},
      {"pbrt", RunExportPbrt, "FITDIR OUT", "a pbrt-v4 scene (scene.pbrt, textures)"},
      {"blender", RunExportBlender, "FITDIR OUT", "a Blender 3.4 Cycles scene script (scene.py, textures)"},
  };
  return table;
}

int RunExport(int argc, char** argv) { return DispatchSubcommand("export", ExportSubcommands(), argc, argv); }

}  // namespace thinslab
