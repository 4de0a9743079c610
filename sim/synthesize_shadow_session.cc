// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/synthesize_shadow_session.h"

#include <nlohmann/json.hpp>


#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/version.h"
#include "thinslab/sim/sim_session.h"

namespace thinslab {

Status SynthesizeShadowMapSession(const SyntheticShadowSessionOptions& options, const Image& tau,
                                  const std::string& session_dir) {
  std::unique_ptr<SimShadowMapRig> rig;
  THINSLAB_RETURN_IF_ERROR(SimShadowMapRig::Create(options.rig, tau, &rig));

  SessionWriter writer;
  THINSLAB_RETURN_IF_ERROR(OpenSimulatedSession(session_dir, options.name, "shadow_map", rig->rig_info(), &writer));
  ShadowMapSessionOptions session = options.session;
  session.sync = SyncForSensor(session.sync, options.rig.sensor);
  THINSLAB_RETURN_IF_ERROR(RunReportedSimulation(
      "sim shadow-maps: frames rendered", static_cast<int64_t>(PlanShadowMapSession(session).size()), options.progress,
      session_dir, &writer,
      [&]() { return RunShadowMapSession(session, rig->camera(), rig->projector(), rig->sample_changer(), &writer); }));

  const std::string truth_dir = JoinPath(session_dir, "ground_truth");
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(truth_dir));
  Image truth = tau;
  truth = Image(tau.width(), tau.height(), {"tau"});
  truth.data() = tau.data();
  truth.attributes()["thinslab_version"] = THINSLAB_VERSION_STRING;
  truth.attributes()["git_hash"] = THINSLAB_GIT_HASH;
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(truth_dir, "tau.exr"), truth));
  nlohmann::json j;
  j["layer_albedo"] = options.rig.layer_albedo;
  j["layer_g"] = options.rig.layer_g;
  j["board_distance_m"] = options.rig.board_distance_m;
  j["pixel_pitch_m"] = options.rig.pixel_pitch_m;
  j["seed"] = options.rig.seed;
  j["monte_carlo_photons_per_node"] = options.rig.monte_carlo.num_photons;
  j["sensor"] = {{"full_well_e", options.rig.sensor.full_well_e},
                 {"read_noise_e", options.rig.sensor.read_noise_e},
                 {"bit_depth", options.rig.sensor.bit_depth},
                 {"black_level_dn", options.rig.sensor.black_level_dn},
                 {"noise", options.rig.sensor.enable_noise}};
  return WriteFileAtomically(JoinPath(truth_dir, "truth.json"), j.dump(2) + "\n");
}

}  // namespace thinslab
