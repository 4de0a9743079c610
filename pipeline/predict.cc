// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/predict.h"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/folder_report.h"
#include "thinslab/pipeline/prediction_report.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/fit/dmf_prediction.h"

namespace thinslab {

// "x,y;x,y" [monitor px].
Status ParseDotList(const std::string& text, std::vector<Eigen::Vector2d>* dots) {
  std::stringstream items(text);
  std::string item;
  while (std::getline(items, item, ';')) {
    double x, y;
    char tail = 0;
    if (std::sscanf(item.c_str(), "%lf,%lf%c", &x, &y, &tail) != 2 || !std::isfinite(x) || !std::isfinite(y) || x < 0 ||
        y < 0 || x > 1e6 || y > 1e6) {
      return Status::Error("--dots: '" + item + "' is not 'x,y' in monitor px (0..1e6); expected 'x,y;x,y;...'");
    }
    dots->emplace_back(x, y);
  }
  if (dots->empty()) return Status::Error("--dots: no dot given; expected 'x,y;x,y;...'");
  return Status::Ok();
}

Status ValidationDots(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                      std::vector<Eigen::Vector2d>* dots) {
  dots->clear();
  for (const FrameRecord* f : session.ValidationFrames("dot")) {
    if (f->camera_id != camera.id || !f->light.dot_px) continue;
    bool seen = false;
    for (const Eigen::Vector2d& d : *dots) seen = seen || (d - *f->light.dot_px).norm() < 1e-9;
    if (!seen) dots->push_back(*f->light.dot_px);
  }
  if (dots->empty()) {
    return Status::Error(JoinPath(session_dir, kSessionManifestName) +
                         ": no validation dot frames (frames[k].validation); give the dots with --dots 'x,y;...'");
  }
  return Status::Ok();
}

Status MergeDotFrames(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                      const SessionCalibration& calibration, const FrameNoiseModel& noise,
                      const Eigen::Vector2d& dot_px, HdrImage* hdr, bool* found) {
  // The capture's frames of this dot, fitted or validation, in the fit's sample state.
  std::vector<const FrameRecord*> frames;
  for (const FrameRecord& f : session.frames) {
    if (f.kind == "dot" && f.status != FrameStatus::kFailed && f.camera_id == camera.id && f.light.dot_px &&
        (*f.light.dot_px - dot_px).norm() < 1e-9) {
      frames.push_back(&f);
    }
  }
  *found = !frames.empty();
  if (frames.empty()) return Status::Ok();
  SessionMergeInfo info;
  const auto darks = session.UsableFrames("dark", frames.front()->sample_state);
  return MergeSessionBracket(session_dir, session, camera, frames, darks, calibration.response_or_null(),
                             HdrMergeOptions(), 1.0, noise, hdr, &info)
      .WithContext("dot (" + std::to_string(dot_px.x()) + ", " + std::to_string(dot_px.y()) + ")");
}

namespace {

// Which fit FIT_DIR holds, from its files; without --fit, the capture kind's fit folder.
Status ResolveFit(const std::string& session_dir, const Session& session, std::string* fit_dir, std::string* kind) {
  const std::string fits = JoinPath(session_dir, "fit");
  if (fit_dir->empty()) {
    if (session.kind == "shadow_map") {
      *fit_dir = JoinPath(fits, "tau");
    } else if (session.kind == "laser_lobe") {
      *fit_dir = JoinPath(fits, "phase");
    } else if (session.kind == "dot_scan") {
      *fit_dir = JoinPath(fits, "dmf");
    } else {
      return Status::Error(JoinPath(session_dir, kSessionManifestName) + ": kind \"" + session.kind +
                           "\": predict knows shadow_map, laser_lobe and dot_scan captures; give the fit with --fit");
    }
  }
  if (FileExists(JoinPath(*fit_dir, "tau.exr"))) {
    *kind = "tau";
  } else if (FileExists(JoinPath(*fit_dir, "rings.csv"))) {
    *kind = "phase";
  } else if (FileExists(JoinPath(*fit_dir, "maps.exr"))) {
    *kind = "dmf";
  } else {
    return Status::Error(*fit_dir + ": not an output of `thinslab fit tau`, `fit phase` or `fit dmf` (no tau.exr, "
                                    "rings.csv or maps.exr); run the fit first or give its folder with --fit");
  }
  return Status::Ok();
}

}  // namespace

Status PredictCapture(const PredictCaptureRun& run, std::ostream& log) {
  const std::string &session_dir = run.session_dir, &dots_text = run.dots;
  std::string fit_dir = run.fit_dir, out_dir = run.out_dir;
  const SessionCalibrationOptions& calibration_options = run.calibration;
  const bool allow_incomplete = run.allow_incomplete_capture;
  if (session_dir.empty()) return Status::Error("thinslab predict: CAPTURE is required");
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, allow_incomplete, &session));
  std::vector<Eigen::Vector2d> dots;
  if (!dots_text.empty()) THINSLAB_RETURN_IF_ERROR(ParseDotList(dots_text, &dots));
  std::string kind;
  THINSLAB_RETURN_IF_ERROR(ResolveFit(session_dir, session, &fit_dir, &kind));
  if (!dots.empty() && kind != "dmf") {
    return Status::Error("thinslab predict: --dots applies to `fit dmf` outputs; " + fit_dir + " is a `fit " + kind +
                         "` output");
  }
  if (out_dir.empty()) out_dir = JoinPath(JoinPath(session_dir, "fit"), "predict");
  StagedDirectory out(out_dir, "predict", {{session_dir, {"fit"}}, {fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());
  if (!run.options_ini.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), run.options_ini));
  }
  if (kind != "dmf") {
    const PredictRun layer{session_dir, fit_dir, out_dir, calibration_options, run.options_ini};
    return kind == "tau" ? PredictShadowFromTau(layer, session, &out) : PredictLobeFromPhase(layer, session, &out);
  }
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras is empty");
  DmfFitOnDisk fit;
  THINSLAB_RETURN_IF_ERROR(ReadDmfFit(fit_dir, &fit));
  CameraInfo camera = session.rig.cameras[0];
  SessionCalibration calibration;
  THINSLAB_RETURN_IF_ERROR(LoadSessionCalibration(session_dir, calibration_options, &camera, &calibration));

  // The dots: given, else the capture's validation dots.
  if (dots.empty()) THINSLAB_RETURN_IF_ERROR(ValidationDots(session_dir, session, camera, &dots));

  FrameNoiseModel noise;
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(session_dir, session, camera, &noise));
  std::ostringstream dots_option;
  for (const Eigen::Vector2d& d : dots) dots_option << (dots_option.tellp() > 0 ? ";" : "") << d.x() << "," << d.y();
  const Provenance provenance{"predict", session_dir, fit_dir,
                              run.options_ini.empty() ? "dots = " + dots_option.str() + "\n" : run.options_ini};
  nlohmann::json entries = nlohmann::json::array();
  std::ostringstream txt;
  txt << "thinslab predict: " << dots.size() << " dots from " << fit_dir << " (NDF atlas stride " << fit.atlas_stride
      << (fit.atlas_stride > 1 ? ": points between the stored ones take the nearest stored NDF" : "") << ")\n";
  for (size_t k = 0; k < dots.size(); ++k) {
    Image image = PredictDotImage(fit, camera, dots[k]);
    nlohmann::json entry = {{"dot_px", {dots[k].x(), dots[k].y()}}, {"file", "dot_" + std::to_string(k) + ".exr"}};
    char line[256];
    HdrImage hdr;
    bool measured = false;
    THINSLAB_RETURN_IF_ERROR(
        MergeDotFrames(session_dir, session, camera, calibration, noise, dots[k], &hdr, &measured));
    entry["measured"] = measured;
    if (measured) {
      Image both(image.width(), image.height(), {"predicted", "valid", "measured", "variance"});
      for (int v = 0; v < image.height(); ++v) {
        for (int u = 0; u < image.width(); ++u) {
          both.at(u, v, 0) = image.at(u, v, 0);
          both.at(u, v, 1) = image.at(u, v, 1);
          both.at(u, v, 2) = hdr.radiance.at(u, v);
          both.at(u, v, 3) = hdr.variance.at(u, v);
        }
      }
      const DotPredictionError e = ComparePrediction(image, hdr.radiance, hdr.variance);
      entry["pixels"] = e.pixels;
      entry["relative_rms"] = e.relative_rms;
      entry["noise_relative_rms"] = e.noise_relative_rms;
      std::snprintf(line, sizeof(line), "  dot (%g, %g): in-lobe relative RMS %.3f (noise alone %.3f) over %d px\n",
                    dots[k].x(), dots[k].y(), e.relative_rms, e.noise_relative_rms, e.pixels);
      image = std::move(both);
    } else {
      std::snprintf(line, sizeof(line), "  dot (%g, %g): predicted (the capture has no frame of it)\n", dots[k].x(),
                    dots[k].y());
    }
    txt << line;
    image.attributes()["units"] = "DN/us, black level and darks removed (the HDR merge's radiance)";
    THINSLAB_RETURN_IF_ERROR(
        WriteMapExr(JoinPath(out.path(), entry["file"].get<std::string>()), image, {"predicted", {"valid"}}, provenance));
    entries.push_back(entry);
  }
  nlohmann::json j;
  j["format"] = "thinslab-predict-summary";
  j["provenance"] = ProvenanceJson(provenance);
  j["kind"] = "dots";
  j["session"] = session_dir;
  j["fit"] = fit_dir;
  j["lobe_fraction"] = 0.1;
  j["atlas_stride"] = fit.atlas_stride;
  j["dots"] = entries;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "summary.json"), j.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "summary.txt"), txt.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out.path(), out_dir, "thinslab predict: " + session_dir));
  THINSLAB_RETURN_IF_ERROR(out.Commit());
  log << txt.str() << "wrote " << out_dir << "\n";
  return Status::Ok();
}

}  // namespace thinslab
