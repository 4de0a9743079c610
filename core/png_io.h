// SPDX-License-Identifier: Apache-2.0
// PNG output: every PNG thinslab writes carries a "Software: thinslab <version>" text chunk,
// the mark by which core/output_guard.h knows a PNG as thinslab's own (and may replace it).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

// Encodes `image` (8- or 16-bit, 1 or 3 channels, OpenCV's BGR order) and writes it atomically.
Status WritePngAtomically(const std::string& path, const cv::Mat& image);

// The sRGB transfer function of a linear value, clamped to [0, 1].
double SrgbEncode(double linear);

// Channel `channel` of a linear radiance image as an 8-bit sRGB tile (white at `white`, each
// pixel drawn `scale` x `scale`) under a 28-px dark header holding `label`.
cv::Mat LabelledRadianceTile(const Image& radiance, int channel, double white, const std::string& label, int scale = 1);

// Tiles of equal height side by side, 6-px white gaps between them.
cv::Mat SideBySide(const std::vector<cv::Mat>& tiles);

}  // namespace thinslab
