// SPDX-License-Identifier: Apache-2.0
// `thinslab check CAPTURE`: the session check of pipeline/capture_check.h for a capture on disk
// (`thinslab acquire` runs the same check at the end of every session).
#include <iostream>

#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/pipeline/capture_check.h"
#include "thinslab/pipeline/capture_reading.h"

namespace thinslab {

void AddCaptureCheckOptions(OptionParser* parser, CaptureCheckOptions* options) {
  parser->AddString(
      "response", &options->response_path,
      "camera response: a response.json, \"linear\", or empty for CAPTURE/calib/response.json if present");
  parser->AddDouble("max-saturated-fraction", &options->max_saturated_fraction,
                    "re-take when a state's shortest exposure has more than this fraction of a frame saturated");
  parser->AddDouble("min-peak-sigmas", &options->min_peak_sigmas,
                    "a lit state whose peak in its longest exposure is below this many noise sigmas shows nothing");
  parser->AddDouble(
      "min-range-fraction", &options->min_range_fraction,
      "warn when a kind's brightest state peaks below this fraction of the range in the longest exposure");
  parser->AddDouble("max-dark-fraction", &options->max_dark_fraction,
                    "warn when the dark frame's 99th percentile exceeds this fraction of the range");
  parser->AddDouble(
      "max-moved-fraction", &options->max_moved_fraction,
      "re-take when two frames of one state differ beyond the noise in more than this fraction of pixels");
  parser->AddDouble(
      "max-brightness-change", &options->max_brightness_change,
      "re-take when a frame's brightness is off its state's neighbours (and exposure ratio) by more than this");
  parser->AddDouble("max-spot-offset-mm", &options->max_spot_offset_mm,
                    "warn when the laser spot is further than this from where the manifest puts the beam [mm]");
  parser->AddDouble("min-dots-found-fraction", &options->min_dots_found_fraction,
                    "warn when fewer of the dots in view are found in the all-dots frame");
  parser->AddDouble("min-lit-fraction", &options->min_lit_fraction,
                    "re-take when less of the fitted board region is in view and lit in the reference / flat frame");
  parser->AddDouble("outlier-sigmas", &options->pair.outlier_sigmas,
                    "a pixel of a frame pair differs when its residual exceeds this many noise sigmas");
}

int RunCheck(int argc, char** argv) {
  std::string session_dir, json_path;
  CaptureCheckOptions options;
  OptionParser parser("check");
  parser.AddPositional("CAPTURE", &session_dir, "capture session folder (holding session.json)");
  parser.AddString("json", &json_path, "also write the check as JSON to this file (e.g. CAPTURE/calib/check.json)");
  AddCaptureCheckOptions(&parser, &options);
  parser.SetHelpFooter(
      "Exit status: 0 when the verdict is \"good\" or \"usable\", 3 when it is \"retake\", 1 on an error.");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && !json_path.empty()) status = CheckOutputFile(json_path, {{session_dir, {"fit", "calib"}}});
  CaptureCheck check;
  if (status.ok()) status = CheckCapture(session_dir, options, &check);
  if (status.ok() && !json_path.empty()) status = CreateParentFolder(json_path);
  if (status.ok() && !json_path.empty()) {
    status = WriteFileAtomically(json_path, check.ToJson().dump(2) + "\n").WithContext("option --json");
  }
  if (!status.ok()) return CommandFailed(status);
  std::cout << check.Describe();
  return check.verdict() == "retake" ? kCheckRetakeExitCode : 0;
}

}  // namespace thinslab
