// SPDX-License-Identifier: Apache-2.0
// A Blender (3.4, Cycles) Python script that builds a RenderScene: the slab's faces are planes
// with a Glass BSDF (GGX or Beckmann as fitted) whose roughness is sqrt(alpha) of an image
// texture (Cycles squares its roughness input); a layer is a box with Volume Scatter (density
// albedo tau / thickness, anisotropy g) plus Volume Absorption ((1 - albedo) tau / thickness),
// the density read from the tau texture at the box's generated coordinates; the backlight an
// emissive plane; the camera the scene's. Blender reads images with row 0 at the top, v = 1, so
// the planes' uv run v = 1 - (y - min y) / height.
//
//   blender -b --factory-startup --python-exit-code 1 --python scene.py -- [--save FILE.blend] [--render FILE.png]
//           [--samples N] [--resolution-percent P]
#pragma once

#include <string>

#include "thinslab/core/provenance.h"
#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"
#include "thinslab/export/scene_textures.h"

namespace thinslab {

std::string BlenderScript(const RenderScene& scene, const SceneTextures& textures);

// DIR/scene.py and DIR/textures/*.exr.
Status WriteBlenderScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance);

}  // namespace thinslab
