// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/round_trip_outputs.h"

#include <cmath>
#include <sstream>

#include "thinslab/core/false_color.h"
#include "thinslab/core/png_io.h"

namespace thinslab {

std::string RoundTripFigure(double value, int digits) {
  if (value < 0) return "-";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << value;
  return s.str();
}

Status WriteRoundTripPictures(const std::string& dir, const Image& images, const RoundTripChannels& channels,
                              double white) {
  const int w = images.width(), h = images.height();
  Image magnified_difference(w, h), invalid(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      magnified_difference.at(x, y) = 5 * std::abs(images.at(x, y, channels.difference));
      invalid.at(x, y) = images.at(x, y, channels.valid) > 0 ? 0.0f : 1.0f;
    }
  }
  THINSLAB_RETURN_IF_ERROR(
      WritePngAtomically(JoinPath(dir, "roundtrip.png"),
                         SideBySide({LabelledRadianceTile(images, channels.measured, white, "capture"),
                                     LabelledRadianceTile(images, channels.rendered, white, "Blender"),
                                     LabelledRadianceTile(magnified_difference, 0, white, "|diff| x5"),
                                     LabelledRadianceTile(images, channels.predicted, white, "predict")})));
  FalseColorOptions difference_colors;
  difference_colors.scale_kind = ColorScale::kDiverging;
  difference_colors.min_value = -0.1 * white;
  difference_colors.max_value = 0.1 * white;
  difference_colors.label = "render - capture";
  return WriteFalseColorPng(JoinPath(dir, "difference.png"), images, channels.difference, &invalid, difference_colors);
}

Status FinishRoundTrip(StagedDirectory* out, const nlohmann::json& summary, const std::string& text,
                       const std::string& options_ini, std::ostream& log) {
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.json"), summary.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.txt"), text));
  if (!options_ini.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "options.ini"), options_ini));
  }
  THINSLAB_RETURN_IF_ERROR(out->Commit());
  log << text << "wrote " << out->final_path() << "\n";
  return Status::Ok();
}

}  // namespace thinslab
