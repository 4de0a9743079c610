// SPDX-License-Identifier: Apache-2.0
// PNG output: every PNG thinslab writes carries a "Software: thinslab <version>" text chunk,
// the mark by which core/output_guard.h knows a PNG as thinslab's own (and may replace it).
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

// Encodes `image` (8- or 16-bit, 1 or 3 channels, OpenCV's BGR order) and writes it atomically.
Status WritePngAtomically(const std::string& path, const cv::Mat& image);

}  // namespace thinslab
