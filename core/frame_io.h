// SPDX-License-Identifier: Apache-2.0
// A capture's frame files (docs/format.md sections 3-4).
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

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
