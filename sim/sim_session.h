// SPDX-License-Identifier: Apache-2.0
// Start of every simulated capture: refuses an existing non-empty folder (a simulation never
// appends to or overwrites a capture) and opens a SessionWriter with the rig description.
#pragma once

#include <filesystem>
#include <string>

#include "acquire/session_writer.h"
#include "core/session.h"
#include "core/version.h"

namespace thinslab {

inline Status OpenSimulatedSession(const std::string& session_dir, const std::string& name, const std::string& kind,
                                   const RigInfo& rig, SessionWriter* writer) {
  std::error_code ec;
  if (std::filesystem::exists(session_dir, ec) && !std::filesystem::is_empty(session_dir, ec)) {
    return Status::Error(session_dir + ": output session folder exists and is not empty");
  }
  Session header;
  header.name = name;
  header.kind = kind;
  header.software = std::string("thinslab ") + THINSLAB_VERSION_STRING + " sim (" + THINSLAB_GIT_HASH + ")";
  header.rig = rig;
  return writer->Open(session_dir, header);
}

}  // namespace thinslab
