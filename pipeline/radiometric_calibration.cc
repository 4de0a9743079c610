// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/radiometric_calibration.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include "thinslab/calib/flat_field.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/response_io.h"
#include "thinslab/calib/response_recovery.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/pipeline/calibration_summary.h"
#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/folder_report.h"

namespace thinslab {
namespace {


Status FindCamera(const std::string& session_dir, const Session& session, const std::string& camera_id,
                  const CameraInfo** camera) {
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras: no camera");
  if (camera_id.empty()) {
    *camera = &session.rig.cameras[0];
    return Status::Ok();
  }
  *camera = session.FindCamera(camera_id);
  if (*camera == nullptr) return Status::Error("--camera " + camera_id + ": no such camera in " + manifest);
  return Status::Ok();
}

std::vector<const FrameRecord*> OfCamera(const std::vector<const FrameRecord*>& frames, const CameraInfo& camera) {
  std::vector<const FrameRecord*> out;
  for (const FrameRecord* f : frames) {
    if (f->camera_id == camera.id) out.push_back(f);
  }
  return out;
}

// A bracket is the usable frames of one camera that show one scene: same kind, sample state and
// light state. Its name is used for the output file.
struct Group {
  std::string name;
  std::vector<const FrameRecord*> frames;
  std::set<double> exposures;
};

std::string Sanitize(const std::string& s) {
  std::string out;
  for (char c : s) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.') ? c : '_';
  return out;
}

std::vector<Group> GroupFrames(const Session& session, const CameraInfo& camera, const std::string& kind_filter) {
  std::map<std::string, Group> groups;
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed || f.validation || f.camera_id != camera.id || f.kind == "dark") continue;
    std::ostringstream name;
    name << Sanitize(f.kind);
    if (f.sample_state != "none") name << "_" << Sanitize(f.sample_state);
    if (!f.light.projector_pattern.empty() && f.light.projector_pattern != "flat") {
      name << "_" << Sanitize(f.light.projector_pattern);
    }
    if (f.light.laser_on && f.kind != "laser") name << "_laser";
    if (f.light.dot_px) name << "_dot" << f.light.dot_px->x() << "_" << f.light.dot_px->y();
    // --kind selects by frame kind or by group name (e.g. "laser_contaminated").
    if (!kind_filter.empty() && f.kind != kind_filter && Sanitize(name.str()) != kind_filter) continue;
    Group& g = groups[Sanitize(name.str())];
    g.name = Sanitize(name.str());
    g.frames.push_back(&f);
    g.exposures.insert(f.exposure_time_us);
  }
  std::vector<Group> out;
  for (auto& [name, g] : groups) out.push_back(std::move(g));
  return out;
}

// A bracket loaded for response recovery: one image per exposure (repeated frames averaged,
// noise falls as 1/sqrt(n)), exposures saturated everywhere left out and named in `skipped`.
struct Bracket {
  std::map<double, std::pair<Image, int>> by_exposure;  // Averaged image, frame count.
  std::vector<ResponseFrame> frames;                    // Point into by_exposure.
  std::vector<std::string> skipped;
};

Status LoadBracket(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                   const Group& group, double saturation_dn, Bracket* bracket) {
  bracket->by_exposure.clear();
  bracket->frames.clear();
  bracket->skipped.clear();
  for (const FrameRecord* f : group.frames) {
    Image image;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *f, &image));
    auto it = bracket->by_exposure.find(f->exposure_time_us);
    if (it == bracket->by_exposure.end()) {
      bracket->by_exposure.emplace(f->exposure_time_us, std::make_pair(std::move(image), 1));
    } else {
      for (size_t i = 0; i < image.data().size(); ++i) it->second.first.data()[i] += image.data()[i];
      ++it->second.second;
    }
  }
  for (auto& [t, entry] : bracket->by_exposure) {
    for (float& v : entry.first.data()) v /= static_cast<float>(entry.second);
    std::ostringstream name;
    name << group.name << " @ " << t << " us (" << entry.second << " frame" << (entry.second > 1 ? "s" : "") << ")";
    // An exposure saturated everywhere carries no information (RecoverResponse would refuse
    // it): leave it out, say so, and let the remaining count decide.
    const bool all_saturated = std::all_of(entry.first.data().begin(), entry.first.data().end(),
                                           [&](float z) { return z >= saturation_dn - 0.5; });
    if (all_saturated) {
      bracket->skipped.push_back(name.str());
      continue;
    }
    bracket->frames.push_back({&entry.first, t, camera.bit_depth, name.str()});
  }
  return Status::Ok();
}


}  // namespace

Status CalibrateResponse(const CalibResponseRun& run, std::ostream& log) {
  const std::string& session_dir = run.session_dir;
  std::string out = run.out;
  const std::string &method = run.method, &kind = run.kind, &camera_id = run.camera_id;
  ResponseRecoveryOptions options = run.options;
  const bool allow_incomplete = run.allow_incomplete_capture;
  Status status = Status::Ok();
  if (status.ok()) status = ResolveCalibOutputFile(session_dir, "response.json", {}, &out);
  if (!status.ok()) return status;
  if (method == "debevec") {
    options.method = ResponseMethod::kDebevec;
  } else if (method == "robertson") {
    options.method = ResponseMethod::kRobertson;
  } else {
    return Status::Error("--method " + method + ": expected debevec or robertson");
  }
  Session session;
  status = ReadCaptureForCommand(session_dir, allow_incomplete, &session);
  if (!status.ok()) return status;
  const CameraInfo* camera = nullptr;
  status = FindCamera(session_dir, session, camera_id, &camera);
  if (!status.ok()) return status;
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (camera->bit_depth > 16) {
    return Status::Error(manifest + ": camera '" + camera->id + "': bit_depth " + std::to_string(camera->bit_depth) +
                              ": float frames are already linear; no response to recover");
  }
  std::vector<Group> groups = GroupFrames(session, *camera, kind);
  if (groups.empty()) {
    return Status::Error(manifest + ": frames: no usable non-dark frame" +
                              (kind.empty() ? std::string() : " of kind '" + kind + "'") + " for camera '" +
                              camera->id + "'");
  }
  options.saturation_dn = camera->saturation_dn - camera->black_level_dn;
  // Brackets with the most exposures are the candidates. Where several tie, the one whose
  // values span the most of the DN range wins: a near-uniform scene (a flat or reference
  // bracket) gives one cluster of values per exposure and leaves the curve between them to the
  // smoothness term (docs/models/radiometric_calibration.md, "Known limits").
  size_t most_exposures = 0;
  for (const Group& g : groups) most_exposures = std::max(most_exposures, g.exposures.size());
  std::vector<const Group*> candidates;
  for (const Group& g : groups) {
    if (g.exposures.size() == most_exposures) candidates.push_back(&g);
  }
  std::vector<BracketCandidate> scored;
  Bracket bracket;
  for (const Group* g : candidates) {
    Bracket loaded;
    status = LoadBracket(session_dir, session, *camera, *g, options.saturation_dn, &loaded);
    if (!status.ok()) return status;
    scored.push_back({g->name, static_cast<int>(g->exposures.size()), static_cast<int>(g->frames.size()),
                      BracketDnCoverage(loaded.frames, options.saturation_dn)});
    // Keep only the best so far in memory (ChooseResponseBracket over the prefix).
    if (ChooseResponseBracket(scored) == static_cast<int>(scored.size()) - 1) bracket = std::move(loaded);
  }
  const int chosen = ChooseResponseBracket(scored);
  const Group& group = *candidates[chosen];
  const double coverage = scored[chosen].dn_coverage;
  if (scored.size() > 1) {
    log << "bracket choice (" << most_exposures << " exposures each), share of the DN range covered:";
    for (const BracketCandidate& c : scored) {
      log << " '" << c.name << "' " << static_cast<int>(std::lround(100 * c.dn_coverage)) << " %";
    }
    log << "; using '" << group.name << "'\n";
  }
  for (const std::string& skipped : bracket.skipped) {
    log << "skipping " << skipped << ": every pixel is saturated\n";
  }
  if (coverage < kMinBracketDnCoverage) {
    log << "warning: bracket '" << group.name << "' covers only "
              << static_cast<int>(std::lround(100 * coverage)) << " % of the DN range (below "
              << static_cast<int>(std::lround(100 * kMinBracketDnCoverage))
              << " %): the response is constrained by data only there and by smoothness elsewhere; use a bracket "
                 "of a scene with a wide spread of radiance (--kind)\n";
  }
  const std::vector<ResponseFrame>& frames = bracket.frames;
  options.black_level_dn = camera->black_level_dn;
  CameraResponse response;
  ResponseRecoverySummary summary;
  status = RecoverResponse(frames, options, &response, &summary).WithContext(JoinPath(session_dir, kSessionManifestName) + ": frames of kind '" + group.name + "'");
  if (!status.ok()) return status;
  response.camera_id = camera->id;
  status = CreateParentFolder(out);
  if (status.ok()) {
    status = WriteResponse(out, response, ProvenanceJson({"calib response", session_dir, "", run.options_ini}).dump());
  }
  if (!status.ok()) return status;
  log << "bracket '" << group.name << "': " << frames.size() << " exposures, " << group.frames.size()
            << " frames\n" << summary.BriefReport() << "\nwrote " << out << "\n";
  return Status::Ok();
}

Status CalibrateHdr(const CalibHdrRun& run, std::ostream& log) {
  const std::string& session_dir = run.session_dir;
  std::string out = run.out;
  const std::string &response_path = run.response_path, &weighting = run.weighting, &kind = run.kind,
                    &camera_id = run.camera_id, &exposures = run.exposures;
  HdrMergeOptions options = run.options;
  const double read_noise_dn = run.read_noise_dn;
  const bool allow_incomplete = run.allow_incomplete_capture;
  Status status = Status::Ok();
  if (!status.ok()) return status;
  if (weighting == "inverse-variance") {
    options.weighting = HdrWeighting::kInverseVariance;
  } else if (weighting == "hat") {
    options.weighting = HdrWeighting::kHat;
  } else if (weighting == "debevec") {
    options.weighting = HdrWeighting::kHat;
    options.log_domain = true;
  } else {
    return Status::Error("--weighting " + weighting + ": expected inverse-variance, hat or debevec");
  }
  if (exposures != "reported" && exposures != "measured") {
    return Status::Error("--exposures " + exposures + ": expected reported or measured");
  }
  if (!(read_noise_dn > 0 && read_noise_dn < 1e6)) {
    return Status::Error("--read-noise-dn " + std::to_string(read_noise_dn) + ": must be in (0, 1e6) DN");
  }
  Session session;
  status = ReadCaptureForCommand(session_dir, allow_incomplete, &session);
  if (!status.ok()) return status;
  const CameraInfo* camera = nullptr;
  status = FindCamera(session_dir, session, camera_id, &camera);
  if (!status.ok()) return status;
  CameraResponse response;
  std::string response_file;
  status = LoadCameraResponse(session_dir, response_path, *camera, &response, &response_file);
  const bool have_response = !response_file.empty();
  if (!status.ok()) return status;
  const std::vector<Group> groups = GroupFrames(session, *camera, kind);
  if (groups.empty()) {
    return Status::Error(JoinPath(session_dir, kSessionManifestName) + ": frames: no usable non-dark frame" +
                              (kind.empty() ? std::string() : " of kind '" + kind + "'"));
  }
  const auto darks = OfCamera(session.UsableFrames("dark"), *camera);
  if (out.empty()) out = JoinPath(JoinPath(session_dir, "calib"), "hdr");
  StagedDirectory staged(out, "calib hdr", {{session_dir, {"calib"}}});
  status = staged.Init();
  if (!status.ok()) return status;
  const std::string options_ini = "# thinslab calib hdr\n" + run.options_ini;
  nlohmann::ordered_json summary;
  summary["format"] = "thinslab-hdr-summary";
  summary["format_version"] = "1.0";
  summary["provenance"] = ProvenanceJson({"calib hdr", session_dir, "", options_ini});
  summary["response"] = have_response ? response.method : "linear";
  summary["weighting"] = weighting;
  summary["camera"] = camera->id;
  FrameNoiseModel noise;
  status = ResolveFrameNoise(session_dir, session, *camera, &noise);
  if (!status.ok()) return status;
  summary["noise"] = noise.ToJson();
  ProgressTracker progress(run.progress, "calib hdr: groups merged", static_cast<int64_t>(groups.size()));
  for (const Group& group : groups) {
    if (!progress.Report(&group - groups.data())) return Status::Error("calib hdr: cancelled");
    HdrImage hdr;
    SessionMergeInfo info;
    status = MergeSessionBracket(session_dir, session, *camera, group.frames, darks,
                                 have_response ? &response : nullptr, options, read_noise_dn, noise, &hdr, &info,
                                 exposures == "measured" ? ExposureCheckMode::kUseMeasured : ExposureCheckMode::kCheck);
    if (!status.ok()) return status.WithContext(group.name);
    const ExposureCheck& check = info.exposure_check;
    Image image = StackChannels({&hdr.radiance, &hdr.variance, &hdr.all_saturated}, {"radiance", "variance", "saturated"});
    image.attributes()["camera"] = camera->id;
    image.attributes()["group"] = group.name;
    image.attributes()["response"] = have_response ? response.method : "linear";
    image.attributes()["exposures_us"] = nlohmann::json(info.exposures_us).dump();
    image.numeric_attributes()["dark_frames"] = {static_cast<double>(info.num_darks)};
    status = WriteMapExr(JoinPath(staged.path(), group.name + ".exr"), image, {"radiance", {"saturated"}},
                         {"calib hdr", session_dir, "", options_ini});
    if (!status.ok()) return status;
    summary["groups"].push_back({{"name", group.name},
                                 {"file", group.name + ".exr"},
                                 {"frames", info.num_frames},
                                 {"exposures_us", info.exposures_us},
                                 {"dark_frames", info.num_darks},
                                 {"dark_exposure_mismatches", info.dark_exposure_mismatches},
                                 {"read_noise_dn", info.read_noise_dn},
                                 {"pixels_all_saturated", hdr.pixels_all_saturated},
                                 {"pixels_fallback", hdr.pixels_fallback},
                                 {"exposure_check", ExposureCheckJson(check, info.merged_with_measured_exposures)}});
    log << group.name << ": " << info.num_frames << " frames, " << info.num_exposures << " exposures, "
              << info.num_darks << " darks, " << hdr.pixels_all_saturated << " pixels saturated everywhere"
              << "; exposures checked against the frames: ";
    if (check.measured) {
      char deviation[32];
      std::snprintf(deviation, sizeof(deviation), "%.2f", 100 * check.max_deviation);
      log << "largest deviation " << deviation << " %\n";
    } else if (info.num_exposures < 2) {
      log << "not applicable (one exposure)\n";
    } else {
      log << "not measured (too few well-exposed pixels)\n";
    }
    if (!check.Warning().empty() && !info.merged_with_measured_exposures) {
      std::cerr << "warning: " << group.name << ": " << check.Warning() << " (--exposures measured merges with the "
                << "measured ones)\n";
    }
  }
  progress.Report(static_cast<int64_t>(groups.size()));
  status = WriteFileAtomically(JoinPath(staged.path(), "summary.json"), summary.dump(2) + "\n");
  if (status.ok()) status = WriteFileAtomically(JoinPath(staged.path(), "options.ini"), options_ini);
  if (status.ok()) status = WriteFolderReport(staged.path(), out, "thinslab calib hdr: " + session_dir);
  if (status.ok()) status = staged.Commit();
  if (!status.ok()) return status;
  log << "wrote " << out << "\n";
  return Status::Ok();
}

Status CalibrateFlatField(const CalibFlatRun& run, std::ostream& log) {
  const std::string &session_dir = run.session_dir, &response_path = run.response_path;
  std::string out = run.out;
  const FlatFieldOptions& options = run.options;
  const bool allow_incomplete = run.allow_incomplete_capture;
  Status status = Status::Ok();
  if (status.ok()) status = ResolveCalibOutputFile(session_dir, "flat_field.exr", {DefaultResponsePath(session_dir, response_path)}, &out);
  if (!status.ok()) return status;
  Session session;
  CameraResponse response;
  std::string response_file;
  status = ReadCaptureAndResponse(session_dir, allow_incomplete, response_path, &session, &response, &response_file);
  if (!status.ok()) return status;
  const bool have_response = !response_file.empty();
  Image flat;
  FlatFieldSummary summary;
  status = ComputeSessionFlatField(session_dir, session, have_response ? &response : nullptr, options, &flat, &summary);
  if (!status.ok()) return status;
  flat.attributes()["camera"] = session.rig.cameras[0].id;
  flat.attributes()["frame_kind"] = summary.kind;
  flat.numeric_attributes()["median_dn_per_us"] = {summary.median_dn_per_us};
  flat.numeric_attributes()["smoothing_sigma_px"] = {options.smoothing_sigma_px};
  flat.attributes()["response"] = have_response ? response.method : "linear";
  status = CreateParentFolder(out);
  if (status.ok()) {
    status = WriteMapExr(out, flat, {"flat", {"valid"}},
                         {"calib flat", session_dir, "", "# thinslab calib flat\n" + run.options_ini});
  }
  if (!status.ok()) return status;
  log << summary.BriefReport() << "\nwrote " << out << "\n";
  return Status::Ok();
}

}  // namespace thinslab
