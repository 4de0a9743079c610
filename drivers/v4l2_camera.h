// SPDX-License-Identifier: Apache-2.0
// V4l2Camera: Camera back-end over the Linux V4L2 kernel API (mmap streaming). Every kernel call
// goes through V4l2Io so tests drive the whole state machine with a simulated device
// (drivers/v4l2_camera_test.cc). Never run against a real device: see docs/drivers.md, "V4L2".
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/camera.h"

namespace thinslab {

// The kernel calls the camera makes. Return values and errno follow the syscalls (-1 and errno
// set on failure; Mmap returns MAP_FAILED).
class V4l2Io {
 public:
  virtual ~V4l2Io() = default;
  virtual int Open(const std::string& path, int flags);
  virtual int Ioctl(int fd, unsigned long request, void* arg);  // NOLINT(runtime/int)
  virtual void* Mmap(size_t length, int prot, int flags, int fd, off_t offset);
  virtual int Munmap(void* addr, size_t length);
  virtual int Close(int fd);
  // poll() on one fd for `events`; returns poll's result and stores revents.
  virtual int Poll(int fd, short events, short* revents, int timeout_ms);  // NOLINT(runtime/int)
};

struct V4l2CameraOptions {
  std::string device = "/dev/video0";
  // "GREY", "Y10", "Y12", "Y16" or "" (first of those the device offers, preferring the deepest).
  std::string pixel_format;
  int width_px = 0, height_px = 0;  // 0 = keep the device's current size.
  int buffers = 4;
  double timeout_s = 2;
  std::string camera_id = "cam0";
  // Null: real syscalls. Tests inject a simulated device.
  std::shared_ptr<V4l2Io> io;
};

class V4l2Camera : public Camera {
 public:
  ~V4l2Camera() override;
  const CameraInfo& info() const override { return info_; }
  // Sets V4L2_CID_EXPOSURE_AUTO to manual and V4L2_CID_EXPOSURE_ABSOLUTE (units of 100 us), then
  // reads the applied value back with VIDIOC_G_CTRL.
  Status SetExposure(double requested_us, double* applied_us) override;
  // Dequeues the next frame (waiting up to timeout_s), converts it to DN and re-queues the buffer.
  Status Capture(CapturedFrame* frame) override;
  std::map<std::string, double> statistics() const override;
  // FourCC of the negotiated format, e.g. "Y16 ".
  const std::string& fourcc() const { return fourcc_; }

 private:
  friend Status OpenV4l2Camera(const V4l2CameraOptions&, std::unique_ptr<V4l2Camera>*);
  V4l2Camera() = default;
  Status Xioctl(unsigned long request, void* arg, const char* name);  // NOLINT(runtime/int)
  void Shutdown();

  V4l2CameraOptions options_;
  std::shared_ptr<V4l2Io> io_;
  int fd_ = -1;
  bool streaming_ = false;
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };
  std::vector<Buffer> buffers_;
  CameraInfo info_;
  std::string fourcc_;
  uint32_t pixelformat_ = 0;
  uint32_t bytesperline_ = 0;
  double exposure_us_ = 0;
  double completed_ = 0, errors_ = 0, timeouts_ = 0, dropped_ = 0;
  bool have_sequence_ = false;
  uint32_t last_sequence_ = 0;
};

// Opens `options.device`, checks VIDEO_CAPTURE + STREAMING, negotiates the pixel format and size,
// maps the buffers and starts streaming. Errors name the device: missing/unopenable path, not a
// capture device, no supported monochrome format (lists what the device offers), REQBUFS/mmap
// failures.
Status OpenV4l2Camera(const V4l2CameraOptions& options, std::unique_ptr<V4l2Camera>* out);

// FourCC of a pixel format name ("GREY", "Y10", "Y12", "Y16"); 0 if unknown.
uint32_t V4l2PixelFormatFromName(const std::string& name);
// Four printable characters of a FourCC, e.g. "Y16 ".
std::string V4l2FourccToString(uint32_t fourcc);

}  // namespace thinslab
