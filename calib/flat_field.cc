// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/flat_field.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "thinslab/calib/hdr_merge.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"

namespace thinslab {

bool FlatFieldOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(smoothing_sigma_px >= 0 && smoothing_sigma_px <= 200)) {
    msg << "FlatFieldOptions::smoothing_sigma_px = " << smoothing_sigma_px << ". Violated constraint: [0, 200]";
  } else if (!(min_relative >= 0 && min_relative < 1)) {
    msg << "FlatFieldOptions::min_relative = " << min_relative << ". Violated constraint: [0, 1)";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::string FlatFieldSummary::BriefReport() const {
  std::ostringstream out;
  out << "flat field from " << num_frames << " '" << kind << "' frames (" << num_exposures << " exposures, "
      << num_darks << " darks), median " << median_dn_per_us << " DN/us, " << pixels_valid << " valid / "
      << pixels_invalid << " invalid pixels, read noise " << read_noise_dn << " DN";
  return out.str();
}

Status ComputeFlatField(const Image& radiance, const Image& variance, const Image& all_saturated,
                        const FlatFieldOptions& options, Image* flat, FlatFieldSummary* summary) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const int w = radiance.width(), h = radiance.height();
  if (variance.width() != w || variance.height() != h || all_saturated.width() != w || all_saturated.height() != h) {
    return Status::Error("ComputeFlatField: radiance, variance and all_saturated differ in size");
  }
  std::vector<float> values;
  values.reserve(radiance.num_pixels());
  for (size_t i = 0; i < radiance.num_pixels(); ++i) {
    const float r = radiance.data()[i];
    if (all_saturated.data()[i] == 0 && std::isfinite(r) && r > 0) values.push_back(r);
  }
  if (values.empty()) return Status::Error("ComputeFlatField: no pixel is lit and unsaturated");
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double median = values[values.size() / 2];
  cv::Mat value(h, w, CV_32F, cv::Scalar(0)), mask(h, w, CV_32F, cv::Scalar(0)), var(h, w, CV_32F, cv::Scalar(0));
  int64_t valid = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float r = radiance.at(x, y);
      const bool ok = all_saturated.at(x, y) == 0 && std::isfinite(r) && r >= options.min_relative * median;
      if (!ok) continue;
      value.at<float>(y, x) = static_cast<float>(r / median);
      var.at<float>(y, x) = static_cast<float>(variance.at(x, y) / (median * median));
      mask.at<float>(y, x) = 1;
      ++valid;
    }
  }
  if (valid == 0) return Status::Error("ComputeFlatField: no valid pixel");
  double variance_factor = 1.0;
  if (options.smoothing_sigma_px > 0) {
    // Normalised convolution: invalid pixels neither contribute nor pull the edges down.
    const double s = options.smoothing_sigma_px;
    cv::GaussianBlur(value, value, cv::Size(), s, s, cv::BORDER_REFLECT);
    cv::GaussianBlur(mask, mask, cv::Size(), s, s, cv::BORDER_REFLECT);
    cv::GaussianBlur(var, var, cv::Size(), s, s, cv::BORDER_REFLECT);
    // A 2-D Gaussian average of independent samples has sum(k^2) = 1 / (4 pi sigma^2) of their variance.
    variance_factor = std::min(1.0, 1.0 / (4.0 * kPi * s * s));
  }
  *flat = Image(w, h, {"flat", "variance", "valid"});
  int64_t flagged = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float m = mask.at<float>(y, x);
      const bool ok = m > 0.25f;
      flat->at(x, y, 0) = ok ? value.at<float>(y, x) / m : 1.0f;
      flat->at(x, y, 1) = ok ? static_cast<float>(var.at<float>(y, x) / m * variance_factor) : 0.0f;
      flat->at(x, y, 2) = ok ? 1.0f : 0.0f;
      if (!ok) ++flagged;
    }
  }
  summary->median_dn_per_us = median;
  summary->pixels_valid = static_cast<int64_t>(w) * h - flagged;
  summary->pixels_invalid = flagged;
  return Status::Ok();
}

Status ComputeSessionFlatField(const std::string& session_dir, const Session& session, const CameraResponse* response,
                               const FlatFieldOptions& options, Image* flat, FlatFieldSummary* summary) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras: no camera");
  const CameraInfo& camera = session.rig.cameras[0];
  auto of_camera = [&](const std::vector<const FrameRecord*>& frames) {
    std::vector<const FrameRecord*> out;
    for (const FrameRecord* f : frames) {
      if (f->camera_id == camera.id) out.push_back(f);
    }
    return out;
  };
  std::string kind = options.kind;
  if (kind.empty()) kind = of_camera(session.UsableFrames("flat")).empty() ? "reference" : "flat";
  const auto frames = of_camera(session.UsableFrames(kind));
  if (frames.empty()) {
    return Status::Error(manifest + ": frames: no usable frame of kind '" + kind + "' for camera '" + camera.id +
                         "' (the flat field needs 'flat' or clean-glass 'reference' frames)");
  }
  if (response != nullptr && !response->camera_id.empty() && response->camera_id != camera.id) {
    return Status::Error("response: camera '" + response->camera_id + "' differs from the session's '" + camera.id + "'");
  }
  HdrImage hdr;
  SessionMergeInfo info;
  FrameNoiseModel noise;
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(session_dir, session, camera, &noise));
  THINSLAB_RETURN_IF_ERROR(MergeSessionBracket(session_dir, session, camera, frames, of_camera(session.UsableFrames("dark")),
                                               response, HdrMergeOptions(), 1.0, noise, &hdr, &info));
  summary->noise = noise;
  *summary = FlatFieldSummary();
  summary->kind = kind;
  summary->num_frames = info.num_frames;
  summary->num_exposures = info.num_exposures;
  summary->num_darks = info.num_darks;
  summary->read_noise_dn = info.read_noise_dn;
  return ComputeFlatField(hdr.radiance, hdr.variance, hdr.all_saturated, options, flat, summary)
      .WithContext(session_dir);
}

}  // namespace thinslab
