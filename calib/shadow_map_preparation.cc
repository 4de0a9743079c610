// SPDX-License-Identifier: Apache-2.0
#include "calib/shadow_map_preparation.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "calib/board_rectification.h"
#include "core/file.h"
#include "core/math.h"
#include "core/session_io.h"

namespace thinslab {

bool ShadowMapPreparationOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (supersample < 1 || supersample > 8) {
    msg << "ShadowMapPreparationOptions::supersample = " << supersample << ". Violated constraint: 1..8";
  } else if (!(board_distance_m >= 0)) {
    msg << "ShadowMapPreparationOptions::board_distance_m = " << board_distance_m << ". Violated constraint: >= 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

namespace {

struct AveragedFrames {
  Image mean_dn_per_us;
  Image variance;
  Image saturated;
  int count = 0;
};

// Averages frames of one kind, normalised by exposure, with a saturation mask. Variance from
// the sensor's conversion gain (shot noise) and the dark frames' read noise.
Status AverageFrames(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                     const std::vector<const FrameRecord*>& frames, const Image* dark_dn,
                     double read_variance_dn2, AveragedFrames* out) {
  out->count = static_cast<int>(frames.size());
  const int w = camera.width_px, h = camera.height_px;
  Image sum(w, h), sum_exposure_var(w, h), saturated(w, h);
  const float saturation_above_black = static_cast<float>(camera.saturation_dn - camera.black_level_dn);
  for (const FrameRecord* frame : frames) {
    Image dn;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frame, &dn));
    const double t = frame->exposure_time_us;
    for (size_t i = 0; i < dn.data().size(); ++i) {
      float v = dn.data()[i];
      if (camera.bit_depth != 32 && v >= saturation_above_black - 0.5f) saturated.data()[i] = 1;
      if (dark_dn != nullptr) v -= dark_dn->data()[i];
      sum.data()[i] += static_cast<float>(v / t);
      const double shot = camera.gain_e_per_dn > 0 ? std::max(0.0f, v) / camera.gain_e_per_dn : 0.0;
      sum_exposure_var.data()[i] += static_cast<float>((shot + read_variance_dn2) / (t * t));
    }
  }
  const float n = static_cast<float>(frames.size());
  out->mean_dn_per_us = Image(w, h);
  out->variance = Image(w, h);
  for (size_t i = 0; i < sum.data().size(); ++i) {
    out->mean_dn_per_us.data()[i] = sum.data()[i] / n;
    out->variance.data()[i] = sum_exposure_var.data()[i] / (n * n);
  }
  out->saturated = saturated;
  return Status::Ok();
}

}  // namespace

Status PrepareShadowMaps(const std::string& session_dir, const Session& session,
                         const ShadowMapPreparationOptions& options, RectifiedShadowMaps* maps) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras: no camera");
  if (!session.rig.board.present) {
    return Status::Error(manifest + ": rig.board: missing; a shadow-map session needs the board distance");
  }
  const CameraInfo& camera = session.rig.cameras[0];
  auto of_camera = [&](std::vector<const FrameRecord*> frames) {
    std::vector<const FrameRecord*> out;
    for (const FrameRecord* f : frames) {
      if (f->camera_id == camera.id) out.push_back(f);
    }
    return out;
  };
  const auto shadow_frames = of_camera(session.UsableFrames("shadow"));
  const auto reference_frames = of_camera(session.UsableFrames("reference"));
  const auto dark_frames = of_camera(session.UsableFrames("dark"));
  if (shadow_frames.empty()) {
    return Status::Error(manifest + ": frames: no usable frame of kind 'shadow' for camera '" + camera.id + "'");
  }

  // Dark level: mean of the dark frames (DN above black level) and read noise from their spread.
  Image dark;
  double read_variance = 0;
  if (!dark_frames.empty()) {
    std::vector<Image> darks(dark_frames.size());
    for (size_t k = 0; k < dark_frames.size(); ++k) {
      THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *dark_frames[k], &darks[k]));
    }
    dark = Image(camera.width_px, camera.height_px);
    double sum_sq = 0;
    for (const Image& d : darks) {
      for (size_t i = 0; i < d.data().size(); ++i) dark.data()[i] += d.data()[i] / darks.size();
    }
    for (const Image& d : darks) {
      for (size_t i = 0; i < d.data().size(); ++i) sum_sq += Sqr(d.data()[i] - dark.data()[i]);
    }
    if (darks.size() > 1) read_variance = sum_sq / (dark.data().size() * (darks.size() - 1));
  }
  AveragedFrames shadow, reference;
  THINSLAB_RETURN_IF_ERROR(AverageFrames(session_dir, session, camera, shadow_frames,
                                         dark.empty() ? nullptr : &dark, read_variance, &shadow));
  if (!reference_frames.empty()) {
    THINSLAB_RETURN_IF_ERROR(AverageFrames(session_dir, session, camera, reference_frames,
                                           dark.empty() ? nullptr : &dark, read_variance, &reference));
  }

  // Rectification onto the board plane over the manifest's region grid.
  const SampleInfo& sample = session.rig.sample;
  const double p = sample.pixel_pitch_m;
  const int w = static_cast<int>(std::lround((sample.region_max_m.x() - sample.region_min_m.x()) / p));
  const int h = static_cast<int>(std::lround((sample.region_max_m.y() - sample.region_min_m.y()) / p));
  if (w < 1 || h < 1 || static_cast<double>(w) * h > 1e9) {
    return Status::Error(manifest + ": rig.sample: region and pixel_pitch_m give a " + std::to_string(w) + "x" +
                         std::to_string(h) + " grid");
  }
  const double distance = options.board_distance_m > 0 ? options.board_distance_m : session.rig.board.distance_m;
  maps->region_min_m = sample.region_min_m;
  maps->pixel_pitch_m = p;
  maps->board_distance_m = distance;
  maps->num_shadow_frames = shadow.count;
  maps->num_reference_frames = reference.count;
  maps->num_dark_frames = static_cast<int>(dark_frames.size());
  BoardGrid grid;
  grid.grid_min_m = sample.region_min_m;
  grid.pixel_pitch_m = p;
  grid.width_px = w;
  grid.height_px = h;
  grid.plane_z_m = -distance;
  grid.supersample = options.supersample;
  const BoardRectifier rectifier(camera, grid);
  maps->outside = rectifier.outside();
  maps->shadow = rectifier.Rectify(shadow.mean_dn_per_us);
  // Sub-samples share camera pixels: the variance of their mean counts each distinct camera
  // pixel once, with the weight of the sub-samples it holds (camera pixels are independent).
  maps->shadow_variance = rectifier.RectifyVariance(shadow.variance);
  Image saturated = shadow.saturated;
  if (reference.count > 0) {
    maps->reference = rectifier.Rectify(reference.mean_dn_per_us);
    maps->reference_variance = rectifier.RectifyVariance(reference.variance);
    for (size_t i = 0; i < saturated.data().size(); ++i) {
      if (reference.saturated.data()[i] > 0) saturated.data()[i] = 1;
    }
  }
  maps->saturated = rectifier.RectifyAny(saturated);
  return Status::Ok();
}

}  // namespace thinslab
