// SPDX-License-Identifier: Apache-2.0
// Reading, writing and validating capture sessions (docs/format.md): the manifest
// (core/manifest_io.h), its semantic checks (core/session_validation.h) and the frame files
// (core/frame_io.h). Journal recovery: core/session_recovery.h.
#pragma once

#include "thinslab/core/frame_io.h"
#include "thinslab/core/manifest_io.h"
#include "thinslab/core/session_validation.h"
