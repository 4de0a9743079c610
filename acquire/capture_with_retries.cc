// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/capture_with_retries.h"

namespace thinslab {

FrameRecord CapturedRecord(const FrameRecord& templ, const CapturedFrame& frame, FrameStatus status) {
  FrameRecord record = templ;
  record.exposure_time_us = frame.exposure_time_us;
  record.gain_db = frame.gain_db;
  record.timestamp_utc = frame.timestamp_utc;
  record.camera_frame_id = frame.frame_id;
  record.camera_timestamp_ns = frame.device_timestamp_ns;
  record.status = status;
  return record;
}

Status CaptureWithRetries(Camera* camera, const FrameRecord& templ, int max_retries, SessionWriter* writer) {
  bool already_on_disk = false;
  THINSLAB_RETURN_IF_ERROR(writer->ClaimStep(templ, &already_on_disk));
  if (already_on_disk) return Status::Ok();  // Resumed session: this frame was captured before.
  std::string last_error;
  for (int attempt = 0; attempt <= max_retries; ++attempt) {
    CapturedFrame frame;
    const Status status = camera->Capture(&frame);
    // Transport statistics ride along with every manifest write (docs/format.md 2.3.1).
    writer->SetCameraStatistics(camera->info().id, camera->statistics());
    if (!status.ok()) {
      last_error = status.message();
      THINSLAB_RETURN_IF_ERROR(writer->AddFailedFrame(templ, last_error));
      continue;
    }
    return writer->AddFrame(CapturedRecord(templ, frame, attempt == 0 ? FrameStatus::kOk : FrameStatus::kRetried),
                            frame.raw_dn);
  }
  return Status::Error("camera '" + camera->info().id + "': capture failed " + std::to_string(max_retries + 1) +
                       " times: " + last_error);
}

}  // namespace thinslab
