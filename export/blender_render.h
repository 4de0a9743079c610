// SPDX-License-Identifier: Apache-2.0
// Runs Blender on a scene written by export/blender_scene.h for the render round trips
// (export/round_trip.h): its --passes renders, with progress from Blender's log and a cancel that
// stops Blender.
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/status.h"

namespace thinslab {

// `blender -b --factory-startup --python-exit-code 1 --python SCENE_DIR/scene.py -- --passes
// PREFIX --samples N`, its output in SCENE_DIR/blender.log. `passes` is how many renders the
// scene makes (for the progress: passes x samples). Errors name the executable (a missing one:
// "--blender: cannot run ...") and end with the log's tail.
Status RenderBlenderPasses(const std::string& blender, const std::string& scene_dir, const std::string& prefix,
                           int passes, int samples, const std::string& progress_label,
                           const ProgressCallback& progress);

// The luminance of a Blender render (R, G and B are equal in the grey scenes): channels
// PREFIX R, G and B (prefix "" for a plain EXR, "ViewLayer.Combined_ring3." for a light group's
// pass of a multilayer one). Errors name the file, a wrong size and a pixel that is not a finite
// radiance >= 0.
Status ReadBlenderRender(const std::string& path, int width, int height, const std::string& channel_prefix, Image* out);

}  // namespace thinslab
