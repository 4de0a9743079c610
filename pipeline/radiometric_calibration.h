// SPDX-License-Identifier: Apache-2.0
// Radiometric calibration of a capture (issue #6), without CLI or device code: what
// `thinslab calib response|hdr|flat` run. Each reads the capture (never modifying its frames),
// writes into CAPTURE/calib/ (or `out`) atomically and logs what it did to `log`; warnings go to
// stderr. docs/format.md ("Radiometric calibration files") describes every file.
#pragma once

#include <ostream>
#include <string>

#include "thinslab/calib/flat_field.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/response_recovery.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/status.h"

namespace thinslab {

// `calib response`: the camera response curve from an exposure bracket of a static scene ->
// calib/response.json (calib/response_recovery.h).
struct CalibResponseRun {
  std::string session_dir;
  std::string out;                  // "" = SESSION/calib/response.json.
  std::string method = "debevec";   // Or "robertson".
  std::string kind;                 // Frame kind or group name of the bracket; "" = most exposures.
  std::string camera_id;            // "" = the first camera.
  ResponseRecoveryOptions options;  // method and saturation/black level are set from the above.
  bool allow_incomplete_capture = false;
  std::string options_ini;  // Its digest goes into response.json's provenance.
};
Status CalibrateResponse(const CalibResponseRun& run, std::ostream& log);

// `calib hdr`: every bracket of the capture merged to radiance + variance ->
// calib/hdr/<group>.exr, summary.json, options.ini (calib/hdr_merge.h).
struct CalibHdrRun {
  std::string session_dir;
  std::string out;                           // "" = SESSION/calib/hdr.
  std::string response_path;                 // "" = SESSION/calib/response.json if present; "linear".
  std::string weighting = "inverse-variance";  // Or "hat", "debevec".
  std::string kind;                          // "" = every non-dark kind.
  std::string camera_id;
  std::string exposures = "reported";        // Or "measured".
  double read_noise_dn = 1.0;                // When the capture has no dark frames.
  HdrMergeOptions options;
  bool allow_incomplete_capture = false;
  std::string options_ini;                   // Written as options.ini.
  ProgressCallback progress;                 // Groups merged; false cancels (core/progress.h).
};
Status CalibrateHdr(const CalibHdrRun& run, std::ostream& log);

// `calib flat`: the projector's flat field -> calib/flat_field.exr (calib/flat_field.h).
struct CalibFlatRun {
  std::string session_dir;
  std::string out;            // "" = SESSION/calib/flat_field.exr.
  std::string response_path;  // As CalibHdrRun::response_path.
  FlatFieldOptions options;
  bool allow_incomplete_capture = false;
  std::string options_ini;    // Its digest goes into the file's provenance.
};
Status CalibrateFlatField(const CalibFlatRun& run, std::ostream& log);

}  // namespace thinslab
