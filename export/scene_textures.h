// SPDX-License-Identifier: Apache-2.0
// The maps a scene loads, written once for every renderer: single-channel float OpenEXR files
// (channel Y, no default-layer tricks: every renderer's image loader reads them), row 0 at the
// grid's smallest y. Each scene writer maps its renderer's texture coordinates onto that.
#pragma once

#include <string>

#include "thinslab/core/provenance.h"
#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"

namespace thinslab {

struct SceneTextures {
  // Paths relative to the scene folder, "" when the scene has no such map.
  std::string top_alpha, bottom_alpha, tau;
};

Status WriteSceneTextures(const RenderScene& scene, const std::string& dir, const Provenance& provenance,
                          SceneTextures* textures);

// A number as scene files write it: shortest round-trip form ("%.9g").
std::string SceneNumber(double value);

// The grid's corners on z, counter-clockwise seen from +z: (min x, min y), (max x, min y),
// (max x, max y), (min x, max y).
struct GridQuad {
  Eigen::Vector3d corner[4];
};
GridQuad QuadAt(const SceneGrid& grid, double z);

}  // namespace thinslab
