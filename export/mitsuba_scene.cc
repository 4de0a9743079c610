// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/mitsuba_scene.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"

namespace thinslab {

namespace {

std::string Vec(const Eigen::Vector3d& v) {
  return SceneNumber(v.x()) + ", " + SceneNumber(v.y()) + ", " + SceneNumber(v.z());
}

// XML comments may not hold "--".
std::string CommentText(std::string text) {
  for (size_t at = text.find("--"); at != std::string::npos; at = text.find("--")) text.replace(at, 2, "- -");
  return text;
}

// to_world of a rectangle or cube: scale the [-1, 1] square / cube to the box, then move it.
void BoxTransform(std::ostringstream& out, const std::string& indent, const Eigen::Vector3d& half_size,
                  const Eigen::Vector3d& centre) {
  out << indent << "<transform name=\"to_world\">\n"
      << indent << "  <scale x=\"" << SceneNumber(half_size.x()) << "\" y=\"" << SceneNumber(half_size.y()) << "\" z=\""
      << SceneNumber(half_size.z()) << "\"/>\n"
      << indent << "  <translate x=\"" << SceneNumber(centre.x()) << "\" y=\"" << SceneNumber(centre.y()) << "\" z=\""
      << SceneNumber(centre.z()) << "\"/>\n"
      << indent << "</transform>\n";
}

// A face of the sample: the grid's rectangle at z, its normal +z (camera side) or, flipped, -z.
void Face(std::ostringstream& out, const SceneGrid& grid, double z, bool normal_down, const std::string& bsdf) {
  const Eigen::Vector2d half = 0.5 * grid.size_m(), centre = grid.centre_m();
  out << "  <shape type=\"rectangle\">\n";
  BoxTransform(out, "    ", Eigen::Vector3d(half.x(), half.y(), 1), Eigen::Vector3d(centre.x(), centre.y(), z));
  if (normal_down) out << "    <boolean name=\"flip_normals\" value=\"true\"/>\n";
  out << bsdf << "  </shape>\n";
}

std::string RoughDielectric(const RoughSlab& slab, const std::string& alpha_texture_id) {
  return "    <bsdf type=\"roughdielectric\">\n      <string name=\"distribution\" value=\"" + slab.distribution +
         "\"/>\n      <ref name=\"alpha\" id=\"" + alpha_texture_id + "\"/>\n      <float name=\"int_ior\" value=\"" +
         SceneNumber(slab.eta) + "\"/>\n      <float name=\"ext_ior\" value=\"1\"/>\n    </bsdf>\n";
}

std::string SmoothDielectric(double eta) {
  return "    <bsdf type=\"dielectric\">\n      <float name=\"int_ior\" value=\"" + SceneNumber(eta) +
         "\"/>\n      <float name=\"ext_ior\" value=\"1\"/>\n    </bsdf>\n";
}

void Bitmap(std::ostringstream& out, const std::string& id, const std::string& file) {
  // raw: the values are roughnesses, not colours; nearest: one map point per texel.
  out << "  <texture type=\"bitmap\" id=\"" << id << "\">\n"
      << "    <string name=\"filename\" value=\"" << file << "\"/>\n"
      << "    <boolean name=\"raw\" value=\"true\"/>\n"
      << "    <string name=\"filter_type\" value=\"nearest\"/>\n"
      << "  </texture>\n";
}

template <typename T>
void Append(std::string* bytes, T value) {
  char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  bytes->append(raw, sizeof(T));
}

}  // namespace

std::string MitsubaVolumeBytes(const SceneGrid& grid, const ScatteringLayer& layer) {
  std::string bytes = "VOL";
  bytes.push_back(3);          // Version.
  Append<int32_t>(&bytes, 1);  // Encoding: float32.
  Append<int32_t>(&bytes, grid.width);
  Append<int32_t>(&bytes, grid.height);
  Append<int32_t>(&bytes, 2);  // z resolution.
  Append<int32_t>(&bytes, 1);  // Channels.
  const Eigen::Vector2d hi = grid.min_m + grid.size_m();
  for (double v : {grid.min_m.x(), grid.min_m.y(), 0.0, hi.x(), hi.y(), layer.thickness_m}) {
    Append<float>(&bytes, static_cast<float>(v));
  }
  for (int z = 0; z < 2; ++z) {
    for (int y = 0; y < grid.height; ++y) {
      for (int x = 0; x < grid.width; ++x) {
        Append<float>(&bytes, static_cast<float>(layer.tau.at(x, y) / layer.thickness_m));
      }
    }
  }
  return bytes;
}

std::string MitsubaSceneXml(const RenderScene& scene, const SceneTextures& textures, const std::string& volume_file) {
  const SceneCamera camera = CameraOf(scene);
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      << "<!-- thinslab export mitsuba of " << CommentText(scene.source) << " (docs/export.md).\n"
      << "     Units: metres. Frame: the sample plane is z = 0, the camera on +z, the backlight on -z.\n";
  for (const std::string& note : scene.notes) out << "     - " << CommentText(note) << "\n";
  out << "     Render: mitsuba -m scalar_rgb scene.xml -->\n"
      << "<scene version=\"3.0.0\">\n"
      << "  <integrator type=\"volpath\">\n    <integer name=\"max_depth\" value=\"64\"/>\n  </integrator>\n"
      << "  <sensor type=\"perspective\">\n"
      << "    <float name=\"fov\" value=\"" << SceneNumber(scene.fov_x_rad * 180 / kPi) << "\"/>\n"
      << "    <string name=\"fov_axis\" value=\"x\"/>\n"
      << "    <float name=\"near_clip\" value=\"0.0001\"/>\n"
      << "    <transform name=\"to_world\">\n"
      << "      <lookat origin=\"" << Vec(camera.eye) << "\" target=\"" << Vec(camera.target) << "\" up=\""
      << Vec(camera.up) << "\"/>\n"
      << "    </transform>\n"
      << "    <sampler type=\"independent\">\n      <integer name=\"sample_count\" value=\"256\"/>\n    </sampler>\n"
      << "    <film type=\"hdrfilm\">\n"
      << "      <integer name=\"width\" value=\"" << scene.image_width << "\"/>\n"
      << "      <integer name=\"height\" value=\"" << scene.image_height << "\"/>\n"
      << "      <string name=\"pixel_format\" value=\"rgb\"/>\n"
      << "    </film>\n"
      << "  </sensor>\n";
  if (scene.slab) {
    const RoughSlab& slab = *scene.slab;
    Bitmap(out, "top_alpha", textures.top_alpha);
    Bitmap(out, "bottom_alpha", textures.bottom_alpha);
    out << "  <!-- The slab's camera-side face (z = 0, normal +z) -->\n";
    Face(out, scene.grid, 0, false, RoughDielectric(slab, "bottom_alpha"));
    out << "  <!-- The slab's monitor-side face (z = -thickness, normal -z) -->\n";
    Face(out, scene.grid, -slab.thickness_m, true, RoughDielectric(slab, "top_alpha"));
  }
  if (scene.layer) {
    const ScatteringLayer& layer = *scene.layer;
    const Eigen::Vector2d size = scene.grid.size_m(), centre = scene.grid.centre_m();
    out << "  <medium type=\"heterogeneous\" id=\"layer\">\n"
        << "    <volume type=\"gridvolume\" name=\"sigma_t\">\n"
        << "      <string name=\"filename\" value=\"" << volume_file << "\"/>\n"
        << "      <transform name=\"to_world\">\n"
        << "        <scale x=\"" << SceneNumber(size.x()) << "\" y=\"" << SceneNumber(size.y()) << "\" z=\""
        << SceneNumber(layer.thickness_m) << "\"/>\n"
        << "        <translate x=\"" << SceneNumber(scene.grid.min_m.x()) << "\" y=\""
        << SceneNumber(scene.grid.min_m.y()) << "\" z=\"0\"/>\n"
        << "      </transform>\n"
        << "    </volume>\n"
        << "    <float name=\"albedo\" value=\"" << SceneNumber(layer.albedo) << "\"/>\n"
        << "    <float name=\"scale\" value=\"1\"/>\n"
        << "    <phase type=\"hg\">\n      <float name=\"g\" value=\"" << SceneNumber(layer.g) << "\"/>\n    </phase>\n"
        << "  </medium>\n"
        << "  <!-- The layer (0 < z < " << SceneNumber(layer.thickness_m)
        << " m): index-matched boundary around the medium -->\n"
        << "  <shape type=\"cube\">\n";
    BoxTransform(out, "    ", Eigen::Vector3d(0.5 * size.x(), 0.5 * size.y(), 0.5 * layer.thickness_m),
                 Eigen::Vector3d(centre.x(), centre.y(), 0.5 * layer.thickness_m));
    out << "    <bsdf type=\"null\"/>\n    <ref name=\"interior\" id=\"layer\"/>\n  </shape>\n";
    // The pane 1 um below the layer: coincident surfaces would intersect ambiguously.
    const double pane_top = -1e-6;
    out << "  <!-- The pane under the layer (smooth, eta " << SceneNumber(layer.glass_eta) << ") -->\n";
    Face(out, scene.grid, pane_top, false, SmoothDielectric(layer.glass_eta));
    Face(out, scene.grid, pane_top - layer.glass_thickness_m, true, SmoothDielectric(layer.glass_eta));
  }
  out << "  <!-- The backlight: the monitor or board plane, radiance 1 -->\n"
      << "  <shape type=\"rectangle\">\n";
  const Eigen::Vector2d centre = scene.grid.centre_m();
  BoxTransform(out, "    ", Eigen::Vector3d(scene.backlight_half_size_m, scene.backlight_half_size_m, 1),
               Eigen::Vector3d(centre.x(), centre.y(), -scene.backlight_distance_m));
  out << "    <emitter type=\"area\">\n      <rgb name=\"radiance\" value=\"1, 1, 1\"/>\n    </emitter>\n"
      << "  </shape>\n"
      << "</scene>\n";
  return out.str();
}

Status WriteMitsubaScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance) {
  if (scene.laser_probe || (scene.layer && scene.layer->tau.empty())) {
    return Status::Error(dir +
                         ": the laser-lobe round trip's scene (a uniform layer seen by reciprocity) is written "
                         "for Blender only");
  }
  SceneTextures textures;
  THINSLAB_RETURN_IF_ERROR(WriteSceneTextures(scene, dir, provenance, &textures));
  std::string volume_file;
  if (scene.layer) {
    volume_file = "layer_sigma_t.vol";
    THINSLAB_RETURN_IF_ERROR(
        WriteFileAtomically(JoinPath(dir, volume_file), MitsubaVolumeBytes(scene.grid, *scene.layer)));
  }
  return WriteFileAtomically(JoinPath(dir, "scene.xml"), MitsubaSceneXml(scene, textures, volume_file));
}

}  // namespace thinslab
