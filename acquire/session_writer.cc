// SPDX-License-Identifier: Apache-2.0
#include "acquire/session_writer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "core/file.h"
#include "core/session_io.h"

namespace thinslab {

std::string UtcTimestampNow() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buf;
}

Status SessionWriter::Open(const std::string& session_dir, const Session& header) {
  dir_ = session_dir;
  on_disk_.clear();
  steps_claimed_ = 0;
  if (FileExists(JoinPath(session_dir, kSessionManifestName))) {
    THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &session_).WithContext("resuming session"));
    for (size_t i = 0; i < session_.frames.size(); ++i) {
      if (session_.frames[i].status != FrameStatus::kFailed) on_disk_.push_back(static_cast<int>(i));
    }
    std::sort(on_disk_.begin(), on_disk_.end(),
              [this](int a, int b) { return session_.frames[a].index < session_.frames[b].index; });
    return Status::Ok();
  }
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(session_dir));
  session_ = header;
  session_.frames.clear();
  if (session_.created_utc.empty()) session_.created_utc = UtcTimestampNow();
  return WriteSession(dir_, session_);
}

Status SessionWriter::AddFrame(FrameRecord record, const Image& raw_dn, int* index) {
  const CameraInfo* camera = session_.FindCamera(record.camera_id);
  if (camera == nullptr) {
    return Status::Error("SessionWriter: frame names unknown camera '" + record.camera_id + "'");
  }
  record.index = static_cast<int>(session_.frames.size());
  char name[32];
  std::snprintf(name, sizeof(name), "%04d.png", record.index);
  const std::string rel_dir = "frames/" + record.camera_id + "/" + record.kind;
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(JoinPath(dir_, rel_dir)));
  record.file = rel_dir + "/" + name;
  if (record.timestamp_utc.empty()) record.timestamp_utc = UtcTimestampNow();
  THINSLAB_RETURN_IF_ERROR(WriteRawFrame(JoinPath(dir_, record.file), raw_dn, camera->bit_depth));
  session_.frames.push_back(record);
  if (index != nullptr) *index = record.index;
  THINSLAB_RETURN_IF_ERROR(WriteSession(dir_, session_));
  Notify();
  return Status::Ok();
}

void SessionWriter::SetCameraStatistics(const std::string& camera_id,
                                        const std::map<std::string, double>& statistics) {
  for (CameraInfo& camera : session_.rig.cameras) {
    if (camera.id == camera_id) camera.stream_statistics = statistics;
  }
}

Status SessionWriter::AddFailedFrame(FrameRecord record, const std::string& error) {
  record.index = static_cast<int>(session_.frames.size());
  record.file.clear();
  record.status = FrameStatus::kFailed;
  record.error = error;
  if (record.timestamp_utc.empty()) record.timestamp_utc = UtcTimestampNow();
  session_.frames.push_back(record);
  return WriteSession(dir_, session_);
}

Status SessionWriter::Save() { return WriteSession(dir_, session_); }

const FrameRecord* SessionWriter::FrameOnDisk(int step) const {
  if (step < 0 || step >= static_cast<int>(on_disk_.size())) return nullptr;
  return &session_.frames[on_disk_[step]];
}

namespace {

std::string DescribePlanned(const FrameRecord& f) {
  std::string s = "camera '" + f.camera_id + "', kind '" + f.kind + "', sample_state '" + f.sample_state +
                  "', pattern '" + f.light.projector_pattern + "', laser " + (f.light.laser_on ? "on" : "off");
  if (f.light.dot_px) {
    s += ", dot (" + std::to_string(f.light.dot_px->x()) + ", " + std::to_string(f.light.dot_px->y()) + ")";
  }
  return s + ", exposure " + std::to_string(f.exposure_time_us) + " us";
}

bool SamePlannedFrame(const FrameRecord& planned, const FrameRecord& recorded) {
  if (planned.camera_id != recorded.camera_id || planned.kind != recorded.kind ||
      planned.sample_state != recorded.sample_state ||
      planned.light.projector_pattern != recorded.light.projector_pattern ||
      planned.light.laser_on != recorded.light.laser_on ||
      planned.light.dot_px.has_value() != recorded.light.dot_px.has_value()) {
    return false;
  }
  if (planned.light.dot_px && (*planned.light.dot_px - *recorded.light.dot_px).norm() > 1e-6) return false;
  // The recorded exposure is the one the camera reported for that frame; the same device
  // applies the same value again, so a 0.5 % tolerance only absorbs rounding in the manifest.
  return std::abs(planned.exposure_time_us - recorded.exposure_time_us) <=
         5e-3 * std::max(planned.exposure_time_us, recorded.exposure_time_us);
}

}  // namespace

Status SessionWriter::ClaimStep(const FrameRecord& planned, bool* already_on_disk) {
  *already_on_disk = false;
  if (stop_check_) {
    const std::string reason = stop_check_();
    if (!reason.empty()) return Status::Error(reason);
  }
  const int step = steps_claimed_;
  if (step < static_cast<int>(on_disk_.size())) {
    const FrameRecord& recorded = session_.frames[on_disk_[step]];
    if (!SamePlannedFrame(planned, recorded)) {
      return Status::Error(JoinPath(dir_, kSessionManifestName) + ": cannot resume: planned frame " +
                           std::to_string(step) + " (" + DescribePlanned(planned) + ") differs from frame index " +
                           std::to_string(recorded.index) + " on disk (" + DescribePlanned(recorded) +
                           "); resume with the options the session was started with");
    }
    *already_on_disk = true;
  }
  ++steps_claimed_;
  if (*already_on_disk) Notify();
  return Status::Ok();
}

}  // namespace thinslab
