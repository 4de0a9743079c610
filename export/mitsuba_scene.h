// SPDX-License-Identifier: Apache-2.0
// A Mitsuba 3 scene of a RenderScene (scene format version 3.0.0; Mitsuba's plugin reference):
// the slab's faces are `rectangle`s with `roughdielectric` BSDFs whose `alpha` is a raw `bitmap`
// texture; a layer is a `cube` with a `null` BSDF around a `heterogeneous` medium whose sigma_t
// is a `gridvolume` (.vol, Mitsuba's binary grid format) and whose phase function is `hg`; the
// backlight is a rectangle `area` emitter; the camera a `perspective` sensor.
// A rectangle's uv is ((x + 1) / 2, (y + 1) / 2) of its local square, so uv (0, 0) is the grid's
// (min x, min y) corner, and a bitmap's row 0 is v = 0: the textures need no flip.
#pragma once

#include <string>

#include "thinslab/core/provenance.h"
#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"
#include "thinslab/export/scene_textures.h"

namespace thinslab {

std::string MitsubaSceneXml(const RenderScene& scene, const SceneTextures& textures, const std::string& volume_file);

// Mitsuba's .vol grid (version 3, float32, one channel) of sigma_t = tau / thickness [1/m] over
// the layer's box: nz = 2 equal slices (trilinear lookups need two), x fastest, then y, then z.
std::string MitsubaVolumeBytes(const SceneGrid& grid, const ScatteringLayer& layer);

// DIR/scene.xml, DIR/textures/*.exr and, for a layer, DIR/layer_sigma_t.vol.
Status WriteMitsubaScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance);

}  // namespace thinslab
