// SPDX-License-Identifier: Apache-2.0
#include "acquire/session_writer.h"

#include <chrono>
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
  if (FileExists(JoinPath(session_dir, kSessionManifestName))) {
    return ReadSession(session_dir, &session_).WithContext("resuming session");
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
  return WriteSession(dir_, session_);
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

}  // namespace thinslab
