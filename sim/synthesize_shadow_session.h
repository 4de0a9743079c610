// SPDX-License-Identifier: Apache-2.0
// SynthesizeShadowMapSession: runs the unchanged acquisition script (acquire/) on the
// simulated rig and writes a real capture session, plus its ground truth:
//   <session>/ground_truth/tau.exr       channel "tau" on the manifest's sample grid
//   <session>/ground_truth/truth.json    layer albedo and g, board distance, seeds
#pragma once

#include <string>

#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/core/image.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/status.h"
#include "thinslab/sim/shadow_map_rig.h"

namespace thinslab {

struct SyntheticShadowSessionOptions {
  SimShadowMapOptions rig;
  ShadowMapSessionOptions session;
  std::string name = "sim_shadow_map";
  // Reports the frames rendered of those planned; returning false cancels (core/progress.h).
  ProgressCallback progress;
};

// `session_dir` must not exist yet (or be empty).
Status SynthesizeShadowMapSession(const SyntheticShadowSessionOptions& options, const Image& tau,
                                  const std::string& session_dir);

}  // namespace thinslab
