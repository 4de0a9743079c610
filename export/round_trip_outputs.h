// SPDX-License-Identifier: Apache-2.0
// What the render round trips (export/round_trip.h: shadow maps; export/lobe_round_trip.h: laser
// lobes; export/dot_round_trip.h: dot scans) share: the capture's camera, the pictures, the
// closing files and the figures' format.
#pragma once

#include <nlohmann/json.hpp>
#include <ostream>
#include <string>

#include "thinslab/core/file.h"
#include "thinslab/core/image.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"

namespace thinslab {

// The capture's camera at 1/downsample resolution in `scene` (pose, pinhole intrinsics: an n x n
// block of camera pixels is one rendered pixel, centres mapping as (c + 0.5) / n - 0.5). Refuses a
// camera with lens distortion (Blender renders a pinhole) and a downsample that leaves fewer than
// 8 px per side, naming `manifest` or --downsample.
Status SetCaptureCamera(const CameraInfo& camera, int downsample, const std::string& manifest, RenderScene* scene);

// The fit a round trip renders: `given` (--fit), else CAPTURE/fit/<folder>; an error naming the
// folder and `fit_command` when it lacks `required_file`.
Status ResolveRoundTripFit(const std::string& session_dir, const std::string& given, const std::string& folder,
                           const std::string& required_file, const std::string& capture_kind,
                           const std::string& fit_command, std::string* fit_dir);
// `given` (--out), else CAPTURE/fit/roundtrip.
std::string RoundTripOutDir(const std::string& session_dir, const std::string& given);
// The scene folder of a round trip: `staged_dir`/scene with the Blender scene written there with
// `provenance`; *scene_dir is that folder, *render_prefix the render's file prefix (scene/render).
Status WriteRoundTripScene(const RenderScene& scene, const std::string& staged_dir, const Provenance& provenance,
                           std::string* scene_dir, std::string* render_prefix);

// summary.json's first fields: format, provenance, kind, session, fit, renderer, samples.
nlohmann::json RoundTripSummaryHead(const std::string& kind, const Provenance& provenance,
                                    const std::string& session_dir, const std::string& fit_dir, int samples);

// A relative figure for summary.txt: fixed digits, "-" for a negative (not measured) value.
std::string RoundTripFigure(double value, int digits = 4);

// roundtrip.png (capture | Blender | |Blender - capture| x 5 | predict on one grey scale, white at
// `white`) and difference.png (Blender - capture, diverging colours at +-10 % of `white`) in
// `dir`, from channels of `images` (pixels whose `valid` channel is 0 are left out of the
// difference picture).
struct RoundTripChannels {
  int measured = 0, rendered = 0, predicted = 0, difference = 0, valid = 0;
};
// `suffix` goes before the extension (roundtrip_dot0.png).
Status WriteRoundTripPictures(const std::string& dir, const Image& images, const RoundTripChannels& channels,
                              double white, const std::string& suffix = "");

// summary.json, summary.txt and options.ini (when given) into `out`, which is then committed; the
// text also goes to `log` with the output folder.
Status FinishRoundTrip(StagedDirectory* out, const nlohmann::json& summary, const std::string& text,
                       const std::string& options_ini, std::ostream& log);

}  // namespace thinslab
