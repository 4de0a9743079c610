// SPDX-License-Identifier: Apache-2.0
// OpenEXR read/write of thinslab::Image. Channels keep their names; Image::attributes()
// become string attributes in the header (docs/format.md lists the ones thinslab writes).
#pragma once

#include <string>

#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/status.h"

namespace thinslab {

enum class ExrPixelType { kFloat, kHalf };

// Writes atomically (temporary file + rename). Refuses non-finite pixels, naming the
// channel and pixel, so a NaN never reaches an output map.
Status WriteExr(const std::string& path, const Image& image,
                ExrPixelType pixel_type = ExrPixelType::kFloat);

// Output maps, format 2.0 (docs/format.md "Output maps"): every channel `name` is stored as the
// layer channel "name.Y", so OpenImageIO, Nuke or Blender list them by layer; the primary map is
// repeated as the default-layer channel "Y", which is what cv::imread and image viewers show;
// integer channels (status, rung) are stored as 32-bit unsigned integers. The header carries the
// provenance (core/provenance.h) and `primary_channel`.
struct MapExrLayout {
  std::string primary;
  std::vector<std::string> integer_channels;
};
Status WriteMapExr(const std::string& path, const Image& map, const MapExrLayout& layout,
                   const Provenance& provenance);

// Reads every channel as float and the header's string and numeric attributes. Output maps come
// back under their plain names whatever the format version: in 2.0 files "name.Y" reads as
// "name" and the repeated "Y" is dropped; 1.0 files (flat names, JSON text attributes) have
// their renamed channels (tau_plain, alpha, residual) and numeric attributes translated.
// Errors (missing, truncated, corrupt) name the file.
Status ReadExr(const std::string& path, Image* image);

// The index of channel `name` of an image read from `file`; an error naming both when it is absent.
Status RequireChannel(const Image& image, const std::string& file, const std::string& name, int* index);
// The `count` finite values of numeric attribute `key`; an error naming the file and the key when
// it is absent, has another size or holds a non-finite value. `hint` ends the message (e.g. "fit
// again"), "" for none.
Status RequireNumericAttribute(const Image& image, const std::string& file, const std::string& key, size_t count,
                               std::vector<double>* values, const std::string& hint = "");

}  // namespace thinslab
