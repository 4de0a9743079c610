// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/session_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <regex>
#include <set>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/session_recovery.h"

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

bool SessionWriterOptions::Check(std::string* error) const {
  if (manifest_min_new_frames < 1) {
    *error = "SessionWriterOptions::manifest_min_new_frames = " + std::to_string(manifest_min_new_frames) +
             ". Violated constraint: >= 1";
  } else if (!(manifest_growth_fraction >= 0) || !std::isfinite(manifest_growth_fraction)) {
    *error = "SessionWriterOptions::manifest_growth_fraction = " + std::to_string(manifest_growth_fraction) +
             ". Violated constraint: finite and >= 0";
  } else if (!(manifest_max_age_s > 0)) {
    *error = "SessionWriterOptions::manifest_max_age_s = " + std::to_string(manifest_max_age_s) +
             ". Violated constraint: > 0";
  } else {
    return true;
  }
  return false;
}

namespace {

namespace fs = std::filesystem;

Status WriteAll(int fd, const std::string& text, const std::string& path) {
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::Error(path + ": write failed: " + std::strerror(errno));
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) return Status::Error(path + ": fsync failed: " + std::strerror(errno));
  return Status::Ok();
}

// A kill can leave the journal's last line incomplete (no newline): it never became a record.
// Cut it off, so that the next line starts on a line of its own.
Status DropIncompleteLastLine(const std::string& path) {
  std::string bytes;
  if (!FileExists(path)) return Status::Ok();
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &bytes));
  if (bytes.empty() || bytes.back() == '\n') return Status::Ok();
  const size_t keep = bytes.rfind('\n') == std::string::npos ? 0 : bytes.rfind('\n') + 1;
  if (::truncate(path.c_str(), static_cast<off_t>(keep)) != 0) {
    return Status::Error(path + ": cannot drop the incomplete last line: " + std::strerror(errno));
  }
  return Status::Ok();
}

}  // namespace

SessionWriter::~SessionWriter() {
  if (journal_fd_ >= 0) ::close(journal_fd_);
}

Status SessionWriter::Open(const std::string& session_dir, const Session& header, const SessionWriterOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  dir_ = session_dir;
  options_ = options;
  on_disk_.clear();
  steps_claimed_ = 0;
  if (journal_fd_ >= 0) ::close(journal_fd_);
  journal_fd_ = -1;
  const std::string journal = JoinPath(session_dir, kSessionJournalName);
  const bool resume = FileExists(JoinPath(session_dir, kSessionManifestName));
  if (resume) {
    if (options_.journal) {
      THINSLAB_RETURN_IF_ERROR(DropIncompleteLastLine(journal));
      THINSLAB_RETURN_IF_ERROR(ReadSessionWithJournal(session_dir, &session_).WithContext("resuming session"));
    } else {
      THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &session_).WithContext("resuming session"));
    }
    for (size_t i = 0; i < session_.frames.size(); ++i) {
      if (session_.frames[i].status != FrameStatus::kFailed) on_disk_.push_back(static_cast<int>(i));
    }
    std::sort(on_disk_.begin(), on_disk_.end(),
              [this](int a, int b) { return session_.frames[a].index < session_.frames[b].index; });
    THINSLAB_RETURN_IF_ERROR(RemoveUnrecordedFrameFiles());
  } else {
    THINSLAB_RETURN_IF_ERROR(CreateDirectories(session_dir));
    session_ = header;
    session_.frames.clear();
    if (session_.created_utc.empty()) session_.created_utc = UtcTimestampNow();
  }
  if (options_.journal) {
    journal_fd_ = ::open(journal.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (journal_fd_ < 0) return Status::Error(journal + ": cannot open for appending: " + std::strerror(errno));
  }
  if (resume) {
    // Until the next write, the manifest holds the frames it held when opened.
    frames_in_manifest_ = static_cast<int>(session_.frames.size());
    manifest_written_at_ = std::chrono::steady_clock::now();
    return Status::Ok();
  }
  return Save();
}

// Frame files named as AddFrame names them, with an index no record has: the frame was
// written and the process killed before its record became durable. A later capture would
// overwrite it, unless that index goes to a failed attempt; remove it now.
Status SessionWriter::RemoveUnrecordedFrameFiles() const {
  static const std::regex frame_name(R"([0-9]+\.png)");
  const fs::path frames_dir = fs::path(dir_) / "frames";
  std::error_code ec;
  if (!fs::is_directory(frames_dir, ec)) return Status::Ok();
  std::set<std::string> recorded;
  for (const FrameRecord& f : session_.frames) {
    if (!f.file.empty()) recorded.insert(fs::path(f.file).lexically_normal().string());
  }
  std::vector<fs::path> unrecorded;
  for (auto it = fs::recursive_directory_iterator(frames_dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!it->is_regular_file(ec) || !std::regex_match(name, frame_name)) continue;
    if (std::stol(name) < static_cast<long>(session_.frames.size())) continue;
    const std::string rel = it->path().lexically_relative(dir_).lexically_normal().string();
    if (recorded.count(rel) == 0) unrecorded.push_back(it->path());
  }
  for (const fs::path& p : unrecorded) {
    if (!fs::remove(p, ec) && ec) return Status::Error(p.string() + ": cannot remove unrecorded frame: " + ec.message());
  }
  return Status::Ok();
}

Status SessionWriter::AppendJournalLine(const std::string& text) {
  if (journal_fd_ < 0) return Status::Ok();
  return WriteAll(journal_fd_, UtcTimestampNow() + " " + text + "\n", JoinPath(dir_, kSessionJournalName));
}

bool SessionWriter::ManifestIsDue() const {
  const int fresh = unsaved_frames();
  if (fresh <= 0) return false;
  const double geometric = options_.manifest_growth_fraction * frames_in_manifest_;
  if (fresh >= options_.manifest_min_new_frames && fresh >= geometric) return true;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - manifest_written_at_).count() >=
         options_.manifest_max_age_s;
}

Status SessionWriter::Record() {
  const FrameRecord& record = session_.frames.back();
  if (journal_fd_ >= 0) {
    std::string json;
    THINSLAB_RETURN_IF_ERROR(FrameRecordToJson(record, &json));
    THINSLAB_RETURN_IF_ERROR(AppendJournalLine(JournalFrameText(record, session_.acquisition, json)));
  }
  if (ManifestIsDue()) THINSLAB_RETURN_IF_ERROR(Save());
  return Status::Ok();
}

Status SessionWriter::AddFrame(FrameRecord record, const Image& raw_dn, int* index) {
  const CameraInfo* camera = session_.FindCamera(record.camera_id);
  if (camera == nullptr) {
    return Status::Error("SessionWriter: frame names unknown camera '" + record.camera_id + "'");
  }
  record.index = static_cast<int>(session_.frames.size());
  char name[32];
  const bool float_frames = camera->bit_depth == 32;  // Linear or float frames: EXR, channel Y.
  std::snprintf(name, sizeof(name), float_frames ? "%04d.exr" : "%04d.png", record.index);
  const std::string rel_dir = "frames/" + record.camera_id + "/" + record.kind;
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(JoinPath(dir_, rel_dir)));
  record.file = rel_dir + "/" + name;
  if (record.timestamp_utc.empty()) record.timestamp_utc = UtcTimestampNow();
  if (float_frames) {
    THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(dir_, record.file), raw_dn));
  } else {
    THINSLAB_RETURN_IF_ERROR(WriteRawFrame(JoinPath(dir_, record.file), raw_dn, camera->bit_depth));
  }
  session_.frames.push_back(record);
  if (index != nullptr) *index = record.index;
  THINSLAB_RETURN_IF_ERROR(Record());
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
  return Record();
}

Status SessionWriter::Save() {
  THINSLAB_RETURN_IF_ERROR(WriteSession(dir_, session_));
  frames_in_manifest_ = static_cast<int>(session_.frames.size());
  manifest_written_at_ = std::chrono::steady_clock::now();
  return Status::Ok();
}

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
