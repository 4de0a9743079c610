// SPDX-License-Identifier: Apache-2.0
// Test and simulation helper: Aravis's own GigE Vision fake camera (ArvGvFakeCamera) served
// in-process on a loopback address, its image supplied by a callback. A simulated rig plugs in
// here, and AravisCamera then reads its frames through the real GigE Vision stack (GVCP
// control, GVSP stream over UDP) exactly as it would read a real camera.
//
// It lives in drivers/ rather than sim/ because it depends on nothing but Aravis and core:
// the frame source is a plain callback, so the tests join it to sim/ without this library
// linking sim/ (which would invert the sim -> drivers dependency).
//
// The fake binds UDP port 3956 on its address; only one can run per address at a time
// (tests using it share the CTest RESOURCE_LOCK "gige_fake_camera_port_3956").
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct AravisFakeFrameRequest {
  int width_px = 0;
  int height_px = 0;
  double exposure_time_us = 0;  // As the fake camera holds it (whole microseconds).
  double gain = 0;              // The fake's raw gain register.
  std::string pixel_format;     // "Mono8", "Mono16", ...
  uint64_t index = 0;           // 0, 1, 2, ... frames served by this helper.
};

// Fills `raw_dn` (width x height, one channel, DN) for one frame. Called on the fake camera's
// own thread. Values are rounded and clamped to the pixel format's range.
using AravisFakeFrameSource = std::function<Status(const AravisFakeFrameRequest& request, Image* raw_dn)>;

struct AravisFakeCameraOptions {
  // Loopback only in tests: an address or interface name the fake binds to.
  std::string interface_address = "127.0.0.1";
  std::string serial = "TSFAKE01";
  // Fraction of GVSP packets the fake drops (Aravis property gvsp-lost-ratio).
  double gvsp_lost_ratio = 0;
  // Seeds GLib's global random generator, which the fake's packet dropping draws from, so a
  // lossy run drops the same packets each time; 0 leaves it alone.
  uint32_t random_seed = 1;
  // The fake looks for a software trigger once per period (its trigger frequency) and
  // free-runs at this period; 10 ms keeps captures quick (its default is 40 ms).
  int frame_period_us = 10000;
  // The camera-side heartbeat timeout (GigE Vision bootstrap register 0x0938); 0 keeps the
  // fake's default (3000 ms). Aravis sends a heartbeat every second.
  int heartbeat_timeout_ms = 0;

  bool Check(std::string* error) const;
};

class AravisFakeCamera {
 public:
  static Status Start(const AravisFakeCameraOptions& options, AravisFakeFrameSource source,
                      std::unique_ptr<AravisFakeCamera>* fake);
  ~AravisFakeCamera();
  AravisFakeCamera(const AravisFakeCamera&) = delete;
  AravisFakeCamera& operator=(const AravisFakeCamera&) = delete;

  // Address to open with AravisCameraOptions::address.
  const std::string& address() const { return options_.interface_address; }
  void SetLostPacketRatio(double ratio);
  // Clears the camera's control-channel privilege register, as a camera does when its
  // heartbeat times out or it is reset: the controller must take control again.
  void DropControl();
  // Whether the camera still grants a controller its control channel (privilege register
  // non-zero): it clears it when the controller's heartbeat times out.
  bool ControlHeld() const;

  uint64_t frames_served() const;
  // Frames whose source callback failed (they were sent black); the last message.
  uint64_t source_errors() const;
  std::string last_source_error() const;

 private:
  AravisFakeCamera() = default;
  // Aravis fill-pattern callback body (ArvBuffer* passed as void*).
  void Fill(void* buffer, uint32_t exposure_time_us, uint32_t gain, uint32_t pixel_format);

  AravisFakeCameraOptions options_;
  AravisFakeFrameSource source_;
  void* gv_fake_ = nullptr;  // ArvGvFakeCamera*, kept opaque so users need no GLib headers.
  mutable std::mutex mutex_;
  uint64_t frames_served_ = 0;
  uint64_t source_errors_ = 0;
  std::string last_source_error_;
};

}  // namespace thinslab
