// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/calibration_options.h"

#include <cstdio>

#include "thinslab/app/option_parser.h"

namespace thinslab {

void AddCalibrationOptions(OptionParser* parser, SessionCalibrationOptions* options) {
  parser->AddString("calibration", &options->mode,
                    "'auto': apply CAPTURE/calib/rig.json and response.json where present; 'none': the manifest's "
                    "geometry and a linear camera");
  parser->AddString("rig", &options->rig_path, "rig.json to apply (default CAPTURE/calib/rig.json if present)");
  parser->AddString("response", &options->response_path,
                    "response.json that linearises the frames, or 'linear' (default CAPTURE/calib/response.json if "
                    "present)");
}

void AddDotDetectionOptions(OptionParser* parser, DotGeometryOptions* options, double* dot_radius_px) {
  parser->AddDouble("dot-radius-px", dot_radius_px,
                    "radius of a displayed dot [monitor px]; 0 = the manifest's rig.monitor.dot_radius_px, else 2");
  parser->AddDouble("threshold-sigma", &options->threshold_sigma,
                    "all-dots frame: a dot's smoothed peak at least this many noise sigmas above the local background");
  parser->AddDouble("threshold-fraction", &options->threshold_fraction,
                    "all-dots frame: ... and at least this fraction of the brightest dot's peak");
  parser->AddDouble("min-peak-fraction", &options->min_peak_fraction,
                    "all-dots frame: ... and at least this fraction of the median dot's peak");
  parser->AddInt("min-blob-area-px", &options->min_blob_area_px,
                 "all-dots frame: ... with at least this many pixels above the threshold");
  parser->AddDouble("peak-separation-fraction", &options->peak_separation_fraction,
                    "all-dots frame: maxima closer than this fraction of the displayed dot spacing are one dot");
  parser->AddInt("window-margin-px", &options->window_margin_px,
                 "all-dots frame: centroid window = a dot's image radius plus this [camera px]");
  parser->AddInt("background-window-px", &options->background_window_px,
                 "all-dots frame: side of the local background's window [camera px]; 0 = from the dot size");
  parser->AddDouble("match-gate-fraction", &options->match_gate_fraction,
                    "all-dots frame: a dot matches the grid within this fraction of the local spacing");
}

Status CheckDotRadiusOption(const OptionParser& parser, double dot_radius_px) {
  if (parser.IsSet("dot-radius-px") && !(dot_radius_px > 0 && dot_radius_px <= 1000)) {
    return Status::Error("--dot-radius-px: must be in (0, 1000] monitor px, got " + std::to_string(dot_radius_px));
  }
  return Status::Ok();
}

}  // namespace thinslab
