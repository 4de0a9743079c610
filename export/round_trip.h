// SPDX-License-Identifier: Apache-2.0
// `thinslab roundtrip CAPTURE` (issue #27 item 3): the fitted material exported to Blender,
// rendered under the capture's own rig and compared with the captured frames and with `thinslab
// predict`. Shadow-map captures with their `fit tau`: the scene is the rig of Gu et al. 2007
// Fig. 9a (export/render_scene.h ShadowRig) seen by the capture's camera (intrinsics and pose);
// Blender renders the board without the layer (reference), and with it twice with independent
// seeds (the renderer's own noise). Each camera pixel's rendered shadow is the render's ratio
// times the pixel's own clean signal, as `predict` builds its own (the projector's falloff, the
// camera's gain and vignetting cancel in the ratio).
// Writes OUT atomically: scene/ (the Blender scene, its textures, the renders and Blender's
// log), roundtrip.exr (channels rendered, predicted, measured, variance, render_variance, valid,
// tau, difference, clean, at the render's resolution), roundtrip.png (capture | render |
// difference | predict), difference.png (render - capture, diverging colours), summary.json and summary.txt (per
// fitted-tau region: render against capture, predict against capture, render against predict, with the noise levels),
// options.ini. Laser-lobe captures with their `fit phase`: export/lobe_round_trip.h; dot scans
// with their `fit dmf`: export/dot_round_trip.h.
#pragma once

#include <ostream>
#include <string>

#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct RoundTripRun {
  std::string session_dir;
  std::string fit_dir;  // "" = CAPTURE/fit/tau (shadow maps), CAPTURE/fit/phase (lobes), CAPTURE/fit/dmf (dots).
  std::string out_dir;              // "" = CAPTURE/fit/roundtrip.
  std::string blender = "blender";  // The Blender executable (a name on PATH or a path).
  // Cycles samples per pixel of each render; 0: the capture kind's default (32 for shadow maps,
  // 8192 for the laser probe's 16 x 16 pixels, 1024 for dots).
  int samples = 0;
  // Camera pixels per rendered pixel along each axis: the render has the capture's intrinsics
  // scaled by 1/downsample, and the capture's images are averaged over downsample^2 blocks.
  int downsample = 2;
  // Dot scans: the dots rendered, "x,y;x,y" [monitor px]; "" = the capture's validation dots.
  std::string dots;
  SessionCalibrationOptions calibration;
  bool allow_incomplete_capture = false;
  std::string options_ini;  // The command's effective options (options.ini, the outputs' digest).
  // The render's samples (three passes; read from Blender's log); cancelling stops Blender.
  ProgressCallback progress;

  Status Check() const;  // Errors name the option (--samples, --downsample, --blender).
};

Status RenderRoundTrip(const RoundTripRun& run, std::ostream& log);

}  // namespace thinslab
