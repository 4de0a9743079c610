// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/exposure_bracket_sim.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <sstream>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/sim/sim_session.h"

namespace thinslab {

bool BracketSimOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (width_px < 1 || height_px < 1 || static_cast<double>(width_px) * height_px > 1e8) {
    msg << "BracketSimOptions::width_px/height_px = " << width_px << "x" << height_px << ". Violated constraint: 1..1e8 pixels";
  } else if (!(min_e_per_us > 0 && max_e_per_us > min_e_per_us)) {
    msg << "BracketSimOptions::min_e_per_us/max_e_per_us = " << min_e_per_us << "/" << max_e_per_us
        << ". Violated constraint: 0 < min < max";
  } else if (!(texture_amplitude >= 0 && texture_amplitude < 1)) {
    msg << "BracketSimOptions::texture_amplitude = " << texture_amplitude << ". Violated constraint: [0, 1)";
  } else if (!(ambient_e_per_us >= 0)) {
    msg << "BracketSimOptions::ambient_e_per_us = " << ambient_e_per_us << ". Violated constraint: >= 0";
  } else if (exposures_us.empty()) {
    msg << "BracketSimOptions::exposures_us is empty";
  } else if (frames_per_exposure < 1 || dark_frames_per_exposure < 0) {
    msg << "BracketSimOptions::frames_per_exposure = " << frames_per_exposure
        << ", dark_frames_per_exposure = " << dark_frames_per_exposure << ". Violated constraint: >= 1, >= 0";
  } else {
    for (size_t k = 0; k < exposures_us.size(); ++k) {
      if (!(exposures_us[k] > 0)) {
        msg << "BracketSimOptions::exposures_us[" << k << "] = " << exposures_us[k] << ". Violated constraint: > 0";
        *error = msg.str();
        return false;
      }
    }
    return sensor.Check(error);
  }
  *error = msg.str();
  return false;
}

Image MakeBracketScene(const BracketSimOptions& options) {
  const int w = options.width_px, h = options.height_px;
  Image scene(w, h);
  const double log_min = std::log(options.min_e_per_us), log_max = std::log(options.max_e_per_us);
  for (int y = 0; y < h; ++y) {
    // Rows are shifted by up to a fifth of the span, so every irradiance occurs at several
    // positions and no two rows are identical.
    const double shift = 0.2 * (log_max - log_min) * ((y * 7919) % h) / std::max(h, 1);
    for (int x = 0; x < w; ++x) {
      const double u = w > 1 ? static_cast<double>(x) / (w - 1) : 0.5;
      double log_e = log_min + u * (log_max - log_min) * 0.8 + shift;
      const double texture = 1.0 + options.texture_amplitude * std::sin(0.37 * x) * std::cos(0.23 * y);
      scene.at(x, y) = static_cast<float>(std::exp(log_e) * texture);
    }
  }
  return scene;
}

Status SimulateBracket(const BracketSimOptions& options, SimulatedBracket* bracket) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  *bracket = SimulatedBracket();
  bracket->scene_e_per_us = MakeBracketScene(options);
  const Image& scene = bracket->scene_e_per_us;
  uint64_t stream = options.seed * 1000003ULL;
  for (double requested_us : options.exposures_us) {
    const double t = options.sensor.AppliedExposureUs(requested_us);  // What the camera reports.
    const double integrated = options.sensor.IntegratedExposureUs(requested_us);
    Image electrons(scene.width(), scene.height());
    Image ambient(scene.width(), scene.height());
    for (size_t i = 0; i < scene.data().size(); ++i) {
      electrons.data()[i] = static_cast<float>((scene.data()[i] + options.ambient_e_per_us) * integrated);
      ambient.data()[i] = static_cast<float>(options.ambient_e_per_us * integrated);
    }
    for (int n = 0; n < options.frames_per_exposure; ++n) {
      bracket->frames.push_back(ApplySensor(electrons, options.sensor, ++stream));
      bracket->frame_exposures_us.push_back(t);
    }
    for (int n = 0; n < options.dark_frames_per_exposure; ++n) {
      bracket->darks.push_back(ApplySensor(ambient, options.sensor, ++stream));
      bracket->dark_exposures_us.push_back(t);
    }
  }
  return Status::Ok();
}

namespace {

const char* CurveName(SimResponseCurve curve) {
  switch (curve) {
    case SimResponseCurve::kLinear:
      return "linear";
    case SimResponseCurve::kGamma:
      return "gamma";
    case SimResponseCurve::kSCurve:
      return "s_curve";
  }
  return "linear";
}

}  // namespace

Status SynthesizeBracketSession(const BracketSimOptions& options, const std::string& session_dir) {
  SimulatedBracket bracket;
  THINSLAB_RETURN_IF_ERROR(SimulateBracket(options, &bracket));
  const SimSensorOptions& sensor = options.sensor;
  RigInfo rig;
  CameraInfo camera;
  camera.id = "cam0";
  camera.model = "sim";
  camera.width_px = options.width_px;
  camera.height_px = options.height_px;
  camera.fx_px = camera.fy_px = 1000;
  camera.cx_px = 0.5 * options.width_px - 0.5;
  camera.cy_px = 0.5 * options.height_px - 0.5;
  camera.cam_from_sample.translation = Eigen::Vector3d(0, 0, 0.5);
  sensor.DescribeCamera(&camera, sensor.response == SimResponseCurve::kLinear);
  rig.cameras.push_back(camera);
  rig.sample.region_min_m = Eigen::Vector2d(-0.01, -0.01);
  rig.sample.region_max_m = Eigen::Vector2d(0.01, 0.01);
  rig.sample.pixel_pitch_m = 1e-4;
  SessionWriter writer;
  THINSLAB_RETURN_IF_ERROR(OpenSimulatedSession(session_dir, "bracket", "exposure_bracket", rig, &writer));
  auto add = [&](const Image& raw, double t, const std::string& kind) {
    FrameRecord record;
    record.camera_id = "cam0";
    record.kind = kind;
    record.exposure_time_us = t;
    record.light.projector_pattern = kind == "dark" ? "" : "flat";
    record.timestamp_utc = UtcTimestampNow();
    return writer.AddFrame(record, raw);
  };
  for (size_t k = 0; k < bracket.frames.size(); ++k) {
    THINSLAB_RETURN_IF_ERROR(add(bracket.frames[k], bracket.frame_exposures_us[k], "bracket"));
  }
  for (size_t k = 0; k < bracket.darks.size(); ++k) {
    THINSLAB_RETURN_IF_ERROR(add(bracket.darks[k], bracket.dark_exposures_us[k], "dark"));
  }
  THINSLAB_RETURN_IF_ERROR(writer.Save());
  const std::string truth_dir = JoinPath(session_dir, "ground_truth");
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(truth_dir));
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(truth_dir, "scene.exr"), bracket.scene_e_per_us));
  nlohmann::json truth;
  truth["scene"] = "scene.exr: noise-free scene irradiance without ambient light, photo-electrons per microsecond";
  truth["response_curve"] = CurveName(sensor.response);
  truth["response_gamma"] = sensor.response_gamma;
  truth["full_well_e"] = sensor.full_well_e;
  truth["read_noise_e"] = sensor.read_noise_e;
  truth["bit_depth"] = sensor.bit_depth;
  truth["black_level_dn"] = sensor.black_level_dn;
  truth["ambient_e_per_us"] = options.ambient_e_per_us;
  return WriteFileAtomically(JoinPath(truth_dir, "truth.json"), truth.dump(2) + "\n");
}

}  // namespace thinslab
