// SPDX-License-Identifier: Apache-2.0
// Camera interface. Real back-ends (Aravis, V4L2) and sim/SimCamera implement it; acquire/
// speaks only this interface, so the same session code runs at the rig and in CI.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct CapturedFrame {
  Image raw_dn;                   // Single channel, raw digital numbers (black level included).
  double exposure_time_us = 0;    // Exposure the device reports having applied.
  double gain_db = 0;             // Analogue gain the device reports applying (0 if it has none).
  std::string timestamp_utc;      // ISO 8601, host clock.
  // What the device stamped on the frame, if it does (FrameRecord::camera_frame_id and
  // camera_timestamp_ns in the manifest): its frame counter, and its timestamp in ns on its own
  // clock (not UTC).
  std::optional<uint64_t> frame_id;
  std::optional<uint64_t> device_timestamp_ns;
};

class Camera {
 public:
  virtual ~Camera() = default;
  // Geometry, bit depth and response as recorded in the manifest.
  virtual const CameraInfo& info() const = 0;
  // Cameras round exposures: `applied_us` receives the value read back from the device.
  virtual Status SetExposure(double requested_us, double* applied_us) = 0;
  virtual Status Capture(CapturedFrame* frame) = 0;
  // Cumulative transport statistics since Open (e.g. "completed_buffers", "failed_buffers",
  // "missing_packets", "resent_packets", "timeouts"), recorded in the capture manifest.
  virtual std::map<std::string, double> statistics() const { return {}; }
};

}  // namespace thinslab
