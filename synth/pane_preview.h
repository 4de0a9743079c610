// SPDX-License-Identifier: Apache-2.0
// What a synthesized contamination layer does on a window: renders the layer on a thin glass
// pane (Gu et al. 2007, Appendix "thin transparent slab", optics/dirty_glass_layer.h with
// Fresnel at every interface) over a background image, in canonical situations of Fig. 8
// (Sec. 4): a window in daytime (bright scene behind, dim room), a window at night (dark
// scene behind, lit room on the viewer's side) and a collimated beam from the side. The
// contrast reversal of Sec. 4 (contaminant darker than clean glass against a bright
// background, brighter under scattering) follows from the model, not from the renderer.
//
// Geometry (docs/conventions.md frames): the layer is on the outside face (+z, towards the
// scene and the sky); the camera looks through the pane from the room, along +z, so it sees
// radiance leaving along wo = (0, 0, -1). Image rows follow sample +y, "up" is -y. Each pixel:
//   L = T_spec(wi = +z) B(x, y)                      Eq. 5 (+ Appendix): the scene, attenuated
//     + R_spec(wi = -z) L_room                       Eqs. 1, 2 (+ Appendix): the room, mirrored
//     + sum_lights f(wi_l, wo) E_l |wi_l . z|        Eqs. 3, 4, 6: single scattering of lights
// with unit-sum radiances in arbitrary linear units.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PaneLight {
  Eigen::Vector3d dir_to_light;  // Unit, pointing from the pane to the light (wi).
  double irradiance = 1;         // Normal to the beam, linear units.
};

struct PaneScene {
  std::string name;
  double background_scale = 1;  // Radiance of the background image, times its values.
  double room_radiance = 0;     // Radiance of the room, seen mirrored in the pane.
  std::vector<PaneLight> lights;
};

// Fig. 8 rows 1, 2 and 5 (Sec. 4): "daylight_window", "night_window", "side_light".
std::vector<PaneScene> CanonicalPaneScenes();

struct PanePreviewOptions {
  double glass_index = 1.5;  // n3 of the pane.
  int max_size_px = 512;     // The layer is box-filtered down to at most this per side.
};

// A background for the preview: sky (bright, upper ~55%) over dark ground with a few darker
// buildings, linear luminance "Y" in [0, 1].
Image ProceduralBackground(int width, int height);

// Renders one scene. `layer` has channels tau, g, albedo, n2; `background` one channel, any
// size (resampled to the layer). `clean` (optional) receives the same view of a clean pane.
// Output: one channel "Y", linear radiance.
Status RenderPaneView(const Image& layer, const Image& background, const PaneScene& scene,
                      const PanePreviewOptions& options, Image* radiance, Image* clean);

struct PanePreviewPanel {
  std::string scene;
  // Mean over contaminated pixels (tau > 0.05) of rendered / clean radiance, split by the
  // background brightness (above / below its median): < 1 darker, > 1 brighter than clean glass.
  double contrast_bright_background = 1, contrast_dark_background = 1;
};

// Renders the canonical scenes side by side (each tone-mapped by its 99th percentile, sRGB) with labels and writes the
// PNG atomically. `background` empty = procedural.
Status WritePanePreview(const std::string& png_path, const Image& layer, const Image& background,
                        const PanePreviewOptions& options, std::vector<PanePreviewPanel>* panels);

// Loads a background: EXR (channel Y, or R,G,B as luminance; linear) or an 8/16-bit image
// file (PNG/JPEG, sRGB-decoded to linear luminance).
Status ReadBackgroundImage(const std::string& path, Image* background);

}  // namespace thinslab
