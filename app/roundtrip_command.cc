// SPDX-License-Identifier: Apache-2.0
// `thinslab roundtrip CAPTURE` (export/round_trip.h runs it; this file parses its options): the
// fitted material rendered by Blender under the capture's own rig, against the capture's frames
// and `thinslab predict` (issue #27 item 3).
#include <iostream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/command_progress.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/export/round_trip.h"

namespace thinslab {

int RunRoundTrip(int argc, char** argv) {
  RoundTripRun run;
  OptionParser parser("roundtrip");
  parser.AddPositional("CAPTURE", &run.session_dir,
                       "shadow-map, laser-lobe or dot-scan capture whose rig the render reproduces");
  parser.AddString("fit", &run.fit_dir,
                   "output folder of `thinslab fit tau`, `fit phase` or `fit dmf` (default CAPTURE/fit/tau, phase or "
                   "dmf by the capture's kind)");
  parser.AddString("out", &run.out_dir, "output folder (default CAPTURE/fit/roundtrip)");
  parser.AddString("blender", &run.blender, "the Blender executable (a name on PATH or a path)");
  parser.AddInt("samples", &run.samples,
                "Cycles samples per pixel of each render (0: 32 for shadow maps, 8192 for laser lobes, 1024 for dots)");
  parser.AddInt("downsample", &run.downsample, "camera pixels per rendered pixel along each axis");
  parser.AddString("dots", &run.dots,
                   "dot scans: the dots to render, 'x,y;x,y' in monitor px (default the capture's validation dots)");
  AddCalibrationOptions(&parser, &run.calibration);
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  run.progress = CommandProgress();
  if (status.ok()) status = RenderRoundTrip(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

}  // namespace thinslab
