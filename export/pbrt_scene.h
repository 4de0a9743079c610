// SPDX-License-Identifier: Apache-2.0
// A pbrt-v4 scene of a RenderScene (pbrt-v4's file format reference): the slab's faces are
// `trianglemesh`es with a `dielectric` material whose `roughness` is an `imagemap` float
// texture (alpha as given: `remaproughness` false); a layer is a `uniformgrid` medium (density =
// tau, sigma_a and sigma_s per metre of the layer's thickness, HG g) inside a box with the
// `interface` material; the backlight is a `diffuse` area light.
// pbrt-v4's dielectric has only the Trowbridge-Reitz (GGX) distribution: a Beckmann fit is
// exported with its alpha as GGX alpha (a note in the file says so).
// pbrt-v4 looks image textures up at t flipped (row 0 at t = 1), so the meshes carry
// t = 1 - (y - min y) / height; the world is mirrored in x by `Scale -1 1 1` before `LookAt`
// because pbrt's camera space is left-handed and the sample frame right-handed.
#pragma once

#include <string>

#include "thinslab/core/provenance.h"
#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"
#include "thinslab/export/scene_textures.h"

namespace thinslab {

std::string PbrtScene(const RenderScene& scene, const SceneTextures& textures);

// DIR/scene.pbrt and DIR/textures/*.exr.
Status WritePbrtScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance);

}  // namespace thinslab
