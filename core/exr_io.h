// SPDX-License-Identifier: Apache-2.0
// OpenEXR read/write of thinslab::Image. Channels keep their names; Image::attributes()
// become string attributes in the header (docs/format.md lists the ones thinslab writes).
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

enum class ExrPixelType { kFloat, kHalf };

// Writes atomically (temporary file + rename). Refuses non-finite pixels, naming the
// channel and pixel, so a NaN never reaches an output map.
Status WriteExr(const std::string& path, const Image& image,
                ExrPixelType pixel_type = ExrPixelType::kFloat);
// Reads every channel as float. Errors (missing, truncated, corrupt) name the file.
Status ReadExr(const std::string& path, Image* image);

}  // namespace thinslab
