// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/capture_reading.h"

#include <filesystem>
#include <iostream>

#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

std::string DefaultResponsePath(const std::string& session_dir, const std::string& response_path) {
  return response_path.empty() ? JoinPath(JoinPath(session_dir, "calib"), "response.json") : response_path;
}

Status ResolveCalibOutputFile(const std::string& session_dir, const std::string& default_name,
                              const std::vector<std::string>& extra_inputs, std::string* out) {
  const std::string calib_dir = JoinPath(session_dir, "calib");
  if (out->empty()) *out = JoinPath(calib_dir, default_name);
  std::vector<InputPath> inputs = {{session_dir, {"calib"}}};
  for (const std::string& input : extra_inputs) inputs.push_back({input, {}});
  return CheckOutputFile(*out, inputs);
}

Status CreateParentFolder(const std::string& file) {
  const std::string parent = std::filesystem::path(file).parent_path().string();
  return parent.empty() || DirectoryExists(parent) ? Status::Ok() : CreateDirectories(parent);
}

Status ReadCaptureForCommand(const std::string& session_dir, bool allow_incomplete, Session* session,
                             CaptureCompleteness* completeness) {
  CaptureCompleteness c;
  THINSLAB_RETURN_IF_ERROR(ReadCapture(session_dir, allow_incomplete ? IncompleteCapture::kAccept : IncompleteCapture::kRefuse, session, &c));
  if (!c.complete()) {
    std::cerr << "warning: " << session_dir << ": processing an incomplete capture (" << c.Describe() << ")\n";
  }
  if (completeness != nullptr) *completeness = c;
  return Status::Ok();
}

Status ReadCaptureAndResponse(const std::string& session_dir, bool allow_incomplete, const std::string& response_path,
                              Session* session, CameraResponse* response, std::string* response_file) {
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, allow_incomplete, session));
  if (session->rig.cameras.empty()) {
    return Status::Error(JoinPath(session_dir, kSessionManifestName) + ": rig.cameras: no camera");
  }
  return LoadCameraResponse(session_dir, response_path, session->rig.cameras[0], response, response_file);
}

nlohmann::json CaptureSummaryJson(const CaptureCompleteness& c) {
  nlohmann::json j;
  j["complete"] = c.complete();
  j["state"] = c.acquired ? nlohmann::json(c.state) : nlohmann::json(nullptr);
  j["usable_frames"] = c.usable_frames;
  j["planned_frames"] = c.planned_frames;
  j["journaled_frames"] = c.journaled_frames;
  return j;
}

}  // namespace thinslab
