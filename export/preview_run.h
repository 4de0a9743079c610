// SPDX-License-Identifier: Apache-2.0
// `thinslab preview FITDIR OUT` (issue #27 item 4): a fitted material in a canonical scene,
// rendered with thinslab's own models. A `fit dmf`: the sample over a backlit checkerboard,
// beside the same view through clean glass (slab_preview.h). A `fit tau` or `synth layer`: the
// layer on a window pane in the scenes of Gu et al. 2007 Fig. 8 (synth/pane_preview.h), its g
// and albedo as `thinslab export` takes them (scene_from_fit.h). Writes OUT atomically:
// preview.png, preview.json ("format": "thinslab-preview-summary": the scene, the contrasts),
// preview.exr (dot scans: channels fitted, clean, linear), options.ini.
#pragma once

#include <ostream>
#include <string>

#include "thinslab/core/status.h"
#include "thinslab/export/scene_from_fit.h"
#include "thinslab/export/slab_preview.h"

namespace thinslab {

struct PreviewRun {
  std::string fit_dir, out_dir;
  SlabPreviewOptions slab;
  ExportOptions layer;    // g, albedo, --phase and the pane's index for layers.
  double layer_n2 = 1.5;  // Refractive index of the contaminant (not measured by the fits).
  int panel_scale = 0;    // Pixels per map point in preview.png; 0: up to a ~320-px panel.
  std::string options_ini;
};

Status PreviewFit(const PreviewRun& run, std::ostream& log);

// Standard deviation over mean of channel `channel` of `view` at the pixels whose channel
// `mask_channel` is > 0: the checkerboard's visibility through the sample.
double CheckerContrast(const Image& view, int channel, int mask_channel);

}  // namespace thinslab
