// SPDX-License-Identifier: Apache-2.0
// What both render round trips (export/round_trip.h: shadow maps; export/lobe_round_trip.h:
// laser lobes) write the same way: the pictures, the closing files and the figures' format.
#pragma once

#include <nlohmann/json.hpp>
#include <ostream>
#include <string>

#include "thinslab/core/file.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

// A relative figure for summary.txt: fixed digits, "-" for a negative (not measured) value.
std::string RoundTripFigure(double value, int digits = 4);

// roundtrip.png (capture | Blender | |Blender - capture| x 5 | predict on one grey scale, white at
// `white`) and difference.png (Blender - capture, diverging colours at +-10 % of `white`) in
// `dir`, from channels of `images` (pixels whose `valid` channel is 0 are left out of the
// difference picture).
struct RoundTripChannels {
  int measured = 0, rendered = 0, predicted = 0, difference = 0, valid = 0;
};
Status WriteRoundTripPictures(const std::string& dir, const Image& images, const RoundTripChannels& channels,
                              double white);

// summary.json, summary.txt and options.ini (when given) into `out`, which is then committed; the
// text also goes to `log` with the output folder.
Status FinishRoundTrip(StagedDirectory* out, const nlohmann::json& summary, const std::string& text,
                       const std::string& options_ini, std::ostream& log);

}  // namespace thinslab
