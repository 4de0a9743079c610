// SPDX-License-Identifier: Apache-2.0
// A fit folder as a renderer scene (issue #27): `fit dmf` (maps.exr: a rough dielectric slab),
// `fit tau` (tau.exr: a scattering layer on a pane, g and albedo from its summary or a `fit
// phase`) or `synth layer` (layer.exr). docs/export.md lists what is approximated and why.
#pragma once

#include <string>

#include "thinslab/core/status.h"
#include "thinslab/export/render_scene.h"

namespace thinslab {

struct ExportOptions {
  // Slab thickness [mm]; < 0: the fit's glass thickness, or 1 mm where the fit's is 0 (Dai's slab
  // is infinitely thin, a renderer's two faces need a distance).
  double slab_thickness_mm = -1;
  // Roughness floor of every face (smooth faces, unfitted points): renderers' microfacet models
  // divide by alpha.
  double min_alpha = 1e-3;
  // Geometric thickness of an exported layer [mm]; its optical thickness stays the fitted tau.
  double layer_thickness_mm = 0.1;
  // The pane under a layer.
  double glass_thickness_mm = 3;
  double glass_eta = 1.5;
  // A `fit phase` folder: g (and the layer model) from its ladder choice, for a `fit tau`.
  std::string phase_dir;
  // Override the fit's layer g / albedo (kFromFit: the fit's).
  static constexpr double kFromFit = -9;
  double g = kFromFit;
  double albedo = kFromFit;
  // Distance of the backlight plane below the sample [mm]; < 0: the fit's monitor distance (dot
  // scans), 20 mm otherwise.
  double backlight_distance_mm = -1;
  int image_width = 640, image_height = 480;

  // Errors name the struct and field (ExportOptions.min_alpha ...).
  Status Check() const;
};

// Reads FIT_DIR (which of the three it is: by its files) into `scene`. Errors name the file and
// the field or channel that is missing or bad.
Status SceneFromFit(const std::string& fit_dir, const ExportOptions& options, RenderScene* scene);

// Per map point, Dai's top-face weight w and the equivalent isotropic roughness alpha as the two
// faces' roughnesses: alpha_top^2 = w alpha^2, alpha_bottom^2 = (1 - w) alpha^2 (the slopes'
// variances of two faces crossed in turn add, so the pair keeps the lobe's width), each at least
// `min_alpha`.
void SplitRoughness(double alpha, double top_face_weight, double min_alpha, double* top, double* bottom);

}  // namespace thinslab
