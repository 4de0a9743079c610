// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/scene_textures.h"

#include <cstdio>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {

namespace {

Status WriteTexture(const Image& map, const std::string& dir, const std::string& name, const SceneGrid& grid,
                    const Provenance& provenance, std::string* relative_path) {
  Image texture = map;
  StampProvenance(provenance, &texture);
  texture.numeric_attributes()["grid_min_m"] = {grid.min_m.x(), grid.min_m.y()};
  texture.numeric_attributes()["pixel_pitch_m"] = {grid.pitch_m};
  *relative_path = "textures/" + name + ".exr";
  return WriteExr(JoinPath(dir, *relative_path), texture);
}

}  // namespace

Status WriteSceneTextures(const RenderScene& scene, const std::string& dir, const Provenance& provenance,
                          SceneTextures* textures) {
  *textures = SceneTextures();
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(JoinPath(dir, "textures")));
  if (scene.slab) {
    THINSLAB_RETURN_IF_ERROR(
        WriteTexture(scene.slab->top_alpha, dir, "top_alpha", scene.grid, provenance, &textures->top_alpha));
    THINSLAB_RETURN_IF_ERROR(
        WriteTexture(scene.slab->bottom_alpha, dir, "bottom_alpha", scene.grid, provenance, &textures->bottom_alpha));
  }
  if (scene.layer && !scene.layer->tau.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteTexture(scene.layer->tau, dir, "tau", scene.grid, provenance, &textures->tau));
  }
  return Status::Ok();
}

std::string SceneNumber(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.9g", value);
  return text;
}

GridQuad QuadAt(const SceneGrid& grid, double z) {
  const Eigen::Vector2d lo = grid.min_m, hi = grid.min_m + grid.size_m();
  return {{Eigen::Vector3d(lo.x(), lo.y(), z), Eigen::Vector3d(hi.x(), lo.y(), z), Eigen::Vector3d(hi.x(), hi.y(), z),
           Eigen::Vector3d(lo.x(), hi.y(), z)}};
}

}  // namespace thinslab
