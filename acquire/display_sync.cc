// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/display_sync.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <vector>

#include "thinslab/acquire/capture_with_retries.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

bool DisplaySyncOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(min_change_dn > 0)) {
    msg << "DisplaySyncOptions::min_change_dn = " << min_change_dn << ". Violated constraint: > 0";
  } else if (!(noise_sigmas >= 0)) {
    msg << "DisplaySyncOptions::noise_sigmas = " << noise_sigmas << ". Violated constraint: >= 0";
  } else if (!(read_noise_dn >= 0)) {
    msg << "DisplaySyncOptions::read_noise_dn = " << read_noise_dn << ". Violated constraint: >= 0";
  } else if (min_changed_pixels < 1) {
    msg << "DisplaySyncOptions::min_changed_pixels = " << min_changed_pixels << ". Violated constraint: >= 1";
  } else if (settle_captures < 2) {
    msg << "DisplaySyncOptions::settle_captures = " << settle_captures << ". Violated constraint: >= 2";
  } else if (max_sync_captures < settle_captures) {
    msg << "DisplaySyncOptions::max_sync_captures = " << max_sync_captures
        << ". Violated constraint: >= settle_captures (" << settle_captures << ")";
  } else if (max_retries < 0) {
    msg << "DisplaySyncOptions::max_retries = " << max_retries << ". Violated constraint: >= 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

bool FramesDiffer(const Image& a_raw, double a_exposure_us, const Image& b_raw, double b_exposure_us,
                  const CameraInfo& camera, const DisplaySyncOptions& options) {
  const int w = a_raw.width(), h = a_raw.height();
  if (b_raw.width() != w || b_raw.height() != h) return true;
  const double black = camera.black_level_dn;
  const double saturation = camera.saturation_dn > 0 ? camera.saturation_dn : 1e30;
  const double scale = a_exposure_us / b_exposure_us;  // b at a's exposure.
  const double gain = camera.gain_e_per_dn > 0 ? camera.gain_e_per_dn : 1.0;
  const double read_var = options.read_noise_dn * options.read_noise_dn;
  // Per pixel: difference, its variance, and validity; then 3x3 means.
  std::vector<double> diff(static_cast<size_t>(w) * h), var(diff.size());
  std::vector<unsigned char> valid(diff.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const double a = a_raw.at(x, y), b = b_raw.at(x, y);
      valid[i] = a < saturation && b < saturation;
      const double sa = std::max(0.0, a - black), sb = std::max(0.0, b - black);
      diff[i] = (a - black) - scale * (b - black);
      // Shot noise (signal / gain, in DN^2) plus read noise of each frame.
      var[i] = sa / gain + read_var + scale * scale * (sb / gain + read_var);
    }
  }
  int changed = 0;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      double sum = 0, sum_var = 0;
      bool ok = true;
      for (int dy = -1; dy <= 1 && ok; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const size_t j = static_cast<size_t>(y + dy) * w + (x + dx);
          if (!valid[j]) {
            ok = false;
            break;
          }
          sum += diff[j];
          sum_var += var[j];
        }
      }
      if (!ok) continue;
      const double mean = sum / 9, sigma = std::sqrt(sum_var) / 9;
      if (std::abs(mean) > std::max(options.min_change_dn, options.noise_sigmas * sigma)) {
        if (++changed >= options.min_changed_pixels) return true;
      }
    }
  }
  return false;
}

Status CaptureSynchronized(Camera* camera, const FrameRecord& templ, LightChange change,
                           const DisplaySyncOptions& options, SyncReference* reference, SessionWriter* writer) {
  const CameraInfo& info = camera->info();
  int failures = 0, discarded = 0;
  std::string last_error;
  SyncReference previous;  // Previous capture of this step, for the settle test.
  for (int capture = 0; capture < options.max_sync_captures + options.max_retries + 1; ++capture) {
    CapturedFrame frame;
    const Status status = camera->Capture(&frame);
    // Transport statistics ride along with every manifest write (docs/format.md 2.3.1).
    writer->SetCameraStatistics(info.id, camera->statistics());
    if (!status.ok()) {
      last_error = status.message();
      THINSLAB_RETURN_IF_ERROR(writer->AddFailedFrame(templ, last_error));
      if (++failures > options.max_retries) {
        return Status::Error("camera '" + info.id + "': capture failed " + std::to_string(failures) +
                             " times: " + last_error);
      }
      continue;
    }
    bool accept = false;
    // A frame still exposed with the previous setting (cameras apply a new exposure a frame or
    // two late) is stale like a frame of the previous pattern.
    const bool exposure_ok = std::abs(frame.exposure_time_us - templ.exposure_time_us) <=
                             5e-3 * std::max(frame.exposure_time_us, templ.exposure_time_us);
    if (exposure_ok) {
      const bool differs = reference->valid && FramesDiffer(frame.raw_dn, frame.exposure_time_us,
                                                            reference->raw_dn, reference->exposure_time_us, info,
                                                            options);
      if (change == LightChange::kNone) {
        accept = true;
      } else if (change == LightChange::kChanged && differs) {
        accept = true;  // The displayed change is seen.
      } else if (change == LightChange::kReshown && reference->valid && !differs) {
        accept = true;  // The state of the frame on disk is seen again.
      } else if (previous.valid && capture + 1 >= options.settle_captures &&
                 !FramesDiffer(frame.raw_dn, frame.exposure_time_us, previous.raw_dn, previous.exposure_time_us,
                               info, options)) {
        accept = true;  // Confirmed settle: the change is not visible to the camera.
      }
    }
    if (accept) {
      const FrameStatus frame_status = failures == 0 ? FrameStatus::kOk : FrameStatus::kRetried;
      THINSLAB_RETURN_IF_ERROR(writer->AddFrame(CapturedRecord(templ, frame, frame_status), frame.raw_dn));
      reference->valid = true;
      reference->raw_dn = std::move(frame.raw_dn);
      reference->exposure_time_us = frame.exposure_time_us;
      return Status::Ok();
    }
    ++discarded;
    ++writer->mutable_session()->acquisition.discarded_frames;
    if (discarded >= options.max_sync_captures) break;
    if (exposure_ok) {
      previous.valid = true;
      previous.raw_dn = std::move(frame.raw_dn);
      previous.exposure_time_us = frame.exposure_time_us;
    }
  }
  return Status::Error("camera '" + info.id + "': display-camera synchronisation failed for pattern '" +
                       templ.light.projector_pattern + "' at " + std::to_string(templ.exposure_time_us) + " us: " +
                       std::to_string(discarded) +
                       " frames showed neither the change nor a settled image (DisplaySyncOptions::max_sync_captures)");
}

namespace {

// The light state a frame is taken in; a change of any part is a change to synchronise on.
struct LightKey {
  std::string sample_state;
  std::string pattern;
  bool laser_on = false;
  bool operator==(const LightKey& o) const {
    return sample_state == o.sample_state && pattern == o.pattern && laser_on == o.laser_on;
  }
  bool operator!=(const LightKey& o) const { return !(*this == o); }
};

LightKey LightOf(const PlannedFrame& p) { return {p.sample_state, p.pattern, p.laser_on}; }

}  // namespace

Status RunSynchronizedPlan(const std::vector<PlannedFrame>& plan, const ExposureBracketOptions& bracket,
                           const DisplaySyncOptions& sync, Camera* camera, Projector* projector,
                           const SampleChanger& change_sample, SessionWriter* writer, Laser* laser) {
  std::string error;
  if (!bracket.Check(&error) || !sync.Check(&error)) return Status::Error(error);
  for (const PlannedFrame& p : plan) {
    if (p.laser_on && laser == nullptr) {
      return Status::Error("RunSynchronizedPlan: frame kind '" + p.kind + "' needs the laser on, and no laser was given");
    }
  }
  ExposureBracketOptions unlocked = bracket;  // Frames the display does not light.
  unlocked.refresh_period_s = 0;
  std::map<std::pair<double, bool>, double> applied_for;  // (requested, refresh-locked) -> applied [us]
  std::optional<std::pair<double, bool>> current_exposure;
  auto set_exposure = [&](const PlannedFrame& p, double* applied) -> Status {
    const std::pair<double, bool> key(p.requested_exposure_us, p.refresh_locked);
    if (current_exposure != key) {
      THINSLAB_RETURN_IF_ERROR(
          ApplyBracketExposure(camera, p.requested_exposure_us, p.refresh_locked ? bracket : unlocked, applied));
      applied_for[key] = *applied;
      current_exposure = key;
    } else {
      *applied = applied_for[key];
    }
    return Status::Ok();
  };
  std::optional<LightKey> shown;  // Light state set up by this run.
  SyncReference reference;
  int last_skipped_step = -1;
  for (size_t step = 0; step < plan.size(); ++step) {
    const PlannedFrame& p = plan[step];
    const LightKey light = LightOf(p);
    FrameRecord templ;
    templ.camera_id = camera->info().id;
    templ.kind = p.kind;
    templ.sample_state = p.sample_state;
    templ.light.projector_pattern = p.pattern;
    templ.light.dot_px = p.dot_px;
    templ.light.laser_on = p.laser_on;
    templ.validation = p.validation;
    THINSLAB_RETURN_IF_ERROR(set_exposure(p, &templ.exposure_time_us));
    bool on_disk = false;
    THINSLAB_RETURN_IF_ERROR(writer->ClaimStep(templ, &on_disk));
    if (on_disk) {
      last_skipped_step = static_cast<int>(step);
      continue;
    }
    if (!shown || shown->sample_state != p.sample_state) THINSLAB_RETURN_IF_ERROR(change_sample(p.sample_state));
    if (!shown || shown->pattern != p.pattern) THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(p.pattern));
    if (laser != nullptr && (!shown || shown->laser_on != p.laser_on)) {
      THINSLAB_RETURN_IF_ERROR(laser->SetEmission(p.laser_on));
    }
    LightChange change = LightChange::kNone;
    if (!shown) {
      // First capture of this run. Resumed: the frame on disk before it is the reference, of
      // this same state (the devices were reopened) or of the state before.
      change = LightChange::kChanged;
      const FrameRecord* before = last_skipped_step >= 0 ? writer->FrameOnDisk(last_skipped_step) : nullptr;
      Image dn;
      if (before != nullptr && LoadFrame(writer->dir(), writer->session(), *before, &dn).ok()) {
        for (float& v : dn.data()) v += static_cast<float>(camera->info().black_level_dn);
        reference.valid = true;
        reference.raw_dn = std::move(dn);
        reference.exposure_time_us = before->exposure_time_us;
        if (LightOf(plan[last_skipped_step]) == light) change = LightChange::kReshown;
      }
    } else if (*shown != light) {
      change = LightChange::kChanged;
    }
    shown = light;
    THINSLAB_RETURN_IF_ERROR(CaptureSynchronized(camera, templ, change, sync, &reference, writer));
  }
  if (!shown) return Status::Ok();
  if (laser != nullptr && shown->laser_on) THINSLAB_RETURN_IF_ERROR(laser->SetEmission(false));
  return projector->ShowPattern("");
}

}  // namespace thinslab
