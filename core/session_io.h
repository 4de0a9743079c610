// SPDX-License-Identifier: Apache-2.0
// Reading, writing and validating capture sessions (docs/format.md).
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

// Parses <session_dir>/session.json and validates it (ValidateSession). Every error names
// the file and the JSON field path, e.g. "s/session.json: rig.cameras[0].fx_px: expected a
// positive number, got -3".
Status ReadSession(const std::string& session_dir, Session* session);
// Writes <session_dir>/session.json atomically.
Status WriteSession(const std::string& session_dir, const Session& session);
// Semantic checks: known major version, positive intrinsics, unique frame indices, frames
// naming known cameras, ok frames having an existing file inside the folder.
Status ValidateSession(const Session& session, const std::string& session_dir);
// One frames[k] object (docs/format.md 2.4) as single-line JSON, and back (the acquisition
// journal stores frame records so). Parse errors start with `where`, e.g. "s/journal.log:12".
Status FrameRecordToJson(const FrameRecord& frame, std::string* json);
Status ParseFrameRecordJson(const std::string& json, const std::string& where, FrameRecord* frame);
// Human summary for `thinslab info`.
std::string SummarizeSession(const Session& session);

// Loads one frame as a single-channel float image in DN with the black level subtracted
// (PNG/TIFF 8/16-bit or EXR). Checks the size against the camera. Errors name the file.
Status LoadFrame(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                 Image* image_dn);
// Loads a frame's optional per-pixel variance (frame.variance_file; format 1.3) in the frame's
// units squared; an empty image when the frame declares none. Errors name the file.
Status LoadFrameVariance(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                         Image* variance);
// Encodes a DN image (before black level removal) as a 16-bit (bit_depth > 8) or 8-bit PNG
// and writes it atomically. Values are rounded and clamped to the bit depth.
Status WriteRawFrame(const std::string& path, const Image& raw_dn, int bit_depth);

}  // namespace thinslab
