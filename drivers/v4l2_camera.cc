// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace thinslab {
namespace {

struct FormatName {
  const char* name;
  uint32_t fourcc;
  int bits;
};
// Deepest first: the order in which an unspecified pixel format is chosen.
constexpr FormatName kFormats[] = {{"Y16", V4L2_PIX_FMT_Y16, 16},
                                   {"Y12", V4L2_PIX_FMT_Y12, 12},
                                   {"Y10", V4L2_PIX_FMT_Y10, 10},
                                   {"GREY", V4L2_PIX_FMT_GREY, 8}};

int BitsOf(uint32_t fourcc) {
  for (const FormatName& f : kFormats) {
    if (f.fourcc == fourcc) return f.bits;
  }
  return 0;
}

std::string ErrnoText(int e) { return std::string(std::strerror(e)); }

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : ", ") + s;
  return out.empty() ? "none" : out;
}

// Monotonic buffer timestamp -> UTC wall clock, by the current offset between the clocks.
std::string TimestampUtc(const timeval& tv, bool monotonic) {
  double wall_s;
  timespec now_real{};
  clock_gettime(CLOCK_REALTIME, &now_real);
  const double real_s = now_real.tv_sec + now_real.tv_nsec * 1e-9;
  const double stamp_s = tv.tv_sec + tv.tv_usec * 1e-6;
  if (monotonic) {
    timespec now_mono{};
    clock_gettime(CLOCK_MONOTONIC, &now_mono);
    wall_s = real_s - (now_mono.tv_sec + now_mono.tv_nsec * 1e-9 - stamp_s);
  } else {
    wall_s = stamp_s > 0 ? stamp_s : real_s;
  }
  const time_t secs = static_cast<time_t>(std::floor(wall_s));
  const int micros = std::clamp(static_cast<int>(std::lround((wall_s - secs) * 1e6)), 0, 999999);
  tm utc{};
  gmtime_r(&secs, &utc);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%04d-%02d-%02dT%02d:%02d:%02d.%06dZ", utc.tm_year + 1900,
                utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, micros);
  return buf;
}

}  // namespace

int V4l2Io::Open(const std::string& path, int flags) { return ::open(path.c_str(), flags); }
int V4l2Io::Ioctl(int fd, unsigned long request, void* arg) {  // NOLINT(runtime/int)
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}
void* V4l2Io::Mmap(size_t length, int prot, int flags, int fd, off_t offset) {
  return ::mmap(nullptr, length, prot, flags, fd, offset);
}
int V4l2Io::Munmap(void* addr, size_t length) { return ::munmap(addr, length); }
int V4l2Io::Close(int fd) { return ::close(fd); }
int V4l2Io::Poll(int fd, short events, short* revents, int timeout_ms) {  // NOLINT
  pollfd p{fd, events, 0};
  const int r = ::poll(&p, 1, timeout_ms);
  *revents = p.revents;
  return r;
}

uint32_t V4l2PixelFormatFromName(const std::string& name) {
  std::string trimmed = name;
  while (!trimmed.empty() && trimmed.back() == ' ') trimmed.pop_back();
  for (const FormatName& f : kFormats) {
    if (trimmed == f.name) return f.fourcc;
  }
  return 0;
}

std::string V4l2FourccToString(uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    s[i] = (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

Status V4l2Camera::Xioctl(unsigned long request, void* arg, const char* name) {  // NOLINT
  if (io_->Ioctl(fd_, request, arg) == -1) {
    const int e = errno;
    return Status::Error("V4L2 camera " + options_.device + ": " + name + " failed: " +
                         ErrnoText(e));
  }
  return Status::Ok();
}

V4l2Camera::~V4l2Camera() { Shutdown(); }

void V4l2Camera::Shutdown() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    io_->Ioctl(fd_, VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  for (const Buffer& b : buffers_) {
    if (b.start != nullptr) io_->Munmap(b.start, b.length);
  }
  if (!buffers_.empty()) {
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    io_->Ioctl(fd_, VIDIOC_REQBUFS, &req);
    buffers_.clear();
  }
  io_->Close(fd_);
  fd_ = -1;
}

Status OpenV4l2Camera(const V4l2CameraOptions& options, std::unique_ptr<V4l2Camera>* out) {
  const std::string dev = "V4L2 camera " + options.device;
  if (options.device.empty()) return Status::Error("V4L2 camera: empty device path");
  if (options.buffers < 1 || options.buffers > 32 || !(options.timeout_s > 0) ||
      options.width_px < 0 || options.height_px < 0) {
    return Status::Error(dev +
                         ": V4l2CameraOptions need 1..32 buffers, timeout_s > 0 and "
                         "non-negative width/height");
  }
  std::unique_ptr<V4l2Camera> cam(new V4l2Camera());
  cam->options_ = options;
  cam->io_ = options.io ? options.io : std::make_shared<V4l2Io>();
  // Non-blocking: DQBUF must never hang; waiting is poll's job, with a timeout.
  cam->fd_ = cam->io_->Open(options.device, O_RDWR | O_NONBLOCK);
  if (cam->fd_ < 0) {
    const int e = errno;
    return Status::Error(dev + ": cannot open: " + ErrnoText(e) +
                         (e == ENOENT ? " (no such device; list devices with v4l2-ctl "
                                        "--list-devices)"
                                      : ""));
  }
  v4l2_capability cap{};
  THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_QUERYCAP, &cap, "VIDIOC_QUERYCAP (not a V4L2 device?)"));
  const uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  const std::string card(reinterpret_cast<const char*>(cap.card),
                         strnlen(reinterpret_cast<const char*>(cap.card), sizeof(cap.card)));
  const std::string bus(reinterpret_cast<const char*>(cap.bus_info),
                        strnlen(reinterpret_cast<const char*>(cap.bus_info), sizeof(cap.bus_info)));
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0 || (caps & V4L2_CAP_STREAMING) == 0) {
    return Status::Error(dev + " (" + card +
                         ") is not a single-planar video capture device with streaming I/O");
  }

  // Formats the device offers.
  std::vector<uint32_t> offered;
  for (uint32_t i = 0; i < 256; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (cam->io_->Ioctl(cam->fd_, VIDIOC_ENUM_FMT, &desc) == -1) break;
    offered.push_back(desc.pixelformat);
  }
  std::vector<std::string> offered_names;
  for (uint32_t f : offered) offered_names.push_back(V4l2FourccToString(f));
  auto is_offered = [&](uint32_t f) {
    return std::find(offered.begin(), offered.end(), f) != offered.end();
  };
  uint32_t fourcc = 0;
  if (!options.pixel_format.empty()) {
    fourcc = V4l2PixelFormatFromName(options.pixel_format);
    if (fourcc == 0) {
      return Status::Error(dev + ": unsupported pixel format \"" + options.pixel_format +
                           "\" (thinslab reads GREY, Y10, Y12, Y16; the device offers " +
                           Join(offered_names) + ")");
    }
    if (!is_offered(fourcc)) {
      return Status::Error(dev + ": does not offer pixel format " + options.pixel_format +
                           " (it offers " + Join(offered_names) + ")");
    }
  } else {
    for (const FormatName& f : kFormats) {
      if (is_offered(f.fourcc)) {
        fourcc = f.fourcc;
        break;
      }
    }
    if (fourcc == 0) {
      return Status::Error(dev + ": offers no monochrome format thinslab reads (GREY, Y10, Y12, "
                                 "Y16); it offers " +
                           Join(offered_names));
    }
  }

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_G_FMT, &fmt, "VIDIOC_G_FMT"));
  if (options.width_px > 0) fmt.fmt.pix.width = options.width_px;
  if (options.height_px > 0) fmt.fmt.pix.height = options.height_px;
  fmt.fmt.pix.pixelformat = fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  fmt.fmt.pix.bytesperline = 0;  // Let the driver choose its stride.
  THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_S_FMT, &fmt, "VIDIOC_S_FMT"));
  // S_FMT may adjust anything; accept only what was asked for.
  if (fmt.fmt.pix.pixelformat != fourcc) {
    return Status::Error(dev + ": asked for pixel format " + V4l2FourccToString(fourcc) +
                         ", the driver set " + V4l2FourccToString(fmt.fmt.pix.pixelformat));
  }
  if ((options.width_px > 0 && fmt.fmt.pix.width != uint32_t(options.width_px)) ||
      (options.height_px > 0 && fmt.fmt.pix.height != uint32_t(options.height_px))) {
    return Status::Error(dev + ": asked for " + std::to_string(options.width_px) + "x" +
                         std::to_string(options.height_px) + ", the driver set " +
                         std::to_string(fmt.fmt.pix.width) + "x" +
                         std::to_string(fmt.fmt.pix.height));
  }
  if (fmt.fmt.pix.width == 0 || fmt.fmt.pix.height == 0) {
    return Status::Error(dev + ": driver reports a zero frame size");
  }
  const int bytes_per_pixel = fourcc == V4L2_PIX_FMT_GREY ? 1 : 2;
  cam->pixelformat_ = fourcc;
  cam->fourcc_ = V4l2FourccToString(fourcc);
  cam->bytesperline_ = std::max<uint32_t>(fmt.fmt.pix.bytesperline,
                                          fmt.fmt.pix.width * bytes_per_pixel);

  CameraInfo& info = cam->info_;
  info.id = options.camera_id;
  info.model = "v4l2";
  info.serial = card + (bus.empty() ? "" : " @ " + bus);
  info.width_px = static_cast<int>(fmt.fmt.pix.width);
  info.height_px = static_cast<int>(fmt.fmt.pix.height);
  info.bit_depth = BitsOf(fourcc);
  info.saturation_dn = std::pow(2.0, info.bit_depth) - 1;

  v4l2_requestbuffers req{};
  req.count = options.buffers;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_REQBUFS, &req, "VIDIOC_REQBUFS (mmap streaming)"));
  if (req.count < 1) return Status::Error(dev + ": driver granted no buffers");
  cam->buffers_.resize(req.count);
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_QUERYBUF, &buf, "VIDIOC_QUERYBUF"));
    if (buf.length < size_t(cam->bytesperline_) * info.height_px) {
      return Status::Error(dev + ": buffer " + std::to_string(i) + " holds " +
                           std::to_string(buf.length) + " bytes, a frame needs " +
                           std::to_string(size_t(cam->bytesperline_) * info.height_px));
    }
    void* start = cam->io_->Mmap(buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, cam->fd_,
                                 static_cast<off_t>(buf.m.offset));
    if (start == MAP_FAILED) {
      const int e = errno;
      return Status::Error(dev + ": mmap of buffer " + std::to_string(i) +
                           " failed: " + ErrnoText(e));
    }
    cam->buffers_[i] = {start, buf.length};
  }
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_QBUF, &buf, "VIDIOC_QBUF"));
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  THINSLAB_RETURN_IF_ERROR(cam->Xioctl(VIDIOC_STREAMON, &type, "VIDIOC_STREAMON"));
  cam->streaming_ = true;
  // The exposure in force before any SetExposure, if the device has the control.
  v4l2_control ctrl{};
  ctrl.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (cam->io_->Ioctl(cam->fd_, VIDIOC_G_CTRL, &ctrl) == 0) cam->exposure_us_ = ctrl.value * 100.0;
  *out = std::move(cam);
  return Status::Ok();
}

Status V4l2Camera::SetExposure(double requested_us, double* applied_us) {
  const std::string dev = "V4L2 camera " + options_.device;
  if (!(requested_us > 0) || !std::isfinite(requested_us)) {
    return Status::Error(dev + ": exposure must be positive and finite");
  }
  v4l2_queryctrl q{};
  q.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (io_->Ioctl(fd_, VIDIOC_QUERYCTRL, &q) == -1 || (q.flags & V4L2_CTRL_FLAG_DISABLED) != 0) {
    return Status::Error(dev + ": has no V4L2_CID_EXPOSURE_ABSOLUTE control");
  }
  // Manual mode first: many UVC cameras ignore (or reject with EBUSY) the absolute exposure in
  // aperture-priority mode. A device without the auto control is already manual.
  v4l2_control mode{};
  mode.id = V4L2_CID_EXPOSURE_AUTO;
  mode.value = V4L2_EXPOSURE_MANUAL;
  if (io_->Ioctl(fd_, VIDIOC_S_CTRL, &mode) == -1 && errno != EINVAL) {
    const int e = errno;
    return Status::Error(dev + ": setting V4L2_CID_EXPOSURE_AUTO to manual failed: " +
                         ErrnoText(e));
  }
  // V4L2_CID_EXPOSURE_ABSOLUTE is in units of 100 us.
  const double units = requested_us / 100.0;
  if (units < q.minimum - 0.5 * std::max(q.step, 1) ||
      units > q.maximum + 0.5 * std::max(q.step, 1)) {
    return Status::Error(dev + ": exposure " + std::to_string(requested_us) +
                         " us is outside the device range [" + std::to_string(q.minimum * 100) +
                         ", " + std::to_string(q.maximum * 100.0) + "] us");
  }
  const int step = std::max(q.step, 1);
  int value = q.minimum + step * static_cast<int>(std::lround((units - q.minimum) / step));
  value = std::clamp(value, q.minimum, q.maximum);
  v4l2_control set{};
  set.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  set.value = value;
  THINSLAB_RETURN_IF_ERROR(Xioctl(VIDIOC_S_CTRL, &set, "VIDIOC_S_CTRL exposure"));
  v4l2_control get{};
  get.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  THINSLAB_RETURN_IF_ERROR(Xioctl(VIDIOC_G_CTRL, &get, "VIDIOC_G_CTRL exposure"));
  exposure_us_ = get.value * 100.0;
  if (applied_us != nullptr) *applied_us = exposure_us_;
  return Status::Ok();
}

Status V4l2Camera::Capture(CapturedFrame* frame) {
  const std::string dev = "V4L2 camera " + options_.device;
  if (!streaming_) return Status::Error(dev + ": not streaming");
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::microseconds(static_cast<int64_t>(options_.timeout_s * 1e6));
  v4l2_buffer buf{};
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) {
      timeouts_ += 1;
      return Status::Error(dev + ": no frame within " + std::to_string(options_.timeout_s) +
                           " s (timeout; is the camera triggered / still connected?)");
    }
    short revents = 0;
    const int r = io_->Poll(fd_, POLLIN, &revents, static_cast<int>(left));
    if (r == -1) {
      if (errno == EINTR) continue;
      const int e = errno;
      return Status::Error(dev + ": poll failed: " + ErrnoText(e));
    }
    if (r == 0) continue;  // The deadline check above reports the timeout.
    if ((revents & (POLLERR | POLLHUP | POLLNVAL)) != 0 && (revents & POLLIN) == 0) {
      return Status::Error(dev + ": device error while waiting for a frame (disconnected?)");
    }
    buf = v4l2_buffer{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (io_->Ioctl(fd_, VIDIOC_DQBUF, &buf) == -1) {
      if (errno == EAGAIN) continue;
      const int e = errno;
      return Status::Error(dev + ": VIDIOC_DQBUF failed: " + ErrnoText(e));
    }
    if (buf.index >= buffers_.size()) {
      return Status::Error(dev + ": driver returned buffer index " + std::to_string(buf.index) +
                           " of " + std::to_string(buffers_.size()));
    }
    const size_t needed = size_t(bytesperline_) * info_.height_px;
    if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0 || (buf.bytesused != 0 && buf.bytesused < needed)) {
      // A corrupt or short frame: give the buffer back and wait for the next one.
      errors_ += 1;
      THINSLAB_RETURN_IF_ERROR(Xioctl(VIDIOC_QBUF, &buf, "VIDIOC_QBUF"));
      continue;
    }
    break;
  }
  const uint8_t* src = static_cast<const uint8_t*>(buffers_[buf.index].start);
  Image raw(info_.width_px, info_.height_px, 0.0f);
  for (int y = 0; y < info_.height_px; ++y) {
    const uint8_t* row = src + size_t(y) * bytesperline_;
    for (int x = 0; x < info_.width_px; ++x) {
      // Y10/Y12/Y16 are little-endian 16-bit words, the value in the low bits.
      raw.at(x, y) = pixelformat_ == V4L2_PIX_FMT_GREY
                         ? float(row[x])
                         : float(uint16_t(row[2 * x] | (uint16_t(row[2 * x + 1]) << 8)));
    }
  }
  if (have_sequence_ && buf.sequence > last_sequence_ + 1) {
    dropped_ += buf.sequence - last_sequence_ - 1;
  }
  have_sequence_ = true;
  last_sequence_ = buf.sequence;
  completed_ += 1;
  const bool monotonic =
      (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
  frame->raw_dn = std::move(raw);
  frame->exposure_time_us = exposure_us_;
  frame->frame_id = buf.sequence;
  // The driver's buffer timestamp (CLOCK_MONOTONIC for most drivers, see the flags), as is.
  if (buf.timestamp.tv_sec > 0 || buf.timestamp.tv_usec > 0) {
    frame->device_timestamp_ns =
        uint64_t(buf.timestamp.tv_sec) * 1000000000ull + uint64_t(buf.timestamp.tv_usec) * 1000ull;
  }
  frame->timestamp_utc = TimestampUtc(buf.timestamp, monotonic);
  return Xioctl(VIDIOC_QBUF, &buf, "VIDIOC_QBUF");
}

std::map<std::string, double> V4l2Camera::statistics() const {
  return {{"completed_buffers", completed_},
          {"failed_buffers", errors_},
          {"timeouts", timeouts_},
          {"dropped_frames", dropped_}};
}

}  // namespace thinslab
