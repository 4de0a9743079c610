// SPDX-License-Identifier: Apache-2.0
// Reading and writing a capture's session.json (docs/format.md section 2).
#pragma once

#include <string>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

// Parses <session_dir>/session.json and validates it (ValidateSession). Every error names
// the file and the JSON field path, e.g. "s/session.json: rig.cameras[0].fx_px: expected a
// positive number, got -3".
Status ReadSession(const std::string& session_dir, Session* session);
// Writes <session_dir>/session.json atomically.
Status WriteSession(const std::string& session_dir, const Session& session);
// One frames[k] object (docs/format.md 2.4) as single-line JSON, and back (the acquisition
// journal stores frame records so). Parse errors start with `where`, e.g. "s/journal.log:12".
Status FrameRecordToJson(const FrameRecord& frame, std::string* json);
Status ParseFrameRecordJson(const std::string& json, const std::string& where, FrameRecord* frame);
}  // namespace thinslab
