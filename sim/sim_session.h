// SPDX-License-Identifier: Apache-2.0
// Start of every simulated capture: refuses an existing non-empty folder (a simulation never
// appends to or overwrites a capture) and opens a SessionWriter with the rig description.
#pragma once

#include <algorithm>
#include <filesystem>
#include <functional>
#include <string>

#include "thinslab/acquire/display_sync.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/session.h"
#include "thinslab/core/version.h"
#include "thinslab/sim/sensor_model.h"

namespace thinslab {

inline Status OpenSimulatedSession(const std::string& session_dir, const std::string& name, const std::string& kind,
                                   const RigInfo& rig, SessionWriter* writer) {
  std::error_code ec;
  if (std::filesystem::exists(session_dir, ec) && !std::filesystem::is_empty(session_dir, ec)) {
    return Status::Error(session_dir + ": output session folder exists and is not empty");
  }
  Session header;
  header.name = name;
  header.kind = kind;
  header.software = std::string("thinslab ") + THINSLAB_VERSION_STRING + " sim (" + THINSLAB_GIT_HASH + ")";
  header.rig = rig;
  // Programs that write linear frames (HDR tools, renderers) declare no gain.
  for (CameraInfo& camera : header.rig.cameras) {
    if (camera.linear_frames()) camera.gain_e_per_dn = 0;
  }
  return writer->Open(session_dir, header);
}

// Runs a simulated capture's acquisition script with its frames reported to `callback` as
// `stage` (frames written of `planned_frames`); returning false from the callback stops the script
// at its next frame. The manifest is saved either way (the frames written are kept), and a
// cancelled run is an error ending in "cancelled" naming the folder.
inline Status RunReportedSimulation(const std::string& stage, int64_t planned_frames, const ProgressCallback& callback,
                                    const std::string& session_dir, SessionWriter* writer,
                                    const std::function<Status()>& script) {
  ProgressTracker progress(callback, stage, planned_frames);
  writer->set_observer([&]() { progress.Report(writer->steps_claimed()); });
  writer->set_stop_check([&]() { return progress.cancelled() ? std::string("cancelled") : std::string(); });
  const Status ran = script();
  writer->set_observer(nullptr);
  writer->set_stop_check(nullptr);
  if (progress.cancelled()) {
    THINSLAB_RETURN_IF_ERROR(writer->Save());
    return Status::Error(session_dir + ": the capture is incomplete (" + std::to_string(writer->steps_claimed()) +
                         " of " + std::to_string(planned_frames) + " frames written): " + stage + " cancelled");
  }
  THINSLAB_RETURN_IF_ERROR(ran);
  return writer->Save();
}

// The display-camera synchronisation's noise model for a simulated sensor: its read noise in DN
// as the response curve passes it at black (a gamma-like curve amplifies it there several
// times), if above the option's (DisplaySyncOptions assumes a low-noise linear camera). Without
// it, two frames of the same state of a very noisy sensor would never agree and a settle never
// be confirmed.
inline DisplaySyncOptions SyncForSensor(DisplaySyncOptions sync, const SimSensorOptions& sensor) {
  if (sensor.linear_float_frames) {  // The options' DN thresholds in the frames' units.
    sync.min_change_dn *= sensor.FrameValuesPerDn();
    sync.read_noise_dn = std::max(sync.read_noise_dn * sensor.FrameValuesPerDn(),
                                  sensor.enable_noise ? sensor.read_noise_e * sensor.value_scale : 0.0);
    return sync;
  }
  if (!sensor.enable_noise) return sync;
  const double sigma = sensor.read_noise_e / sensor.full_well_e;  // Fraction of full scale.
  const double full_scale_dn = sensor.saturation_dn() - sensor.black_level_dn;
  const double read_noise_dn = 0.5 * (sensor.ResponseCurve(sigma) - sensor.ResponseCurve(-sigma)) * full_scale_dn;
  sync.read_noise_dn = std::max(sync.read_noise_dn, read_noise_dn);
  return sync;
}

}  // namespace thinslab
