// SPDX-License-Identifier: Apache-2.0
// Display-camera synchronisation. After Projector::ShowPattern (or Laser::SetEmission, or a
// sample change) returns, a streaming camera may still deliver frames exposed before the change
// (buffers queued in the camera or the transport). A frame therefore counts for a new light
// state only once it differs measurably from the previous state's frame; if it never does (the
// change is invisible to the camera: a dot outside its view, or no previous frame to compare
// with) it counts after a confirmed settle: at least `settle_captures` captures and the last two
// agreeing. When a resumed run shows again the state of the last frame on disk, a frame counts
// once it agrees with that frame (or after a confirmed settle). Frames rejected on the way are
// discarded (counted in the manifest's acquisition.discarded_frames, never recorded as
// frames); device errors are recorded as failed frames and retried.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thinslab/acquire/exposure_bracket.h"
#include "thinslab/acquire/sample_changer.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/laser.h"

namespace thinslab {

struct DisplaySyncOptions {
  // A 3x3-averaged pixel difference counts as a change when it exceeds both min_change_dn and
  // noise_sigmas times its noise (shot noise from gain_e_per_dn, or 1 e-/DN when unknown, plus
  // read_noise_dn), in DN at the new frame's exposure.
  double min_change_dn = 6;
  double noise_sigmas = 6;
  double read_noise_dn = 2;
  int min_changed_pixels = 3;
  // Confirmed settle: at least this many captures, the last two agreeing.
  int settle_captures = 3;
  // Captures after which synchronisation gives up with an error naming camera and pattern.
  int max_sync_captures = 12;
  // Device errors (dropped frames, timeouts) tolerated per frame before the session stops.
  int max_retries = 2;

  bool Check(std::string* error) const;
};

// Raw frame and the exposure it was taken at, as the reference of the next pattern change.
struct SyncReference {
  bool valid = false;
  Image raw_dn;  // Raw DN (black level included), as CapturedFrame::raw_dn.
  double exposure_time_us = 0;
};

// True if `a` differs measurably from `b` (both raw DN of the same camera) after scaling `b`
// to `a`'s exposure; saturated pixels of either are ignored.
bool FramesDiffer(const Image& a_raw, double a_exposure_us, const Image& b_raw, double b_exposure_us,
                  const CameraInfo& camera, const DisplaySyncOptions& options);

// What happened to the light state before a capture.
enum class LightChange {
  kNone,     // The state of the previous frame of this run: the first frame with the exposure.
  kChanged,  // A new state: a frame that differs from *reference (the previous state's frame,
             // possibly invalid), else a confirmed settle.
  kReshown,  // The state of *reference shown again (a resumed run): a frame that agrees with
             // *reference, else a confirmed settle.
};

// Captures the frame described by `templ` (whose exposure_time_us is the applied exposure),
// accepting it by the rule for `change`; any accepted frame's reported exposure must match.
// The accepted frame is written through `writer` and becomes the new *reference. The caller
// must have claimed the step (SessionWriter::ClaimStep).
Status CaptureSynchronized(Camera* camera, const FrameRecord& templ, LightChange change,
                           const DisplaySyncOptions& options, SyncReference* reference, SessionWriter* writer);

// One planned frame of a session run by RunSynchronizedPlan (shadow maps, laser lobe, dot scan,
// exposure bracket).
struct PlannedFrame {
  std::string kind;
  std::string sample_state = "none";
  std::string pattern;  // Projector pattern id (drivers/pattern_id.h).
  double requested_exposure_us = 0;
  std::optional<Eigen::Vector2d> dot_px;
  bool laser_on = false;
  // The display is in the light path of this frame: its exposure is rounded to whole refresh
  // periods (ExposureBracketOptions::refresh_period_s). False for frames lit by the laser alone.
  bool refresh_locked = true;
  bool validation = false;  // FrameRecord::validation: not for fitting.
};

// Runs `plan` in order: changes the sample, the displayed pattern and the laser (if `laser` is
// given; a plan that switches the laser on without one is refused) when they change, applies
// each exposure (ApplyBracketExposure, read back; refresh-locked frames at whole refresh
// periods), claims each frame (skipping frames already on disk when resuming, without touching
// sample, display or laser for them) and captures it with CaptureSynchronized. On resume, the
// reference for the first capture is the last frame on disk, loaded from its file: of the same
// light state (kReshown) or of the one before (kChanged). Ends with the display black and the
// laser off.
Status RunSynchronizedPlan(const std::vector<PlannedFrame>& plan, const ExposureBracketOptions& bracket,
                           const DisplaySyncOptions& sync, Camera* camera, Projector* projector,
                           const SampleChanger& change_sample, SessionWriter* writer, Laser* laser = nullptr);

}  // namespace thinslab
