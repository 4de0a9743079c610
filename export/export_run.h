// SPDX-License-Identifier: Apache-2.0
// `thinslab export RENDERER FITDIR OUT` (issue #27): a fit folder as a scene a renderer loads.
// Writes OUT atomically (core/file.h StagedDirectory): the scene file (Mitsuba 3 scene.xml, pbrt-v4
// scene.pbrt or Blender scene.py), textures/*.exr, for a Mitsuba layer layer_sigma_t.vol,
// export.json (what was exported and approximated) and options.ini.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "thinslab/core/status.h"
#include "thinslab/export/scene_from_fit.h"

namespace thinslab {

// The renderers `thinslab export` writes for: "mitsuba", "pbrt", "blender".
std::vector<std::string> ExportRenderers();

struct ExportRun {
  std::string renderer;
  std::string fit_dir, out_dir;
  ExportOptions options;
  std::string options_ini;  // The effective options (their digest is the textures' options_digest).
};

Status ExportFit(const ExportRun& run, std::ostream& log);

}  // namespace thinslab
