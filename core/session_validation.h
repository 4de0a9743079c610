// SPDX-License-Identifier: Apache-2.0
// Semantic checks of a capture session and its summary for `thinslab info`.
#pragma once

#include <string>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

// Semantic checks: known major version, positive intrinsics, unique frame indices, frames
// naming known cameras, ok frames having an existing file inside the folder.
Status ValidateSession(const Session& session, const std::string& session_dir);
// Human summary for `thinslab info`.
std::string SummarizeSession(const Session& session);

}  // namespace thinslab
