// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/pbrt_scene.h"

#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"

namespace thinslab {

namespace {

std::string Triple(const Eigen::Vector3d& v) {
  return SceneNumber(v.x()) + " " + SceneNumber(v.y()) + " " + SceneNumber(v.z());
}

// The grid's rectangle at z as two triangles with uv, normal +z (counter-clockwise seen from +z)
// or -z.
std::string QuadMesh(const SceneGrid& grid, double z, bool normal_down) {
  const GridQuad quad = QuadAt(grid, z);
  std::ostringstream out;
  out << "  Shape \"trianglemesh\"\n    \"point3 P\" [";
  for (int k = 0; k < 4; ++k) out << (k ? "  " : " ") << Triple(quad.corner[k]);
  // Texture row 0 (min y) is at t = 1 in pbrt-v4's image lookups.
  out << " ]\n    \"point2 uv\" [ 0 1  1 1  1 0  0 0 ]\n"
      << (normal_down ? "    \"integer indices\" [ 0 2 1  0 3 2 ]\n" : "    \"integer indices\" [ 0 1 2  0 2 3 ]\n");
  return out.str();
}

// The layer's box, every face's normal outwards (pbrt puts a medium interface's "inside" on the
// side opposite the normal).
std::string BoxMesh(const SceneGrid& grid, double z0, double z1) {
  const GridQuad lo = QuadAt(grid, z0), hi = QuadAt(grid, z1);
  std::ostringstream out;
  out << "  Shape \"trianglemesh\"\n    \"point3 P\" [";
  for (int k = 0; k < 4; ++k) out << " " << Triple(lo.corner[k]);
  for (int k = 0; k < 4; ++k) out << " " << Triple(hi.corner[k]);
  // Vertices 0-3 the bottom (counter-clockwise from +z), 4-7 the top.
  out << " ]\n    \"integer indices\" [ 0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  "
         "3 0 4  3 4 7 ]\n";
  return out.str();
}

}  // namespace

std::string PbrtScene(const RenderScene& scene, const SceneTextures& textures) {
  const SceneCamera camera = CameraOf(scene);
  std::ostringstream out;
  out << "# thinslab export pbrt of " << scene.source << " (docs/export.md).\n"
      << "# Units: metres. Frame: the sample plane is z = 0, the camera on +z, the backlight on -z.\n";
  for (const std::string& note : scene.notes) out << "# - " << note << "\n";
  if (scene.slab && scene.slab->distribution != "ggx") {
    out << "# - pbrt-v4's dielectric has only Trowbridge-Reitz (GGX): the " << scene.slab->distribution
        << " alpha maps are used as GGX alpha\n";
  }
  const bool wide = scene.image_width >= scene.image_height;
  const double fov_short_axis = wide ? FovY(scene.fov_x_rad, scene.image_width, scene.image_height) : scene.fov_x_rad;
  out << "# Render: pbrt scene.pbrt\n\n"
      << "Scale -1 1 1\n"
      << "LookAt " << Triple(camera.eye) << "  " << Triple(camera.target) << "  " << Triple(camera.up) << "\n"
      << "Camera \"perspective\" \"float fov\" [ " << SceneNumber(fov_short_axis * 180 / kPi) << " ]\n"
      << "Film \"rgb\" \"integer xresolution\" [ " << scene.image_width << " ] \"integer yresolution\" [ "
      << scene.image_height << " ] \"string filename\" [ \"render.exr\" ]\n"
      << "Sampler \"zsobol\" \"integer pixelsamples\" [ 256 ]\n"
      << "Integrator \"volpath\" \"integer maxdepth\" [ 64 ]\n\n"
      << "WorldBegin\n\n";
  if (scene.slab) {
    const RoughSlab& slab = *scene.slab;
    for (const auto& [name, file] :
         {std::make_pair("top_alpha", textures.top_alpha), std::make_pair("bottom_alpha", textures.bottom_alpha)}) {
      out << "Texture \"" << name << "\" \"float\" \"imagemap\" \"string filename\" [ \"" << file
          << "\" ] \"string filter\" [ \"point\" ]\n";
    }
    for (const auto& [comment, texture, z, down] :
         {std::make_tuple("camera-side face (z = 0, normal +z)", "bottom_alpha", 0.0, false),
          std::make_tuple("monitor-side face (z = -thickness, normal -z)", "top_alpha", -slab.thickness_m, true)}) {
      out << "\n# The slab's " << comment << "\nAttributeBegin\n"
          << "  Material \"dielectric\" \"float eta\" [ " << SceneNumber(slab.eta) << " ] \"texture roughness\" \""
          << texture << "\" \"bool remaproughness\" false\n"
          << QuadMesh(scene.grid, z, down) << "AttributeEnd\n";
    }
  }
  if (scene.layer) {
    const ScatteringLayer& layer = *scene.layer;
    const Eigen::Vector2d hi = scene.grid.min_m + scene.grid.size_m();
    out << "\n# The layer (0 < z < " << SceneNumber(layer.thickness_m)
        << " m): density tau, so sigma_t integrates to tau across it\n"
        << "MakeNamedMedium \"layer\" \"string type\" [ \"uniformgrid\" ]\n"
        << "  \"integer nx\" [ " << scene.grid.width << " ] \"integer ny\" [ " << scene.grid.height
        << " ] \"integer nz\" [ 2 ]\n"
        << "  \"point3 p0\" [ " << Triple(Eigen::Vector3d(scene.grid.min_m.x(), scene.grid.min_m.y(), 0)) << " ]"
        << " \"point3 p1\" [ " << Triple(Eigen::Vector3d(hi.x(), hi.y(), layer.thickness_m)) << " ]\n"
        << "  \"rgb sigma_a\" [ " << Triple(Eigen::Vector3d::Constant((1 - layer.albedo) / layer.thickness_m))
        << " ] \"rgb sigma_s\" [ " << Triple(Eigen::Vector3d::Constant(layer.albedo / layer.thickness_m)) << " ]\n"
        << "  \"float scale\" [ 1 ] \"float g\" [ " << SceneNumber(layer.g) << " ]\n"
        << "  \"float density\" [";
    // x fastest, then y, then z (two equal slices).
    for (int z = 0; z < 2; ++z) {
      for (int y = 0; y < scene.grid.height; ++y) {
        out << "\n   ";
        for (int x = 0; x < scene.grid.width; ++x) out << " " << SceneNumber(layer.tau.at(x, y));
      }
    }
    out << " ]\n\nAttributeBegin\n  MediumInterface \"layer\" \"\"\n  Material \"interface\"\n"
        << BoxMesh(scene.grid, 0, layer.thickness_m) << "AttributeEnd\n";
    // The pane 1 um below the layer: coincident surfaces would intersect ambiguously.
    const double pane_top = -1e-6;
    out << "\n# The pane under the layer (smooth)\nAttributeBegin\n"
        << "  Material \"dielectric\" \"float eta\" [ " << SceneNumber(layer.glass_eta) << " ]\n"
        << QuadMesh(scene.grid, pane_top, false) << QuadMesh(scene.grid, pane_top - layer.glass_thickness_m, true)
        << "AttributeEnd\n";
  }
  SceneGrid light = scene.grid;
  light.min_m = scene.grid.centre_m() - Eigen::Vector2d::Constant(scene.backlight_half_size_m);
  light.width = light.height = 1;
  light.pitch_m = 2 * scene.backlight_half_size_m;
  out << "\n# The backlight: the monitor or board plane, radiance 1, facing +z\nAttributeBegin\n"
      << "  AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ]\n"
      << QuadMesh(light, -scene.backlight_distance_m, false) << "AttributeEnd\n";
  return out.str();
}

Status WritePbrtScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance) {
  if (scene.laser_probe || (scene.layer && scene.layer->tau.empty())) {
    return Status::Error(dir +
                         ": the laser-lobe round trip's scene (a uniform layer seen by reciprocity) is written "
                         "for Blender only");
  }
  SceneTextures textures;
  THINSLAB_RETURN_IF_ERROR(WriteSceneTextures(scene, dir, provenance, &textures));
  return WriteFileAtomically(JoinPath(dir, "scene.pbrt"), PbrtScene(scene, textures));
}

}  // namespace thinslab
