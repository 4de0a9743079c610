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
  Image tau;                // Channel Y, >= 0; empty for a uniform layer.
  double uniform_tau = -1;  // >= 0 with an empty `tau`: the layer's tau everywhere (Blender only).
  double g = 0, albedo = 0;
  double thickness_m = 1e-4;
  double glass_eta = 1.5, glass_thickness_m = 3e-3;
};

// The capture's own shadow-map rig (Gu et al. 2007, Fig. 9a) for the render round trip
// (export/round_trip.h), in place of the backlight: a Lambertian board at z = -board_distance_m
// lit through the layer by a collimated source (the projector). The camera sees the board
// directly, not through the layer, as the simulated rig and `fit tau` model it; the pane's faces
// are left out (a parallel pane shifts collimated light without turning it, and its Fresnel loss
// is the same with and without the layer, so the shadow-to-reference ratio keeps it out).
struct ShadowRig {
  double board_distance_m = 0;
  double board_albedo = 0.8;
  Eigen::Vector3d light_propagation = Eigen::Vector3d(0, 0, -1);  // Unit: the direction the light travels.
};

// The capture's laser-lobe rig (Gu et al. 2007, Fig. 9b; export/lobe_round_trip.h) rendered by
// reciprocity. A collimated beam along -z of Gaussian profile (1/e^2 radius beam_radius_m)
// crosses the layer at beam_centre_m and the scattered light lands on a Lambertian board at z =
// -board_distance_m, where the camera measures rings of it. Traced from a camera, a board point
// finds the beam's spot in the layer on about (r_b / d)^2 cos^4(theta) of its paths (1e-5 at 60
// degrees): too few for rings. Light transport is reciprocal (HG phase functions are symmetric),
// so each ring is rendered as a Lambertian emitter of radiance 1 in its own light group, and an
// orthographic camera looking along the beam over its cross-section (view_size_m square,
// centred on the beam) receives, per ring, the light the beam would put on that ring: the ring's
// mean irradiance is proportional to the sum over the image of (beam profile x radiance) / ring
// area. No board, camera or pane faces are drawn: the sim and Eq. 8 leave out their
// interreflections.
struct LaserProbe {
  double board_distance_m = 0;
  double beam_radius_m = 0;
  Eigen::Vector2d beam_centre_m = Eigen::Vector2d::Zero();
  std::vector<double> ring_inner_m, ring_outer_m;  // Ring k spans [inner, outer) from the centre.
  double view_size_m = 0;
  int image_px = 16;
};

// The capture's dot-scan monitor for the render round trip (export/dot_round_trip.h): Lambertian
// discs of radiance `radiance` (the fit's median dot radiance, in the capture's DN/us, so the
// render is in the capture's units), one lit per render. The rest of the monitor is black and
// not drawn.
struct DotMonitor {
  struct Dot {
    Eigen::Vector3d centre_m, normal;  // The normal points towards the sample.
    double radius_m = 0;
  };
  std::vector<Dot> dots;
  double radiance = 1;
};

// Pinhole intrinsics of the rig camera in pixels of image_width x image_height (OpenCV: pixel
// centres at integer coordinates, y down).
struct PinholeIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
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
  // The rig camera's intrinsics (the round trip renders the capture's pixels); empty: fov_x_rad
  // frames the sample with the image's centre on the optical axis.
  std::optional<PinholeIntrinsics> intrinsics;
  // A uniform emitter of radiance 1 in the plane z = -backlight_distance_m, facing +z, covering
  // the sample region and its surroundings (the monitor or board of the rig); not drawn with
  // shadow_rig.
  double backlight_distance_m = 0.04;
  double backlight_half_size_m = 0.1;
  std::optional<ShadowRig> shadow_rig;
  std::optional<LaserProbe> laser_probe;  // Replaces the camera and lights (Blender only).
  std::optional<DotMonitor> dot_monitor;  // Replaces the backlight (Blender only).
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
