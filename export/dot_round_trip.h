// SPDX-License-Identifier: Apache-2.0
// The dot-scan part of `thinslab roundtrip CAPTURE` (export/round_trip.h, issue #27 item 3): a
// dot-scan capture's `fit dmf` exported as the rough slab `thinslab export` writes (the
// equivalent analytic roughness of each point split between the two faces, one microfacet
// family, a clear dielectric of the fit's eta: export/scene_from_fit.h) and rendered by Blender
// under the capture's rig: its camera (pose, pinhole intrinsics, at 1/downsample resolution) and
// its monitor (the fit's monitor pose) lighting one dot at a time, a Lambertian disc of the dot's
// radius and the fit's median dot radiance, so the render is in the capture's DN/us. Per dot the
// render is compared with the capture's HDR merge of that dot and with `thinslab predict`'s image
// of it (Dai Eq. 12 with the fitted tabulated NDF), over the pixels of the lobe.
// Writes OUT atomically: scene/, dot_<k>.exr (rendered, predicted, measured, variance,
// render_variance, valid, difference at the render's resolution), roundtrip_dot<k>.png and
// difference_dot<k>.png, summary.json, summary.txt, options.ini.
#pragma once

#include <ostream>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/export/round_trip.h"

namespace thinslab {

// `session` is CAPTURE's manifest (kind dot_scan).
Status RenderDotRoundTrip(const RoundTripRun& run, const Session& session, std::ostream& log);

}  // namespace thinslab
