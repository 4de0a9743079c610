// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/aravis_camera.h"

#include <arpa/inet.h>
#include <arv.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <sstream>
#include <utility>

namespace thinslab {

struct AravisCamera::Handles {
  ArvCamera* camera = nullptr;  // Holds its own reference to the device.
  ArvStream* stream = nullptr;
  ~Handles() {
    if (stream != nullptr) g_object_unref(stream);
    // Releasing the camera releases the device: Aravis leaves control (CCP = 0) and stops its
    // heartbeat thread.
    if (camera != nullptr) g_object_unref(camera);
  }
  ArvGvDevice* gv_device() const {
    ArvDevice* device = arv_camera_get_device(camera);
    return ARV_IS_GV_DEVICE(device) ? ARV_GV_DEVICE(device) : nullptr;
  }
};

namespace {

constexpr int kGvcpPort = 3956;

struct PixelFormatInfo {
  const char* name;
  int bit_depth;
  int bytes_per_pixel;
};
// Unpacked little-endian monochrome formats (GenICam PFNC); packed ones (Mono12p,
// Mono12Packed) would need unpacking and are refused.
constexpr PixelFormatInfo kSupportedFormats[] = {
    {"Mono8", 8, 1}, {"Mono10", 10, 2}, {"Mono12", 12, 2}, {"Mono14", 14, 2}, {"Mono16", 16, 2}};

const PixelFormatInfo* FindSupportedFormat(const std::string& name) {
  for (const PixelFormatInfo& f : kSupportedFormats) {
    if (name == f.name) return &f;
  }
  return nullptr;
}

std::string SupportedFormatList() {
  std::string out;
  for (const PixelFormatInfo& f : kSupportedFormats) out += (out.empty() ? "" : ", ") + std::string(f.name);
  return out;
}

std::string Join(const std::vector<std::string>& values) {
  std::string out;
  for (const auto& v : values) out += (out.empty() ? "" : ", ") + v;
  return out;
}

// Takes the message out of a GError and frees it.
std::string TakeMessage(GError** error) {
  std::string message = (*error != nullptr && (*error)->message != nullptr) ? (*error)->message : "unknown error";
  g_clear_error(error);
  return message;
}

std::string Num(double v) {
  std::ostringstream ss;
  ss << v;
  return ss.str();
}

const char* BufferStatusName(ArvBufferStatus status) {
  switch (status) {
    case ARV_BUFFER_STATUS_SUCCESS: return "success";
    case ARV_BUFFER_STATUS_CLEARED: return "cleared";
    case ARV_BUFFER_STATUS_TIMEOUT: return "timeout (frame retention expired with packets missing)";
    case ARV_BUFFER_STATUS_MISSING_PACKETS: return "missing packets";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return "wrong packet id";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH: return "size mismatch (payload larger than the buffer)";
    case ARV_BUFFER_STATUS_FILLING: return "still filling";
    case ARV_BUFFER_STATUS_ABORTED: return "aborted";
    default: return "unknown";
  }
}

// ISO 8601 UTC with milliseconds from nanoseconds since the Unix epoch.
std::string IsoUtcFromNs(uint64_t ns) {
  const std::time_t seconds = static_cast<std::time_t>(ns / 1000000000ull);
  const int ms = static_cast<int>((ns / 1000000ull) % 1000);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1,
                tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
  return buf;
}

uint64_t NowNs() {
  return static_cast<uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}

class ScopedFd {
 public:
  explicit ScopedFd(int fd) : fd_(fd) {}
  ~ScopedFd() {
    if (fd_ >= 0) ::close(fd_);
  }
  ScopedFd(const ScopedFd&) = delete;
  ScopedFd& operator=(const ScopedFd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// The local address the kernel routes to `device` from: connect() on a UDP socket only
// selects the route, it sends nothing. Aravis needs it as the GVCP/GVSP interface address.
Status LocalAddressFor(const in_addr& device, const std::string& name, in_addr* local) {
  ScopedFd fd(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (fd.get() < 0) return Status::Error(name + ": cannot create a UDP socket: " + std::strerror(errno));
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(kGvcpPort);
  to.sin_addr = device;
  if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&to), sizeof(to)) != 0) {
    return Status::Error(name + ": no route to the camera address: " + std::strerror(errno));
  }
  sockaddr_in self{};
  socklen_t len = sizeof(self);
  if (::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&self), &len) != 0) {
    return Status::Error(name + ": cannot find the local interface address: " + std::strerror(errno));
  }
  *local = self.sin_addr;
  return Status::Ok();
}

// One unicast GVCP READREG of the bootstrap Version register (address 0), resent a few times
// within `timeout_s`. Any GigE Vision device answers it, controlled by us or not. A refused
// port (ICMP port unreachable) fails at once.
Status ProbeGvcp(const in_addr& device, double timeout_s, const std::string& name) {
  ScopedFd fd(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (fd.get() < 0) return Status::Error(name + ": cannot create a UDP socket: " + std::strerror(errno));
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(kGvcpPort);
  to.sin_addr = device;
  if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&to), sizeof(to)) != 0) {
    return Status::Error(name + ": no route to the camera address: " + std::strerror(errno));
  }
  const uint16_t request_id = 0x7451;
  // GVCP command header: key 0x42, flags 0x01 (acknowledge), command READREG 0x0080, payload
  // length 4, request id; payload: one big-endian register address.
  const unsigned char packet[12] = {0x42, 0x01, 0x00, 0x80, 0x00, 0x04,
                                    static_cast<unsigned char>(request_id >> 8),
                                    static_cast<unsigned char>(request_id & 0xff), 0, 0, 0, 0};
  const int attempts = 3;
  const int wait_ms = std::max(1, static_cast<int>(timeout_s * 1000 / attempts));
  for (int attempt = 0; attempt < attempts; ++attempt) {
    if (::send(fd.get(), packet, sizeof(packet), 0) < 0 && errno != ECONNREFUSED) {
      return Status::Error(name + ": cannot send to UDP port 3956: " + std::strerror(errno));
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(wait_ms);
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      pollfd p{fd.get(), POLLIN, 0};
      const int n = ::poll(&p, 1, static_cast<int>(left.count()));
      if (n <= 0) break;
      unsigned char reply[64];
      const ssize_t got = ::recv(fd.get(), reply, sizeof(reply), 0);
      if (got < 0) {
        if (errno == ECONNREFUSED) {
          return Status::Error(name +
                               ": no GigE Vision device there (UDP port 3956 refused the connection: "
                               "nothing listens at this address)");
        }
        continue;
      }
      // Acknowledge: status, answer 0x0081 (READREG_ACK), length, ack id, value.
      if (got >= 12 && reply[2] == 0x00 && reply[3] == 0x81 && reply[6] == packet[6] && reply[7] == packet[7]) {
        return Status::Ok();
      }
    }
  }
  return Status::Error(name + ": no GigE Vision reply on UDP port 3956 within " + Num(timeout_s) +
                       " s (is the camera powered, on this subnet, and is UDP 3956 open in the firewall?)");
}

}  // namespace

bool AravisCameraOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (address.empty()) {
    msg << "AravisCameraOptions::address is empty. Violated constraint: an IPv4 address or an Aravis device id";
  } else if (pixel_format.empty()) {
    msg << "AravisCameraOptions::pixel_format is empty. Violated constraint: one of " << SupportedFormatList();
  } else if (!std::isfinite(gain_db)) {
    msg << "AravisCameraOptions::gain_db = " << gain_db << ". Violated constraint: finite";
  } else if (stream_buffers < 1 || stream_buffers > 256) {
    msg << "AravisCameraOptions::stream_buffers = " << stream_buffers << ". Violated constraint: 1..256";
  } else if (!(frame_timeout_s > 0) || !std::isfinite(frame_timeout_s)) {
    msg << "AravisCameraOptions::frame_timeout_s = " << frame_timeout_s << ". Violated constraint: > 0";
  } else if (packet_resend != 0 && packet_resend != 1) {
    msg << "AravisCameraOptions::packet_resend = " << packet_resend << ". Violated constraint: 0 or 1";
  } else if (packet_size != 0 && (packet_size < 576 || packet_size > 16384)) {
    msg << "AravisCameraOptions::packet_size = " << packet_size
        << ". Violated constraint: 0 (negotiate) or 576..16384 bytes";
  } else if (packet_timeout_us <= 0) {
    msg << "AravisCameraOptions::packet_timeout_us = " << packet_timeout_us << ". Violated constraint: > 0";
  } else if (frame_retention_us <= 0) {
    msg << "AravisCameraOptions::frame_retention_us = " << frame_retention_us << ". Violated constraint: > 0";
  } else if (!(connect_timeout_s > 0) || !std::isfinite(connect_timeout_s)) {
    msg << "AravisCameraOptions::connect_timeout_s = " << connect_timeout_s << ". Violated constraint: > 0";
  } else if (width_px < 0 || height_px < 0 || ((width_px == 0) != (height_px == 0))) {
    msg << "AravisCameraOptions::width_px, height_px = " << width_px << ", " << height_px
        << ". Violated constraint: both 0 (keep the camera's region) or both > 0";
  } else if (camera_id.empty()) {
    msg << "AravisCameraOptions::camera_id is empty. Violated constraint: non-empty (e.g. \"cam0\")";
  } else if (bit_depth < 0 || bit_depth > 16) {
    msg << "AravisCameraOptions::bit_depth = " << bit_depth << ". Violated constraint: 0 (from pixel format) or 1..16";
  } else if (!(black_level_dn >= 0) || !std::isfinite(black_level_dn)) {
    msg << "AravisCameraOptions::black_level_dn = " << black_level_dn << ". Violated constraint: >= 0";
  } else if (!(saturation_dn >= 0) || !std::isfinite(saturation_dn)) {
    msg << "AravisCameraOptions::saturation_dn = " << saturation_dn << ". Violated constraint: >= 0";
  } else if (!(nominal_focal_length_px >= 0) || !std::isfinite(nominal_focal_length_px)) {
    msg << "AravisCameraOptions::nominal_focal_length_px = " << nominal_focal_length_px
        << ". Violated constraint: >= 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

AravisCamera::AravisCamera(const AravisCameraOptions& options, std::unique_ptr<Handles> handles)
    : options_(options), h_(std::move(handles)), device_name_("aravis camera " + options.address) {
  for (const char* key : {"timeouts", "incomplete_frames", "rearms", "control_regained", "stale_buffers_dropped",
                          "frames_captured"}) {
    counters_[key] = 0;
  }
}

AravisCamera::~AravisCamera() {
  if (h_ != nullptr && h_->camera != nullptr && h_->stream != nullptr) {
    GError* error = nullptr;
    arv_camera_stop_acquisition(h_->camera, &error);
    g_clear_error(&error);
  }
}

Status AravisCamera::Configure() {
  ArvCamera* cam = h_->camera;
  GError* error = nullptr;
  auto text = [](const char* s) { return std::string(s != nullptr ? s : ""); };
  const std::string vendor = text(arv_camera_get_vendor_name(cam, &error));
  g_clear_error(&error);
  const std::string model = text(arv_camera_get_model_name(cam, &error));
  g_clear_error(&error);
  const std::string serial = text(arv_camera_get_device_serial_number(cam, &error));
  g_clear_error(&error);
  device_name_ = "aravis camera " + options_.address + " (" + vendor + " " + model +
                 (serial.empty() ? "" : ", serial " + serial) + ")";
  auto fail = [&](const std::string& what) { return Status::Error(device_name_ + ": " + what); };

  guint n_formats = 0;
  const char** formats = arv_camera_dup_available_pixel_formats_as_strings(cam, &n_formats, &error);
  if (error != nullptr) return fail("cannot list pixel formats: " + TakeMessage(&error));
  offered_formats_.clear();
  for (guint i = 0; i < n_formats; ++i) {
    if (formats[i] != nullptr) offered_formats_.push_back(formats[i]);
  }
  g_free(formats);

  const PixelFormatInfo* format = FindSupportedFormat(options_.pixel_format);
  const bool offered = std::find(offered_formats_.begin(), offered_formats_.end(), options_.pixel_format) !=
                       offered_formats_.end();
  if (!offered) {
    return fail("pixel format '" + options_.pixel_format + "' is not offered by the camera (offered: " +
                Join(offered_formats_) + "; thinslab reads " + SupportedFormatList() + ")");
  }
  if (format == nullptr) {
    return fail("pixel format '" + options_.pixel_format + "' is offered but thinslab reads only " +
                SupportedFormatList() + " (single-channel, unpacked)");
  }
  bytes_per_pixel_ = format->bytes_per_pixel;

  if (options_.width_px > 0) {
    arv_camera_set_region(cam, 0, 0, options_.width_px, options_.height_px, &error);
    if (error != nullptr) {
      return fail("cannot set the region to " + std::to_string(options_.width_px) + "x" +
                  std::to_string(options_.height_px) + " px: " + TakeMessage(&error));
    }
  }
  arv_camera_set_pixel_format_from_string(cam, options_.pixel_format.c_str(), &error);
  if (error != nullptr) return fail("cannot set pixel format '" + options_.pixel_format + "': " + TakeMessage(&error));
  const std::string format_now = text(arv_camera_get_pixel_format_as_string(cam, &error));
  g_clear_error(&error);
  if (format_now != options_.pixel_format) {
    return fail("pixel format reads back as '" + format_now + "' after setting '" + options_.pixel_format + "'");
  }
  gint x = 0, y = 0, width = 0, height = 0;
  arv_camera_get_region(cam, &x, &y, &width, &height, &error);
  if (error != nullptr) return fail("cannot read the region: " + TakeMessage(&error));
  if (options_.width_px > 0 && (width != options_.width_px || height != options_.height_px)) {
    return fail("region reads back as " + std::to_string(width) + "x" + std::to_string(height) + " px, not the " +
                std::to_string(options_.width_px) + "x" + std::to_string(options_.height_px) + " px asked for");
  }
  if (width <= 0 || height <= 0) return fail("camera reports an empty region");

  const gboolean has_gain = arv_camera_is_gain_available(cam, &error);
  g_clear_error(&error);
  if (has_gain) {
    arv_camera_set_gain(cam, options_.gain_db, &error);
    if (error != nullptr) {
      double lo = 0, hi = 0;
      const std::string message = TakeMessage(&error);
      arv_camera_get_gain_bounds(cam, &lo, &hi, &error);
      g_clear_error(&error);
      return fail("cannot set gain " + Num(options_.gain_db) + " (camera range " + Num(lo) + " .. " + Num(hi) +
                  "): " + message);
    }
    gain_ = arv_camera_get_gain(cam, &error);
    if (error != nullptr) return fail("cannot read the gain back: " + TakeMessage(&error));
  } else if (options_.gain_db != 0) {
    return fail("camera has no Gain feature; AravisCameraOptions::gain_db must be 0");
  }

  arv_camera_set_acquisition_mode(cam, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
  if (error != nullptr) return fail("cannot set continuous acquisition mode: " + TakeMessage(&error));
  const gboolean software_trigger = arv_camera_is_software_trigger_supported(cam, &error);
  g_clear_error(&error);
  if (!software_trigger) return fail("camera has no software trigger (TriggerSoftware), which thinslab needs");
  arv_camera_set_trigger(cam, "Software", &error);
  if (error != nullptr) return fail("cannot select the software trigger: " + TakeMessage(&error));

  if (h_->gv_device() != nullptr) {
    if (options_.packet_size > 0) {
      arv_camera_gv_set_packet_size(cam, options_.packet_size, &error);
      if (error != nullptr) {
        return fail("cannot set GVSP packet size " + std::to_string(options_.packet_size) +
                    " bytes: " + TakeMessage(&error));
      }
    } else {
      // Cameras without test-packet support cannot negotiate; their current size may still
      // work, so carry on with it and leave a trace in the manifest's statistics.
      arv_camera_gv_auto_packet_size(cam, &error);
      if (error != nullptr) {
        g_clear_error(&error);
        counters_["packet_size_negotiation_failed"] = 1;
      }
    }
    // Cameras round the packet size to their increment: record what is in use.
    packet_size_bytes_ = static_cast<int>(arv_camera_gv_get_packet_size(cam, &error));
    if (error != nullptr) return fail("cannot read back the GVSP packet size: " + TakeMessage(&error));
    if (packet_size_bytes_ <= 0) return fail("camera reports a GVSP packet size of 0 bytes");
  }

  exposure_us_ = arv_camera_get_exposure_time(cam, &error);
  g_clear_error(&error);

  info_ = CameraInfo();
  info_.id = options_.camera_id;
  info_.model = "aravis";
  info_.serial = serial;
  info_.width_px = width;
  info_.height_px = height;
  const double f = options_.nominal_focal_length_px > 0 ? options_.nominal_focal_length_px : width;
  info_.fx_px = info_.fy_px = f;
  // OpenCV convention (integer pixel centres): the image centre is at (w - 1) / 2.
  info_.cx_px = 0.5 * (width - 1);
  info_.cy_px = 0.5 * (height - 1);
  info_.bit_depth = options_.bit_depth > 0 ? options_.bit_depth : format->bit_depth;
  info_.black_level_dn = options_.black_level_dn;
  info_.saturation_dn =
      options_.saturation_dn > 0 ? options_.saturation_dn : std::ldexp(1.0, info_.bit_depth) - 1;
  return Status::Ok();
}

Status AravisCamera::StartStream() {
  GError* error = nullptr;
  h_->stream = arv_camera_create_stream(h_->camera, nullptr, nullptr, &error);
  if (h_->stream == nullptr || error != nullptr) {
    return Status::Error(device_name_ + ": cannot create the stream: " + TakeMessage(&error));
  }
  if (ARV_IS_GV_STREAM(h_->stream)) {
    g_object_set(h_->stream, "packet-resend",
                 options_.packet_resend ? ARV_GV_STREAM_PACKET_RESEND_ALWAYS : ARV_GV_STREAM_PACKET_RESEND_NEVER,
                 "packet-timeout", static_cast<guint>(options_.packet_timeout_us), "frame-retention",
                 static_cast<guint>(options_.frame_retention_us), "socket-buffer",
                 ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
  }
  const guint payload = arv_camera_get_payload(h_->camera, &error);
  if (error != nullptr || payload == 0) {
    return Status::Error(device_name_ + ": cannot read the payload size: " +
                         (error != nullptr ? TakeMessage(&error) : std::string("camera reports 0 bytes")));
  }
  const size_t needed = static_cast<size_t>(info_.width_px) * info_.height_px * bytes_per_pixel_;
  if (payload < needed) {
    return Status::Error(device_name_ + ": payload of " + std::to_string(payload) + " bytes is smaller than a " +
                         std::to_string(info_.width_px) + "x" + std::to_string(info_.height_px) + " " +
                         options_.pixel_format + " image (" + std::to_string(needed) + " bytes)");
  }
  for (int i = 0; i < options_.stream_buffers; ++i) {
    arv_stream_push_buffer(h_->stream, arv_buffer_new_allocate(payload));
  }
  arv_camera_start_acquisition(h_->camera, &error);
  if (error != nullptr) return Status::Error(device_name_ + ": cannot start acquisition: " + TakeMessage(&error));
  return Status::Ok();
}

int AravisCamera::DrainStaleBuffers() {
  // A frame that arrives after its capture timed out must not be taken for the next trigger's.
  int dropped = 0;
  while (ArvBuffer* buffer = arv_stream_try_pop_buffer(h_->stream)) {
    arv_stream_push_buffer(h_->stream, buffer);
    ++dropped;
  }
  counters_["stale_buffers_dropped"] += dropped;
  return dropped;
}

uint64_t AravisCamera::UnwrapFrameId(uint64_t raw_id) {
  if (have_frame_id_ && raw_id < last_raw_frame_id_ && last_raw_frame_id_ <= 0xffff) frame_id_offset_ += 0xffff;
  last_raw_frame_id_ = raw_id;
  have_frame_id_ = true;
  return raw_id + frame_id_offset_;
}

ArvBuffer* AravisCamera::PopFrameOfThisTrigger(uint64_t timeout_us, int abandoned) {
  const gint64 deadline = g_get_monotonic_time() + static_cast<gint64>(timeout_us);
  while (true) {
    const gint64 left = deadline - g_get_monotonic_time();
    if (left <= 0) return nullptr;
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(h_->stream, static_cast<guint64>(left));
    if (buffer == nullptr || abandoned <= 0) return buffer;
    // Frames arrive in id order: one just above the last taken belongs to a trigger given up
    // on. A camera that restarted its ids (a reset) gives lower ones, which are taken.
    const uint64_t id = UnwrapFrameId(arv_buffer_get_frame_id(buffer));
    if (id <= last_taken_frame_id_ || id > last_taken_frame_id_ + static_cast<uint64_t>(abandoned)) return buffer;
    arv_stream_push_buffer(h_->stream, buffer);
    counters_["stale_buffers_dropped"] += 1;
  }
}

Status AravisCamera::Rearm(const std::string& reason) {
  counters_["rearms"] += 1;
  GError* error = nullptr;
  ArvGvDevice* gv = h_->gv_device();
  if (gv != nullptr && !arv_gv_device_is_controller(gv)) {
    // The camera dropped our control channel (heartbeat lost during an idle gap, a reboot or
    // another application): take it back, or say who holds it.
    if (!arv_gv_device_take_control(gv, &error)) {
      // A timeout is a camera that no longer answers at all; a refusal is another controller.
      const bool silent = error != nullptr && g_error_matches(error, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_TIMEOUT);
      return Status::Error(device_name_ + ": " + reason + "; cannot take control of the camera again (" +
                           TakeMessage(&error) + "): " +
                           (silent ? "the camera does not answer (unplugged, powered off or unreachable)"
                                   : "another application may be controlling it"));
    }
    g_clear_error(&error);
    counters_["control_regained"] += 1;
  }
  arv_camera_stop_acquisition(h_->camera, &error);
  g_clear_error(&error);
  DrainStaleBuffers();
  // A camera that lost control may also have been reset: restore trigger mode and exposure.
  arv_camera_set_trigger(h_->camera, "Software", &error);
  if (error != nullptr) {
    return Status::Error(device_name_ + ": " + reason + "; cannot restore the software trigger: " +
                         TakeMessage(&error));
  }
  if (exposure_us_ > 0) {
    arv_camera_set_exposure_time(h_->camera, exposure_us_, &error);
    g_clear_error(&error);
  }
  arv_camera_start_acquisition(h_->camera, &error);
  if (error != nullptr) {
    return Status::Error(device_name_ + ": " + reason + "; cannot restart acquisition: " + TakeMessage(&error));
  }
  return Status::Ok();
}

Status AravisCamera::SetExposure(double requested_us, double* applied_us) {
  if (!(requested_us > 0) || !std::isfinite(requested_us)) {
    return Status::Error(device_name_ + ": exposure " + Num(requested_us) + " us is not a positive number");
  }
  GError* error = nullptr;
  double lo = 0, hi = 0;
  arv_camera_get_exposure_time_bounds(h_->camera, &lo, &hi, &error);
  if (error == nullptr && hi > 0 && (requested_us < lo || requested_us > hi)) {
    return Status::Error(device_name_ + ": exposure " + Num(requested_us) + " us is outside the camera's range " +
                         Num(lo) + " .. " + Num(hi) + " us");
  }
  g_clear_error(&error);
  arv_camera_set_exposure_time(h_->camera, requested_us, &error);
  if (error != nullptr) {
    return Status::Error(device_name_ + ": cannot set exposure " + Num(requested_us) + " us: " + TakeMessage(&error));
  }
  // Cameras round exposures (the Aravis fake to whole microseconds): record what it applied.
  const double applied = arv_camera_get_exposure_time(h_->camera, &error);
  if (error != nullptr) {
    return Status::Error(device_name_ + ": cannot read back the exposure: " + TakeMessage(&error));
  }
  if (!(applied > 0)) return Status::Error(device_name_ + ": exposure reads back as " + Num(applied) + " us");
  exposure_us_ = applied;
  if (applied_us != nullptr) *applied_us = applied;
  return Status::Ok();
}

Status AravisCamera::Capture(CapturedFrame* frame) {
  DrainStaleBuffers();
  const int abandoned_before = abandoned_triggers_;
  int triggers = 0;
  ArvGvDevice* gv = h_->gv_device();
  if (gv != nullptr && !arv_gv_device_is_controller(gv)) {
    THINSLAB_RETURN_IF_ERROR(Rearm("control of the camera was lost since the last frame"));
  }
  const guint64 timeout_us = static_cast<guint64>(options_.frame_timeout_s * 1e6);
  GError* error = nullptr;
  ArvBuffer* buffer = nullptr;
  for (int attempt = 0; attempt < 2 && buffer == nullptr; ++attempt) {
    arv_camera_software_trigger(h_->camera, &error);
    if (error == nullptr) ++triggers;
    if (error != nullptr) {
      const std::string message = "software trigger failed: " + TakeMessage(&error);
      if (attempt == 0) {
        THINSLAB_RETURN_IF_ERROR(Rearm(message));
        continue;
      }
      return Status::Error(device_name_ + ": " + message + " (also after re-arming)");
    }
    buffer = PopFrameOfThisTrigger(timeout_us, abandoned_before);
    if (buffer == nullptr) {
      counters_["timeouts"] += 1;
      const std::string message = "no frame within " + Num(options_.frame_timeout_s) + " s of the software trigger";
      if (attempt == 0) {
        THINSLAB_RETURN_IF_ERROR(Rearm(message));
        continue;
      }
      abandoned_triggers_ = abandoned_before + triggers;
      return Status::Error(device_name_ + ": " + message +
                           ", also after re-arming (retaking control and restarting acquisition); check the "
                           "cable, the firewall (GVSP is UDP from the camera) and the packet size (" +
                           std::to_string(packet_size_bytes_) + " bytes vs. the interface MTU)");
    }
  }
  // Hands the buffer back to the stream whichever way this returns.
  struct Requeue {
    ArvStream* stream;
    ArvBuffer* buffer;
    ~Requeue() { arv_stream_push_buffer(stream, buffer); }
  } requeue{h_->stream, buffer};

  const uint64_t frame_id = UnwrapFrameId(arv_buffer_get_frame_id(buffer));
  // Within this capture the first frame after its (re-)trigger answers it. Triggers sent so far
  // (earlier captures' abandoned ones and this capture's) whose frames are neither this one nor
  // among the ids skipped or drained before it may still arrive: the next capture skips them.
  // (When the camera never took a timed-out trigger, the next capture's own frame looks like its
  // leftover: one wasted frame timeout and re-arm there, never a wrong frame.)
  if (frame_id > last_taken_frame_id_) {
    const uint64_t passed = frame_id - last_taken_frame_id_ - 1;  // Ids before this frame, not taken.
    const int64_t outstanding = static_cast<int64_t>(abandoned_before) + triggers - 1 -
                                static_cast<int64_t>(std::min<uint64_t>(passed, 1u << 20));
    abandoned_triggers_ = static_cast<int>(std::max<int64_t>(0, outstanding));
  } else {
    abandoned_triggers_ = 0;  // The camera restarted its ids.
  }
  last_taken_frame_id_ = frame_id;

  const ArvBufferStatus status = arv_buffer_get_status(buffer);
  if (status != ARV_BUFFER_STATUS_SUCCESS) {
    counters_["incomplete_frames"] += 1;
    const auto stats = statistics();
    auto stat = [&](const char* key) {
      const auto it = stats.find(key);
      return it == stats.end() ? std::string("?") : Num(it->second);
    };
    return Status::Error(device_name_ + ": frame " + std::to_string(frame_id) + " incomplete: " +
                         BufferStatusName(status) + " (stream so far: missing_packets " + stat("missing_packets") +
                         ", resend_requests " + stat("resend_requests") + ", resent_packets " +
                         stat("resent_packets") + ", packet resend " + (options_.packet_resend ? "on" : "off") + ")");
  }
  if (arv_buffer_get_payload_type(buffer) != ARV_BUFFER_PAYLOAD_TYPE_IMAGE) {
    return Status::Error(device_name_ + ": frame " + std::to_string(frame_id) + " carries no image payload");
  }
  const int width = arv_buffer_get_image_width(buffer);
  const int height = arv_buffer_get_image_height(buffer);
  if (width != info_.width_px || height != info_.height_px) {
    return Status::Error(device_name_ + ": frame " + std::to_string(frame_id) + " is " + std::to_string(width) + "x" +
                         std::to_string(height) + " px, expected " + std::to_string(info_.width_px) + "x" +
                         std::to_string(info_.height_px));
  }
  const ArvPixelFormat pixel_format = arv_buffer_get_image_pixel_format(buffer);
  if (static_cast<int>(ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format)) != 8 * bytes_per_pixel_) {
    return Status::Error(device_name_ + ": frame " + std::to_string(frame_id) + " has " +
                         std::to_string(ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format)) +
                         " bits per pixel, expected " + options_.pixel_format);
  }
  gint padding_x = 0, padding_y = 0;
  arv_buffer_get_image_padding(buffer, &padding_x, &padding_y);
  const size_t stride = static_cast<size_t>(width) * bytes_per_pixel_ + std::max(0, padding_x);
  size_t size = 0;
  const auto* data = static_cast<const unsigned char*>(arv_buffer_get_image_data(buffer, &size));
  const size_t needed = stride * (height - 1) + static_cast<size_t>(width) * bytes_per_pixel_;
  if (data == nullptr || size < needed) {
    return Status::Error(device_name_ + ": frame " + std::to_string(frame_id) + " holds " + std::to_string(size) +
                         " bytes, a " + std::to_string(width) + "x" + std::to_string(height) + " " +
                         options_.pixel_format + " image needs " + std::to_string(needed));
  }
  Image image(width, height);
  for (int yy = 0; yy < height; ++yy) {
    const unsigned char* row = data + stride * yy;
    for (int xx = 0; xx < width; ++xx) {
      if (bytes_per_pixel_ == 1) {
        image.at(xx, yy) = row[xx];
      } else {
        // GenICam unpacked formats are little-endian.
        const unsigned char* p = row + 2 * xx;
        image.at(xx, yy) = static_cast<float>(p[0] | (p[1] << 8));
      }
    }
  }
  const uint64_t system_ns = arv_buffer_get_system_timestamp(buffer);
  frame->raw_dn = std::move(image);
  frame->exposure_time_us = exposure_us_;
  frame->gain_db = gain_;
  frame->frame_id = frame_id;
  // The device timestamp counts camera ticks since its power-up (Aravis converts them to ns),
  // not UTC: it is recorded as is, and the host's clock when the frame arrived gives the UTC
  // time. 0 means the camera gave none.
  const uint64_t device_ns = arv_buffer_get_timestamp(buffer);
  if (device_ns != 0) frame->device_timestamp_ns = device_ns;
  frame->timestamp_utc = IsoUtcFromNs(system_ns != 0 ? system_ns : NowNs());
  counters_["frames_captured"] += 1;
  return Status::Ok();
}

std::map<std::string, double> AravisCamera::statistics() const {
  std::map<std::string, double> out = counters_;
  out["packet_size_bytes"] = packet_size_bytes_;
  out["exposure_time_us"] = exposure_us_;
  if (h_ == nullptr || h_->stream == nullptr) return out;
  const guint n = arv_stream_get_n_infos(h_->stream);
  for (guint i = 0; i < n; ++i) {
    const char* name = arv_stream_get_info_name(h_->stream, i);
    if (name == nullptr) continue;
    std::string key = name;
    if (key.rfind("n_", 0) == 0) key = key.substr(2);
    // Aravis's names, made explicit: its "failures" are failed buffers and its "timeouts" are
    // buffers that timed out inside the stream (this driver's "timeouts" are triggers that got
    // no buffer at all).
    if (key == "failures") key = "failed_buffers";
    if (key == "timeouts") key = "buffer_timeouts";
    const GType type = arv_stream_get_info_type(h_->stream, i);
    if (type == G_TYPE_UINT64) {
      out[key] = static_cast<double>(arv_stream_get_info_uint64(h_->stream, i));
    } else if (type == G_TYPE_DOUBLE) {
      out[key] = arv_stream_get_info_double(h_->stream, i);
    }
  }
  if (n == 0) {
    // Older streams without named infos: the two counter calls of the 0.8 API.
    guint64 completed = 0, failures = 0, underruns = 0;
    arv_stream_get_statistics(h_->stream, &completed, &failures, &underruns);
    out["completed_buffers"] = static_cast<double>(completed);
    out["failed_buffers"] = static_cast<double>(failures);
    out["underruns"] = static_cast<double>(underruns);
    if (ARV_IS_GV_STREAM(h_->stream)) {
      guint64 resent = 0, missing = 0;
      arv_gv_stream_get_statistics(ARV_GV_STREAM(h_->stream), &resent, &missing);
      out["resent_packets"] = static_cast<double>(resent);
      out["missing_packets"] = static_cast<double>(missing);
    }
  }
  return out;
}

Status OpenAravisCamera(const AravisCameraOptions& options, std::unique_ptr<AravisCamera>* camera) {
  std::string check_error;
  if (!options.Check(&check_error)) return Status::Error(check_error);
  const std::string name = "aravis camera " + options.address;
  GError* error = nullptr;
  ArvDevice* device = nullptr;
  in_addr device_ip{};
  if (::inet_pton(AF_INET, options.address.c_str(), &device_ip) == 1) {
    // By address: unicast only. arv_camera_new()/arv_open_device() would fall back to a
    // discovery broadcast on every interface when the address does not answer.
    THINSLAB_RETURN_IF_ERROR(ProbeGvcp(device_ip, options.connect_timeout_s, name));
    in_addr local_ip{};
    THINSLAB_RETURN_IF_ERROR(LocalAddressFor(device_ip, name, &local_ip));
    GInetAddress* interface_address =
        g_inet_address_new_from_bytes(reinterpret_cast<const guint8*>(&local_ip), G_SOCKET_FAMILY_IPV4);
    GInetAddress* device_address =
        g_inet_address_new_from_bytes(reinterpret_cast<const guint8*>(&device_ip), G_SOCKET_FAMILY_IPV4);
    device = arv_gv_device_new(interface_address, device_address, &error);
    g_object_unref(interface_address);
    g_object_unref(device_address);
    if (device == nullptr) {
      return Status::Error(name + ": cannot open the GigE Vision device: " + TakeMessage(&error));
    }
  } else {
    // A device id ("<vendor>-<serial>"): Aravis finds it by discovery.
    device = arv_open_device(options.address.c_str(), &error);
    if (device == nullptr) {
      return Status::Error(name + ": no device with this id found by Aravis discovery" +
                           (error != nullptr ? ": " + TakeMessage(&error) : std::string()));
    }
  }
  g_clear_error(&error);
  ArvCamera* arv_camera = arv_camera_new_with_device(device, &error);
  g_object_unref(device);  // The camera keeps its own reference.
  if (arv_camera == nullptr) return Status::Error(name + ": not usable as a camera: " + TakeMessage(&error));
  g_clear_error(&error);

  auto handles = std::make_unique<AravisCamera::Handles>();
  handles->camera = arv_camera;
  ArvGvDevice* gv = handles->gv_device();
  if (gv != nullptr && !arv_gv_device_is_controller(gv)) {
    return Status::Error(name + ": cannot take control of the camera: another application controls it");
  }
  std::unique_ptr<AravisCamera> opened(new AravisCamera(options, std::move(handles)));
  THINSLAB_RETURN_IF_ERROR(opened->Configure());
  THINSLAB_RETURN_IF_ERROR(opened->StartStream());
  *camera = std::move(opened);
  return Status::Ok();
}

}  // namespace thinslab
