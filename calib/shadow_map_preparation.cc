// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/shadow_map_preparation.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "thinslab/core/grid_size.h"
#include "thinslab/calib/board_rectification.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

bool ShadowMapPreparationOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (supersample < 1 || supersample > 8) {
    msg << "ShadowMapPreparationOptions::supersample = " << supersample << ". Violated constraint: 1..8";
  } else if (!(board_distance_m >= 0 && board_distance_m <= kMaxBoardDistanceM)) {
    msg << "ShadowMapPreparationOptions::board_distance_m = " << board_distance_m << ". Violated constraint: [0, "
        << kMaxBoardDistanceM << "] m (--board-distance-m; 0 = the manifest's)";
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

// Dark frames: their mean in raw DN above black (for the shot noise of the signal above it) and
// linearised (subtracted in the linear domain), and the read noise from their spread (raw DN).
struct DarkLevel {
  Image raw_dn, linear_dn;
  double read_variance_dn2 = 0;
  bool empty() const { return raw_dn.empty(); }
};

// Averages frames of one kind, linearised by the camera response (nullptr = linear) and
// normalised by exposure, with a saturation mask. Variance from the noise model (shot noise;
// the read noise from it or from the dark frames) or the frame's own variance_file, in raw DN,
// times the response's slope squared.
Status AverageFrames(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                     const CameraResponse* response, const std::vector<const FrameRecord*>& frames,
                     const DarkLevel& dark, const FrameNoiseModel& noise, AveragedFrames* out) {
  out->count = static_cast<int>(frames.size());
  const int w = camera.width_px, h = camera.height_px;
  Image sum(w, h), sum_exposure_var(w, h), saturated(w, h);
  const float saturation_above_black = static_cast<float>(camera.saturation_dn - camera.black_level_dn);
  const bool test_saturation = camera.bit_depth != 32 || camera.linear_frames();
  // Without a model ("default": no gain and nothing to estimate from) there is no shot noise.
  const double variance_per_value =
      noise.method == "default" ? (camera.gain_e_per_dn > 0 ? 1 / camera.gain_e_per_dn : 0.0) : noise.variance_per_value;
  const double read_variance = noise.variance_floor.value_or(dark.read_variance_dn2);
  for (const FrameRecord* frame : frames) {
    Image dn, own_variance;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frame, &dn));
    THINSLAB_RETURN_IF_ERROR(LoadFrameVariance(session_dir, session, *frame, &own_variance));
    const double t = frame->exposure_time_us;
    for (size_t i = 0; i < dn.data().size(); ++i) {
      const float z = dn.data()[i];
      if (test_saturation && z >= saturation_above_black - 0.5f) saturated.data()[i] = 1;
      double v = response != nullptr ? response->Linearize(z) : z;
      const double slope = response != nullptr ? response->Slope(z) : 1.0;
      double signal_dn = z;
      if (!dark.empty()) {
        v -= dark.linear_dn.data()[i];
        signal_dn -= dark.raw_dn.data()[i];
      }
      sum.data()[i] += static_cast<float>(v / t);
      const double frame_variance = own_variance.empty()
                                        ? variance_per_value * std::max(0.0, signal_dn) + read_variance
                                        : own_variance.data()[i];
      sum_exposure_var.data()[i] += static_cast<float>(Sqr(slope) * frame_variance / (t * t));
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

Status AverageDarks(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                    const CameraResponse* response, const std::vector<const FrameRecord*>& dark_frames,
                    DarkLevel* dark) {
  if (dark_frames.empty()) return Status::Ok();
  std::vector<Image> darks(dark_frames.size());
  for (size_t k = 0; k < dark_frames.size(); ++k) {
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *dark_frames[k], &darks[k]));
  }
  dark->raw_dn = Image(camera.width_px, camera.height_px);
  dark->linear_dn = Image(camera.width_px, camera.height_px);
  const float n = static_cast<float>(darks.size());
  for (Image& d : darks) {
    for (size_t i = 0; i < d.data().size(); ++i) dark->raw_dn.data()[i] += d.data()[i] / n;
  }
  double sum_sq = 0;
  for (Image& d : darks) {
    for (size_t i = 0; i < d.data().size(); ++i) sum_sq += Sqr(d.data()[i] - dark->raw_dn.data()[i]);
    LinearizeFrame(response, &d);
    for (size_t i = 0; i < d.data().size(); ++i) dark->linear_dn.data()[i] += d.data()[i] / n;
  }
  if (darks.size() > 1) dark->read_variance_dn2 = sum_sq / (dark->raw_dn.data().size() * (darks.size() - 1));
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
  maps->camera = session.rig.cameras[0];
  SessionCalibrationOptions calibration = options.calibration;
  calibration.flat_field = options.load_flat_field && calibration.mode != "none";
  THINSLAB_RETURN_IF_ERROR(LoadSessionCalibration(session_dir, calibration, &maps->camera, &maps->calibration));
  const CameraInfo& camera = maps->camera;
  const CameraResponse* response = maps->calibration.response_or_null();
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
  const auto validation_frames = of_camera(session.ValidationFrames("shadow"));
  if (shadow_frames.empty()) {
    return Status::Error(manifest + ": frames: no usable frame of kind 'shadow' for camera '" + camera.id + "'");
  }

  DarkLevel dark;
  THINSLAB_RETURN_IF_ERROR(AverageDarks(session_dir, session, camera, response, dark_frames, &dark));
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(session_dir, session, camera, &maps->noise));
  AveragedFrames shadow, reference;
  THINSLAB_RETURN_IF_ERROR(
      AverageFrames(session_dir, session, camera, response, shadow_frames, dark, maps->noise, &shadow));
  if (!reference_frames.empty()) {
    THINSLAB_RETURN_IF_ERROR(
        AverageFrames(session_dir, session, camera, response, reference_frames, dark, maps->noise, &reference));
  }

  // Rectification onto the board plane over the manifest's region grid.
  const SampleInfo& sample = session.rig.sample;
  const double p = sample.pixel_pitch_m;
  int w = 0, h = 0;
  THINSLAB_RETURN_IF_ERROR(ShadowMapGridSize(session, manifest, &w, &h));
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
  maps->camera_footprint_m = CameraFootprintM(camera, grid);
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
  if (options.split_halves && shadow_frames.size() >= 2) {
    // Alternate frames, so a slow drift of the light falls into both halves alike.
    auto half_of = [](const std::vector<const FrameRecord*>& frames, size_t parity) {
      std::vector<const FrameRecord*> out;
      for (size_t k = parity; k < frames.size(); k += 2) out.push_back(frames[k]);
      return out;
    };
    maps->halves_share_reference = reference_frames.size() < 2;
    for (size_t parity = 0; parity < 2; ++parity) {
      AveragedFrames half;
      THINSLAB_RETURN_IF_ERROR(AverageFrames(session_dir, session, camera, response, half_of(shadow_frames, parity),
                                             dark, maps->noise, &half));
      RectifiedShadowMaps::Half out;
      out.shadow = rectifier.Rectify(half.mean_dn_per_us);
      out.shadow_variance = rectifier.RectifyVariance(half.variance);
      if (!maps->halves_share_reference) {
        AveragedFrames half_reference;
        THINSLAB_RETURN_IF_ERROR(AverageFrames(session_dir, session, camera, response,
                                               half_of(reference_frames, parity), dark, maps->noise, &half_reference));
        out.reference = rectifier.Rectify(half_reference.mean_dn_per_us);
        out.reference_variance = rectifier.RectifyVariance(half_reference.variance);
      } else {
        out.reference = maps->reference;
        out.reference_variance = maps->reference_variance;
      }
      maps->halves.push_back(std::move(out));
    }
  }
  if (!validation_frames.empty()) {
    AveragedFrames validation;
    THINSLAB_RETURN_IF_ERROR(
        AverageFrames(session_dir, session, camera, response, validation_frames, dark, maps->noise, &validation));
    maps->num_validation_frames = validation.count;
    maps->validation_shadow = rectifier.Rectify(validation.mean_dn_per_us);
    maps->validation_shadow_variance = rectifier.RectifyVariance(validation.variance);
    maps->validation_saturated = rectifier.RectifyAny(validation.saturated);
    if (options.keep_camera_frames) {
      shadow = std::move(validation);
    }
  }
  if (options.keep_camera_frames) {
    maps->camera_reference = reference.mean_dn_per_us;
    maps->camera_reference_variance = reference.variance;
    maps->camera_shadow = std::move(shadow.mean_dn_per_us);
    maps->camera_shadow_variance = std::move(shadow.variance);
    maps->camera_shadow_saturated = std::move(shadow.saturated);
    for (size_t i = 0; i < reference.saturated.data().size(); ++i) {
      if (reference.saturated.data()[i] > 0) maps->camera_shadow_saturated.data()[i] = 1;
    }
  }
  if (!maps->calibration.flat_field.empty()) {
    // A map pixel touching an invalid flat-field pixel gets no flat (0).
    Image invalid(camera.width_px, camera.height_px);
    for (size_t i = 0; i < invalid.data().size(); ++i)
      invalid.data()[i] = maps->calibration.flat_field.data()[i] > 0 ? 0 : 1;
    maps->flat = rectifier.Rectify(maps->calibration.flat_field);
    const Image flat_invalid = rectifier.RectifyAny(invalid);
    for (size_t i = 0; i < maps->flat.data().size(); ++i) {
      if (flat_invalid.data()[i] > 0) maps->flat.data()[i] = 0;
    }
  }
  return Status::Ok();
}

Status ShadowMapGridSize(const Session& session, const std::string& manifest, int* width, int* height) {
  const SampleInfo& sample = session.rig.sample;
  return CheckedGridSize(sample.region_max_m.x() - sample.region_min_m.x(),
                         sample.region_max_m.y() - sample.region_min_m.y(), sample.pixel_pitch_m,
                         GridRounding::kNearest, 1,
                         manifest + ": rig.sample (region_min_m, region_max_m, pixel_pitch_m)", width, height);
}

}  // namespace thinslab
