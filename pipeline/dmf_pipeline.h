// SPDX-License-Identifier: Apache-2.0
// The whole dot-scan fit of dual-microfacet maps (Dai et al. 2009) from a capture folder to an
// output folder (maps.exr, the NDF atlas, summary.json/.txt, options.ini), without device code.
#pragma once

#include <string>

#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_processing.h"

namespace thinslab {

struct FitDmfRun {
  DmfProcessingOptions processing;
  DmfMapFitOptions fit;
  double eta = 0;  // 0 = the manifest's sample.glass_ior.
  double cluster_fraction = 0.01;
  int atlas_stride = 0;  // 0 = at most 64 x 64 tiles.
  std::string ndf_pixels;
  bool ladder = false;  // Issue #8 rungs per point (needs held-out dots).
  int ladder_tile = 4;  // Grid points per side of the tiles whose points decide together.
  std::string ladder_criterion = "held-out";  // Or "bic".
  bool ladder_apply = true;  // maps.exr and the atlas hold the chosen rung's model.
  bool allow_incomplete_capture = false;  // Accept a capture whose acquisition did not complete.
  std::string options_ini;
};

// Reads the capture, prepares the Eq. 12 slices, fits (and with `ladder` the issue #8 rungs),
// writes <out_dir> atomically; `brief` receives summary.txt's text.
Status FitDmfPipeline(const std::string& session_dir, const std::string& out_dir, FitDmfRun run, std::string* brief);

}  // namespace thinslab
