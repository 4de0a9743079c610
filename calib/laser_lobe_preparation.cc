// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/laser_lobe_preparation.h"

#include <cmath>
#include <set>
#include <sstream>
#include <vector>

#include "thinslab/core/grid_size.h"
#include "thinslab/calib/board_rectification.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

bool LaserLobePreparationOptions::Check(std::string* error) const {
  if (supersample < 1 || supersample > 8) {
    *error =
        "LaserLobePreparationOptions::supersample = " + std::to_string(supersample) + ". Violated constraint: 1..8";
    return false;
  }
  if (!(board_distance_m >= 0 && board_distance_m <= kMaxBoardDistanceM)) {
    *error = "LaserLobePreparationOptions::board_distance_m = " + std::to_string(board_distance_m) +
             ". Violated constraint: [0, " + std::to_string(kMaxBoardDistanceM) +
             "] m (--board-distance-m; 0 = the manifest's)";
    return false;
  }
  if (!(board_pitch_m == 0 || (board_pitch_m >= 1e-6 && board_pitch_m <= 0.01))) {
    *error = "LaserLobePreparationOptions::board_pitch_m = " + std::to_string(board_pitch_m) +
             ". Violated constraint: 0 (the manifest's) or [1e-6, 0.01] m (--board-pitch-m)";
    return false;
  }
  return true;
}

namespace {

Status MergeAndRectify(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                       const CameraResponse* response, const std::vector<const FrameRecord*>& frames,
                       double read_noise_dn, const FrameNoiseModel& noise, const BoardRectifier& rectifier,
                       bool keep_camera, BoardHdr* out) {
  if (frames.empty()) return Status::Ok();
  std::vector<Image> images(frames.size()), variances(frames.size());
  std::vector<HdrFrame> hdr_frames;
  std::set<double> exposures;
  for (size_t k = 0; k < frames.size(); ++k) {
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frames[k], &images[k]));
    THINSLAB_RETURN_IF_ERROR(LoadFrameVariance(session_dir, session, *frames[k], &variances[k]));
    hdr_frames.push_back({&images[k], frames[k]->exposure_time_us});
    if (!variances[k].empty()) hdr_frames.back().variance_dn2 = &variances[k];
    exposures.insert(frames[k]->exposure_time_us);
  }
  HdrMergeOptions merge_options;
  merge_options.saturation_dn = camera.saturation_dn - camera.black_level_dn;
  merge_options.gain_e_per_dn = noise.method == "default" ? camera.gain_e_per_dn : noise.gain_e_per_dn();
  // An estimated or declared floor is the read noise; the 0.5 DN floor is for integer darks.
  merge_options.read_noise_dn = noise.variance_floor.has_value() ? std::sqrt(*noise.variance_floor)
                                                                 : std::max(read_noise_dn, 0.5);
  merge_options.response = response;
  merge_options.black_level_dn = camera.black_level_dn;
  if (exposures.size() >= 2 && !camera.linear_frames()) {
    THINSLAB_RETURN_IF_ERROR(CheckBracketExposures(hdr_frames, merge_options, &out->exposure_check));
  }
  HdrImage hdr;
  THINSLAB_RETURN_IF_ERROR(MergeExposureBracket(hdr_frames, merge_options, &hdr));
  out->radiance = rectifier.Rectify(hdr.radiance);
  out->variance = rectifier.RectifyVariance(hdr.variance);  // Of the board pixel's mean.
  out->all_saturated = rectifier.RectifyAny(hdr.all_saturated);
  if (keep_camera) {
    out->camera_radiance = std::move(hdr.radiance);
    out->camera_variance = std::move(hdr.variance);
    out->camera_all_saturated = std::move(hdr.all_saturated);
  }
  out->num_frames = static_cast<int>(frames.size());
  out->num_exposures = static_cast<int>(exposures.size());
  return Status::Ok();
}

}  // namespace

Status PrepareLaserLobe(const std::string& session_dir, const Session& session,
                        const LaserLobePreparationOptions& options, LaserLobeImages* images) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras: no camera");
  if (!session.rig.board.present) {
    return Status::Error(manifest + ": rig.board: missing; the laser-lobe fit needs the board distance (Gu Eq. 8)");
  }
  images->camera = session.rig.cameras[0];
  THINSLAB_RETURN_IF_ERROR(
      LoadSessionCalibration(session_dir, options.calibration, &images->camera, &images->calibration));
  const CameraInfo& camera = images->camera;
  const CameraResponse* response = images->calibration.response_or_null();
  auto of_camera = [&](const std::vector<const FrameRecord*>& frames) {
    std::vector<const FrameRecord*> out;
    for (const FrameRecord* f : frames) {
      if (f->camera_id == camera.id) out.push_back(f);
    }
    return out;
  };
  const auto lobe = of_camera(session.UsableFrames("laser", "contaminated"));
  if (lobe.empty()) {
    return Status::Error(manifest + ": frames: no usable frame of kind 'laser' with sample_state 'contaminated'");
  }
  std::set<double> lobe_exposures;
  for (const auto* f : lobe) lobe_exposures.insert(f->exposure_time_us);
  // Linear frames (frame_values "linear": merged HDR, a renderer) already hold the whole range.
  if (lobe_exposures.size() < 2 && !camera.linear_frames()) {
    return Status::Error(manifest + ": frames: the 'laser' frames hold a single exposure_time_us (" +
                         std::to_string(*lobe_exposures.begin()) +
                         "); the lobe spans many decades and needs an exposure bracket (>= 2 exposures), or frames "
                         "already linear over that range declared with rig.cameras[].frame_values \"linear\"");
  }
  // Read noise from the dark frames' spread around their mean, per exposure group.
  const auto darks = of_camera(session.UsableFrames("dark"));
  double read_noise = 1.0;
  if (!darks.empty()) {
    double sum = 0, sum_sq = 0;
    size_t n = 0;
    for (const FrameRecord* f : darks) {
      Image dark;
      THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *f, &dark));
      for (float v : dark.data()) {
        sum += v;
        sum_sq += static_cast<double>(v) * v;
        ++n;
      }
    }
    const double mean = sum / n;
    read_noise = std::sqrt(std::max(sum_sq / n - mean * mean, 0.25));
  }
  const SampleInfo& sample = session.rig.sample;
  const double p = options.board_pitch_m > 0 ? options.board_pitch_m : sample.pixel_pitch_m;
  BoardGrid grid;
  grid.grid_min_m = sample.region_min_m;
  grid.pixel_pitch_m = p;
  THINSLAB_RETURN_IF_ERROR(CheckedGridSize(sample.region_max_m.x() - sample.region_min_m.x(),
                                           sample.region_max_m.y() - sample.region_min_m.y(), p, GridRounding::kNearest,
                                           8, manifest + ": rig.sample (region_min_m, region_max_m, pixel_pitch_m" +
                                               (options.board_pitch_m > 0 ? " replaced by --board-pitch-m)" : ")"),
                                           &grid.width_px, &grid.height_px));
  const double board_distance_m =
      options.board_distance_m > 0 ? options.board_distance_m : session.rig.board.distance_m;
  grid.plane_z_m = -board_distance_m;
  grid.supersample = options.supersample;
  const BoardRectifier rectifier(camera, grid);
  images->outside = rectifier.outside();
  images->grid_min_m = grid.grid_min_m;
  images->pixel_pitch_m = p;
  images->board_distance_m = board_distance_m;
  images->beam_radius_m = session.rig.laser.present ? session.rig.laser.beam_radius_m : 0.0;
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(session_dir, session, camera, &images->noise));
  if (images->noise.variance_floor.has_value()) read_noise = std::sqrt(*images->noise.variance_floor);
  images->read_noise_dn = read_noise;
  const FrameNoiseModel& noise = images->noise;
  THINSLAB_RETURN_IF_ERROR(
      MergeAndRectify(session_dir, session, camera, response, lobe, read_noise, noise, rectifier,
                      options.keep_camera_hdr, &images->lobe));
  THINSLAB_RETURN_IF_ERROR(MergeAndRectify(session_dir, session, camera, response,
                                           of_camera(session.UsableFrames("laser", "clean")), read_noise, noise,
                                           rectifier, options.keep_camera_hdr, &images->clean));
  THINSLAB_RETURN_IF_ERROR(MergeAndRectify(session_dir, session, camera, response,
                                           of_camera(session.UsableFrames("flat")), read_noise, noise, rectifier,
                                           options.keep_camera_hdr, &images->flat));
  const auto validation = of_camera(session.ValidationFrames("laser", "contaminated"));
  std::set<double> validation_exposures;
  for (const auto* f : validation) validation_exposures.insert(f->exposure_time_us);
  if (validation_exposures.size() == 1 && !camera.linear_frames()) {
    return Status::Error(manifest + ": frames: the validation 'laser' frames hold a single exposure_time_us (" +
                         std::to_string(*validation_exposures.begin()) +
                         "); a validation lobe needs an exposure bracket like the fitted one");
  }
  THINSLAB_RETURN_IF_ERROR(MergeAndRectify(session_dir, session, camera, response, validation, read_noise, noise,
                                           rectifier, options.keep_camera_hdr, &images->validation_lobe));
  return Status::Ok();
}

}  // namespace thinslab
