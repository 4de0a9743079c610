// SPDX-License-Identifier: Apache-2.0
// What `thinslab export` hands to a renderer (issue #27): the fitted sample as geometry and
// material in the sample frame (docs/conventions.md: the sample is the plane z = 0, +z points to
// the camera, the monitor or board lights it from -z), the rig camera's pose and a backlight.
// The scene writers (mitsuba_scene.h, pbrt_scene.h, blender_scene.h) translate this one
// description into each renderer's terms; none of them reads a fit folder itself.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"

namespace thinslab {

// The map grid of the fit: pixel (col, row) covers x in min + [col, col + 1) pitch, y likewise;
// texture row 0 is the smallest y (as in maps.exr and tau.exr).
struct SceneGrid {
  int width = 0, height = 0;
  Eigen::Vector2d min_m = Eigen::Vector2d::Zero();
  double pitch_m = 0;
  Eigen::Vector2d size_m() const { return Eigen::Vector2d(width * pitch_m, height * pitch_m); }
  Eigen::Vector2d centre_m() const { return min_m + 0.5 * size_m(); }
};

// A rough dielectric slab (a `fit dmf`): the camera-side face at z = 0, the monitor-side face at
// z = -thickness. Each face is a Walter et al. 2007 microfacet interface (GGX or Beckmann) with a
// roughness map; a smooth face has the floor roughness.
struct RoughSlab {
  double eta = 1.5;
  double thickness_m = 0;
  std::string distribution = "ggx";  // "ggx" or "beckmann": one per scene, as renderers take it.
  Image top_alpha;                   // Monitor-side face, channel Y: Walter's alpha.
  Image bottom_alpha;                // Camera-side face.
};

// A scattering layer on a smooth pane (a `fit tau` or `synth layer`, Gu et al. 2007): the layer
// occupies 0 < z < thickness on the camera-side face of a pane of `glass_thickness_m`. Its
// extinction is tau / thickness (so its optical thickness along z is the fitted tau), its
// phase function Henyey-Greenstein with `g`, its single-scattering albedo `albedo`.
struct ScatteringLayer {
  Image tau;  // Channel Y, >= 0.
  double g = 0, albedo = 0;
  double thickness_m = 1e-4;
  double glass_eta = 1.5, glass_thickness_m = 3e-3;
};

struct RenderScene {
  SceneGrid grid;
  std::optional<RoughSlab> slab;
  std::optional<ScatteringLayer> layer;
  // The camera: the rig camera's pose when the fit recorded it (worldToCamera), else a camera
  // straight above the sample. The field of view frames the sample region (not the rig camera's
  // intrinsics: exported scenes show the material, not the capture's pixels).
  Rigid3d cam_from_sample;
  int image_width = 640, image_height = 480;
  double fov_x_rad = 0;
  // A uniform emitter of radiance 1 in the plane z = -backlight_distance_m, facing +z, covering
  // the sample region and its surroundings (the monitor or board of the rig).
  double backlight_distance_m = 0.04;
  double backlight_half_size_m = 0.1;
  std::string source;              // The fit folder.
  std::vector<std::string> notes;  // What the export approximated (written beside the scene).
};

// The camera in renderer terms: centre, a point on the optical axis and the image's up direction
// (OpenCV's camera y points down, so up is -y).
struct SceneCamera {
  Eigen::Vector3d eye, target, up;
};
SceneCamera CameraOf(const RenderScene& scene);

// A camera above the grid's centre at `height_m`, looking down -z with image x along +x (used
// when the fit recorded no camera pose).
Rigid3d CameraAbove(const SceneGrid& grid, double height_m);

// The horizontal field of view that shows the whole grid (with 10 % margin) from `cam_from_sample`
// in an image of aspect width / height.
double FramingFovX(const SceneGrid& grid, const Rigid3d& cam_from_sample, int width, int height);

// The vertical field of view of the same image (pbrt's "fov" is that of the shorter image axis).
double FovY(double fov_x_rad, int width, int height);

}  // namespace thinslab
