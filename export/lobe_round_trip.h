// SPDX-License-Identifier: Apache-2.0
// The laser-lobe half of `thinslab roundtrip CAPTURE` (export/round_trip.h, issue #27 item 3):
// a laser-lobe capture's `fit phase` (g, tau, and the albedo it was given) exported as a uniform
// Henyey-Greenstein layer and rendered by Blender under the capture's rig (Gu et al. 2007 Fig.
// 9b: the beam's radius and direction, the board distance), by reciprocity
// (export/render_scene.h LaserProbe): one light group per measured ring. The rendered rings are
// compared with the capture's rings and with `thinslab predict` (Eq. 8) per band of angle, with
// one free scale (the fit's beta holds the beam's power, the albedo and the camera's gain, which
// the render does not know), and imaged back in the capture's camera.
// Writes OUT atomically: scene/ (the Blender scene, the renders, Blender's log), lobe_rings.csv,
// roundtrip.exr (camera pixels: rendered, predicted, measured, variance, valid, difference),
// roundtrip.png (capture | Blender | |difference| x 5 | predict), difference.png, summary.json,
// summary.txt, options.ini.
#pragma once

#include <ostream>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/export/round_trip.h"

namespace thinslab {

// `session` is CAPTURE's manifest (kind laser_lobe).
Status RenderLobeRoundTrip(const RoundTripRun& run, const Session& session, std::ostream& log);

}  // namespace thinslab
