// SPDX-License-Identifier: Apache-2.0
// Display-camera synchronisation. After Projector::ShowPattern returns, a streaming camera may
// still deliver frames exposed before the change (buffers queued in the camera or the
// transport). A frame therefore counts for a new pattern only once it differs measurably from
// the previous pattern's frame; if it never does (the change is invisible to the camera: a dot
// outside its view, or no previous frame to compare with) it counts after a confirmed settle:
// at least `settle_captures` captures and the last two agreeing. Frames rejected on the way are
// discarded (counted in the manifest's acquisition.discarded_frames, never recorded as
// frames); device errors are recorded as failed frames and retried.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "acquire/exposure_bracket.h"
#include "acquire/session_writer.h"
#include "acquire/shadow_map_session.h"
#include "core/image.h"
#include "core/status.h"
#include "drivers/camera.h"

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

// Captures the frame described by `templ` (whose exposure_time_us is the applied exposure).
// When `pattern_changed`, applies the synchronisation rule against `*reference` (which may be
// invalid); otherwise takes the first frame whose reported exposure matches. The accepted
// frame is written through `writer` and becomes the new *reference. The caller must have
// claimed the step (SessionWriter::ClaimStep).
Status CaptureSynchronized(Camera* camera, const FrameRecord& templ, bool pattern_changed,
                           const DisplaySyncOptions& options, SyncReference* reference, SessionWriter* writer);

// One planned frame of a display-driven session (dot scan, exposure bracket).
struct PlannedFrame {
  std::string kind;
  std::string sample_state = "none";
  std::string pattern;  // Projector pattern id (drivers/pattern_id.h).
  double requested_exposure_us = 0;
  std::optional<Eigen::Vector2d> dot_px;
};

// Runs `plan` in order: changes the sample and the displayed pattern when they change, applies
// each exposure (ApplyBracketExposure, read back), claims each frame (skipping frames already
// on disk when resuming, without touching sample or display for them) and captures it with
// CaptureSynchronized. On resume, the reference for the first pattern change is the last
// frame on disk, loaded from its file.
Status RunSynchronizedPlan(const std::vector<PlannedFrame>& plan, const ExposureBracketOptions& bracket,
                           const DisplaySyncOptions& sync, Camera* camera, Projector* projector,
                           const SampleChanger& change_sample, SessionWriter* writer);

}  // namespace thinslab
