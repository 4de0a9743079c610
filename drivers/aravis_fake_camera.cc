// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/aravis_fake_camera.h"

#include <arv.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <utility>

namespace thinslab {
namespace {

// GigE Vision bootstrap registers (GigE Vision 2.0, table 28); Aravis keeps its names for
// them private.
constexpr guint32 kHeartbeatTimeoutRegister = 0x0938;
constexpr guint32 kControlChannelPrivilegeRegister = 0x0a00;

ArvGvFakeCamera* Gv(void* p) { return static_cast<ArvGvFakeCamera*>(p); }

std::string PixelFormatName(ArvPixelFormat format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_8: return "Mono8";
    case ARV_PIXEL_FORMAT_MONO_10: return "Mono10";
    case ARV_PIXEL_FORMAT_MONO_12: return "Mono12";
    case ARV_PIXEL_FORMAT_MONO_14: return "Mono14";
    case ARV_PIXEL_FORMAT_MONO_16: return "Mono16";
    default: {
      std::ostringstream ss;
      ss << "0x" << std::hex << static_cast<unsigned>(format);
      return ss.str();
    }
  }
}

}  // namespace

bool AravisFakeCameraOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (interface_address.empty()) {
    msg << "AravisFakeCameraOptions::interface_address is empty. Violated constraint: e.g. \"127.0.0.1\"";
  } else if (serial.empty()) {
    msg << "AravisFakeCameraOptions::serial is empty. Violated constraint: non-empty";
  } else if (!(gvsp_lost_ratio >= 0 && gvsp_lost_ratio < 1)) {
    msg << "AravisFakeCameraOptions::gvsp_lost_ratio = " << gvsp_lost_ratio << ". Violated constraint: [0, 1)";
  } else if (frame_period_us < 1000 || frame_period_us > 10000000) {
    msg << "AravisFakeCameraOptions::frame_period_us = " << frame_period_us << ". Violated constraint: 1000..1e7";
  } else if (heartbeat_timeout_ms < 0) {
    msg << "AravisFakeCameraOptions::heartbeat_timeout_ms = " << heartbeat_timeout_ms
        << ". Violated constraint: >= 0 (0 = the fake's default)";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status AravisFakeCamera::Start(const AravisFakeCameraOptions& options, AravisFakeFrameSource source,
                               std::unique_ptr<AravisFakeCamera>* fake) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (!source) return Status::Error("AravisFakeCamera: no frame source given");
  std::unique_ptr<AravisFakeCamera> self(new AravisFakeCamera());
  self->options_ = options;
  self->source_ = std::move(source);
  // NULL GenICam file: the fake's description is built into libaravis (a resource).
  ArvGvFakeCamera* gv =
      arv_gv_fake_camera_new_full(options.interface_address.c_str(), options.serial.c_str(), nullptr);
  if (gv == nullptr) {
    return Status::Error("aravis fake camera on " + options.interface_address + ": cannot create it");
  }
  self->gv_fake_ = gv;
  if (!arv_gv_fake_camera_is_running(gv)) {
    return Status::Error("aravis fake camera on " + options.interface_address +
                         ": did not start (no such interface, or UDP port 3956 there is taken by another "
                         "fake camera or arv-fake-gv-camera)");
  }
  ArvFakeCamera* camera = arv_gv_fake_camera_get_fake_camera(gv);
  if (options.random_seed != 0) g_random_set_seed(options.random_seed);
  g_object_set(gv, "gvsp-lost-ratio", options.gvsp_lost_ratio, nullptr);
  arv_fake_camera_write_register(camera, ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US,
                                 static_cast<guint32>(options.frame_period_us));
  // In trigger mode the fake looks for a software trigger once per 1 / trigger_frequency.
  arv_fake_camera_set_trigger_frequency(camera, 1e6 / options.frame_period_us);
  if (options.heartbeat_timeout_ms > 0) {
    arv_fake_camera_write_register(camera, kHeartbeatTimeoutRegister, static_cast<guint32>(options.heartbeat_timeout_ms));
  }
  // Captureless, so it converts to Aravis's C callback type; it may use the private members.
  auto fill = [](ArvBuffer* buffer, void* data, guint32 exposure_time_us, guint32 gain, ArvPixelFormat pixel_format) {
    static_cast<AravisFakeCamera*>(data)->Fill(buffer, exposure_time_us, gain, pixel_format);
  };
  arv_fake_camera_set_fill_pattern(camera, fill, self.get());
  *fake = std::move(self);
  return Status::Ok();
}

AravisFakeCamera::~AravisFakeCamera() {
  if (gv_fake_ != nullptr) {
    // Stops the fake's thread before this object (the fill callback's data) goes away.
    g_object_unref(Gv(gv_fake_));
  }
}

void AravisFakeCamera::Fill(void* buffer_ptr, uint32_t exposure_time_us, uint32_t gain,
                            uint32_t pixel_format_value) {
  ArvBuffer* buffer = static_cast<ArvBuffer*>(buffer_ptr);
  const ArvPixelFormat pixel_format = static_cast<ArvPixelFormat>(pixel_format_value);
  AravisFakeFrameRequest request;
  request.width_px = arv_buffer_get_image_width(buffer);
  request.height_px = arv_buffer_get_image_height(buffer);
  request.exposure_time_us = exposure_time_us;
  request.gain = gain;
  request.pixel_format = PixelFormatName(pixel_format);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    request.index = frames_served_;
  }
  // Inside the fill callback arv_buffer_get_data() reports size 0 (the fake sets the size
  // after filling); the buffer was allocated for the payload, width x height x bytes.
  size_t ignored = 0;
  auto* data = static_cast<unsigned char*>(const_cast<void*>(arv_buffer_get_data(buffer, &ignored)));
  const int bits = static_cast<int>(ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format));
  const int bytes = (bits + 7) / 8;
  const size_t n = static_cast<size_t>(std::max(0, request.width_px)) * std::max(0, request.height_px);
  if (data == nullptr || n == 0) return;
  std::memset(data, 0, n * bytes);

  Image image;
  Status status = source_(request, &image);
  if (status.ok() && (image.width() != request.width_px || image.height() != request.height_px ||
                      image.num_channels() != 1)) {
    status = Status::Error("frame source returned a " + std::to_string(image.width()) + "x" +
                           std::to_string(image.height()) + " image with " + std::to_string(image.num_channels()) +
                           " channels for a " + std::to_string(request.width_px) + "x" +
                           std::to_string(request.height_px) + " single-channel request");
  }
  const bool mono = request.pixel_format.rfind("Mono", 0) == 0;
  if (status.ok() && !mono) status = Status::Error("fake camera set to " + request.pixel_format + ", not a Mono format");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++frames_served_;
    if (!status.ok()) {
      ++source_errors_;
      last_source_error_ = status.message();
    }
  }
  if (!status.ok()) return;  // Sent black; the test sees source_errors().
  const double max_dn = std::ldexp(1.0, std::min(bits, 16)) - 1;
  for (int y = 0; y < request.height_px; ++y) {
    for (int x = 0; x < request.width_px; ++x) {
      const float v = image.at(x, y);
      const double dn = std::isfinite(v) ? std::clamp(std::round(static_cast<double>(v)), 0.0, max_dn) : 0.0;
      const size_t i = static_cast<size_t>(y) * request.width_px + x;
      if (bytes == 1) {
        data[i] = static_cast<unsigned char>(dn);
      } else {
        const auto u = static_cast<uint16_t>(dn);
        data[2 * i] = static_cast<unsigned char>(u & 0xff);  // Little-endian, as GenICam.
        data[2 * i + 1] = static_cast<unsigned char>(u >> 8);
      }
    }
  }
}

void AravisFakeCamera::SetLostPacketRatio(double ratio) {
  g_object_set(Gv(gv_fake_), "gvsp-lost-ratio", ratio, nullptr);
}

void AravisFakeCamera::DropControl() {
  arv_fake_camera_write_register(arv_gv_fake_camera_get_fake_camera(Gv(gv_fake_)), kControlChannelPrivilegeRegister, 0);
}

bool AravisFakeCamera::ControlHeld() const {
  guint32 privilege = 0;
  arv_fake_camera_read_register(arv_gv_fake_camera_get_fake_camera(Gv(gv_fake_)), kControlChannelPrivilegeRegister,
                                &privilege);
  return privilege != 0;
}

uint64_t AravisFakeCamera::frames_served() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return frames_served_;
}

uint64_t AravisFakeCamera::source_errors() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return source_errors_;
}

std::string AravisFakeCamera::last_source_error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_source_error_;
}

}  // namespace thinslab
