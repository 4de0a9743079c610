// SPDX-License-Identifier: Apache-2.0
// GigE Vision camera through Aravis 0.8 (docs/drivers.md, "Aravis"). One frame per Capture():
// the camera runs in software-trigger mode, Capture() fires TriggerSoftware and waits for the
// buffer, so every frame is taken after the session script has set the light state. Opening
// by IP address talks to that address only (unicast GVCP, no discovery broadcast); opening by
// device id uses Aravis discovery. Errors name the device (address and serial).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/drivers/camera.h"

// Aravis's own declaration (arvtypes.h), repeated so that this header needs no Aravis include.
typedef struct _ArvBuffer ArvBuffer;

namespace thinslab {

struct AravisCameraOptions {
  // IPv4 address ("192.168.1.20", "127.0.0.1") or an Aravis device id ("Basler-21234567").
  std::string address;
  // GenICam PixelFormat; thinslab reads Mono8, Mono10, Mono12, Mono14 and Mono16 (unpacked,
  // little-endian). Others, or one the camera does not offer, are refused by name.
  std::string pixel_format = "Mono16";
  // Analog gain in the camera's Gain feature units (dB on SFNC cameras; raw on GainRaw ones).
  double gain_db = 0;
  // Buffers queued on the stream; > 1 so a late frame never blocks the next one.
  int stream_buffers = 8;
  // Longest wait for a frame after its software trigger (exposure + transfer + margin), s.
  double frame_timeout_s = 2;
  // 1: ask the camera to resend lost GVSP packets (Aravis packet-resend ALWAYS); 0: never.
  int packet_resend = 1;
  // GVSP packet size in bytes; 0 = negotiate (arv_camera_gv_auto_packet_size). The value in
  // use is read back and reported as statistics()["packet_size_bytes"].
  int packet_size = 0;
  // Aravis stream timeouts, microseconds: wait for a missing packet before asking for a
  // resend, and keep an incomplete frame before giving up on it.
  int packet_timeout_us = 20000;
  int frame_retention_us = 100000;
  // Unicast GVCP probe of an IP address before opening it, so a wrong address fails in this
  // time instead of Aravis's ~2.5 s of retries.
  double connect_timeout_s = 1;
  // Region (0 = leave the camera's current width/height; offsets are set to 0 otherwise).
  int width_px = 0;
  int height_px = 0;
  // Manifest description. bit_depth 0 = from the pixel format (Mono12 -> 12); a 12-bit sensor
  // delivering Mono16 with its values in the low bits should say 12 here.
  std::string camera_id = "cam0";
  int bit_depth = 0;
  double black_level_dn = 0;
  // 0 = 2^bit_depth - 1.
  double saturation_dn = 0;
  // Nominal intrinsics until calib/ measures them; 0 = focal length = image width, principal
  // point at the image centre (the manifest requires positive values).
  double nominal_focal_length_px = 0;

  bool Check(std::string* error) const;
};

// Not thread-safe: one thread drives a camera (Aravis runs its own stream and heartbeat
// threads underneath).
class AravisCamera : public Camera {
 public:
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override;
  // Drops stale buffers, fires the software trigger and waits frame_timeout_s. After a timeout
  // (e.g. control lost during an idle gap) it re-arms once: retakes control if the camera
  // dropped it, restarts acquisition and triggers again. An incomplete frame (missing packets)
  // is an error naming the frame id and the packet counters; the caller retries.
  Status Capture(CapturedFrame* frame) override;
  // Aravis stream counters (arv_stream_get_n_infos: completed_buffers, failed_buffers,
  // missing_packets, resend_requests, resent_packets, ...) plus this driver's own:
  // timeouts, incomplete_frames, rearms, control_regained, stale_buffers_dropped,
  // packet_size_bytes, exposure_time_us.
  std::map<std::string, double> statistics() const override;

  // "127.0.0.1 (Aravis Fake GV01)": used in every message.
  const std::string& device_name() const { return device_name_; }
  int packet_size_bytes() const { return packet_size_bytes_; }
  // The pixel formats the camera offers, as GenICam names.
  const std::vector<std::string>& offered_pixel_formats() const { return offered_formats_; }

 private:
  friend Status OpenAravisCamera(const AravisCameraOptions& options,
                                 std::unique_ptr<AravisCamera>* camera);
  struct Handles;
  AravisCamera(const AravisCameraOptions& options, std::unique_ptr<Handles> handles);

  Status Configure();
  Status StartStream();
  Status Rearm(const std::string& reason);
  int DrainStaleBuffers();
  // GigE Vision 1.x block ids are 16 bits and skip 0: unwrapped into a counter.
  uint64_t UnwrapFrameId(uint64_t raw_id);
  // The next buffer within `timeout_us`, skipping (requeueing, counted as stale) frames of
  // triggers that earlier captures gave up on: ids in (last_taken_frame_id_, last_taken_frame_id_
  // + `abandoned`]. Such a frame may still be in flight when DrainStaleBuffers runs.
  ArvBuffer* PopFrameOfThisTrigger(uint64_t timeout_us, int abandoned);

  AravisCameraOptions options_;
  std::unique_ptr<Handles> h_;
  CameraInfo info_;
  std::string device_name_;
  std::vector<std::string> offered_formats_;
  int bytes_per_pixel_ = 2;
  int packet_size_bytes_ = 0;
  double exposure_us_ = 0;
  double gain_ = 0;  // Read back after setting (cameras round it); stamped on every frame.
  uint64_t last_raw_frame_id_ = 0;
  uint64_t frame_id_offset_ = 0;
  bool have_frame_id_ = false;
  uint64_t last_taken_frame_id_ = 0;  // Unwrapped id of the last frame a capture took.
  int abandoned_triggers_ = 0;        // Triggers of earlier captures whose frames may still arrive.
  std::map<std::string, double> counters_;
};

// Opens the camera, applies the options (region, pixel format, gain, packet size, software
// trigger) and starts acquisition with `stream_buffers` queued buffers.
Status OpenAravisCamera(const AravisCameraOptions& options, std::unique_ptr<AravisCamera>* camera);

}  // namespace thinslab
