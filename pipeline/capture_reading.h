// SPDX-License-Identifier: Apache-2.0
// How the fit and calibration pipelines read a capture: through the journal, and refusing one
// whose acquisition did not complete unless --allow-incomplete (core/session_recovery.h); and
// the record of what was read in their summary.json.
#pragma once

#include <nlohmann/json.hpp>

#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/session_recovery.h"

namespace thinslab {

// ReadCapture (refusing an incomplete capture unless allow_incomplete); an accepted incomplete
// capture is announced on stderr.
Status ReadCaptureForCommand(const std::string& session_dir, bool allow_incomplete, Session* session,
                             CaptureCompleteness* completeness = nullptr);

// ReadCaptureForCommand, then the camera response that applies to the capture's first camera
// (LoadCameraResponse: `response_path`, else SESSION/calib/response.json if present;
// *response_file "" = linear). Errors: no camera, or a response of another camera.
Status ReadCaptureAndResponse(const std::string& session_dir, bool allow_incomplete, const std::string& response_path,
                              Session* session, CameraResponse* response, std::string* response_file);

// A calibration command's single-file output: `out`, or SESSION/calib/<default_name> when
// `out` is "". Refused (core/output_guard.h) when it would replace an input outside
// SESSION/calib/ or a file thinslab did not write; `extra_inputs` are the command's other
// input files (the response.json it reads), which it must not replace either.
// The response file a command reads: `response_path`, or SESSION/calib/response.json.
std::string DefaultResponsePath(const std::string& session_dir, const std::string& response_path);
Status ResolveCalibOutputFile(const std::string& session_dir, const std::string& default_name,
                              const std::vector<std::string>& extra_inputs, std::string* out);

// Creates the folder `file` goes into, if missing: called right before the write, so that a
// refused or failed command leaves no empty SESSION/calib/ behind.
Status CreateParentFolder(const std::string& file);

// {"complete": bool, "state": string or null, "usable_frames", "planned_frames",
// "journaled_frames"} (docs/format.md section 9).
nlohmann::json CaptureSummaryJson(const CaptureCompleteness& completeness);

}  // namespace thinslab
