// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/usb_laser.h"

#include <libusb.h>

#include <cstdio>
#include <cstdlib>

namespace thinslab {
namespace {

libusb_context* Ctx(void* p) { return static_cast<libusb_context*>(p); }
libusb_device_handle* Handle(void* p) { return static_cast<libusb_device_handle*>(p); }

std::string Hex4(uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "%04x", v);
  return buf;
}

std::string UsbError(int code) {
  return std::string(libusb_error_name(code)) + " (" + libusb_strerror(code) + ")";
}

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    const size_t pos = s.find(sep, start);
    parts.push_back(s.substr(start, pos == std::string::npos ? std::string::npos : pos - start));
    if (pos == std::string::npos) return parts;
    start = pos + 1;
  }
}

// Hexadecimal without 0x, at most `max_digits` digits.
bool ParseHex(const std::string& s, int max_digits, uint32_t* value) {
  if (s.empty() || static_cast<int>(s.size()) > max_digits) return false;
  uint32_t v = 0;
  for (char c : s) {
    int d;
    if (c >= '0' && c <= '9') {
      d = c - '0';
    } else if (c >= 'a' && c <= 'f') {
      d = c - 'a' + 10;
    } else if (c >= 'A' && c <= 'F') {
      d = c - 'A' + 10;
    } else {
      return false;
    }
    v = v * 16 + d;
  }
  *value = v;
  return true;
}

bool ParseDecimal(const std::string& s, int min, int max, int* value) {
  if (s.empty() || s.size() > 9) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  const int v = std::atoi(s.c_str());
  if (v < min || v > max) return false;
  *value = v;
  return true;
}

Status ParseTransfer(const std::string& spec, const std::string& key, const std::string& text,
                     UsbControlTransfer* t) {
  const std::vector<std::string> f = Split(text, ',');
  auto error = [&](const std::string& what) {
    return Status::Error("--laser \"" + spec + "\": " + key + "=" + text + ": " + what);
  };
  if (f.size() < 4) {
    return error("expected <bmRequestType>,<bRequest>,<wValue>,<wIndex>[,<data byte>...] in hex");
  }
  uint32_t rt, req, value, index;
  if (!ParseHex(f[0], 2, &rt) || !ParseHex(f[1], 2, &req) || !ParseHex(f[2], 4, &value) ||
      !ParseHex(f[3], 4, &index)) {
    return error("bmRequestType and bRequest are 1-2 hex digits, wValue and wIndex 1-4");
  }
  if ((rt & 0x80) != 0) {
    return error("bmRequestType 0x" + f[0] +
                 " is device-to-host; on/off transfers must be host-to-device (bit 7 clear)");
  }
  t->request_type = static_cast<uint8_t>(rt);
  t->request = static_cast<uint8_t>(req);
  t->value = static_cast<uint16_t>(value);
  t->index = static_cast<uint16_t>(index);
  t->data.clear();
  for (size_t i = 4; i < f.size(); ++i) {
    uint32_t b;
    if (!ParseHex(f[i], 2, &b)) return error("data byte \"" + f[i] + "\" is not 1-2 hex digits");
    t->data.push_back(static_cast<uint8_t>(b));
  }
  return Status::Ok();
}

// HID class requests (HID 1.11, section 7.2) on a feature report with report id 0.
constexpr uint8_t kHidSetReport = 0x09, kHidGetReport = 0x01;
constexpr uint16_t kFeatureReport0 = 0x0300;
// The relay boards' 8-byte feature report commands (firmware of the "USBRelay" V-USB boards).
constexpr uint8_t kRelayOn = 0xFF, kRelayOff = 0xFD;

}  // namespace

Status ParseUsbLaserSpec(const std::string& spec, UsbLaserOptions* options) {
  UsbLaserOptions out;
  const std::vector<std::string> fields = Split(spec, ':');
  auto error = [&](const std::string& what) {
    return Status::Error("--laser \"" + spec + "\": " + what);
  };
  if (fields[0] == "hid-relay") {
    out.protocol = UsbLaserOptions::Protocol::kHidRelay;
  } else if (fields[0] == "vendor") {
    out.protocol = UsbLaserOptions::Protocol::kVendor;
  } else {
    return error("unknown protocol \"" + fields[0] + "\" (expected hid-relay or vendor)");
  }
  size_t positional = 0;
  bool have_on = false, have_off = false;
  for (size_t i = 1; i < fields.size(); ++i) {
    const std::string& f = fields[i];
    const size_t eq = f.find('=');
    if (eq == std::string::npos) {
      uint32_t v;
      if (positional == 0 || positional == 1) {
        if (!ParseHex(f, 4, &v)) {
          return error(std::string(positional == 0 ? "vendor id" : "product id") + " \"" + f +
                       "\" is not 1-4 hex digits");
        }
        (positional == 0 ? out.vendor_id : out.product_id) = static_cast<uint16_t>(v);
      } else if (positional == 2 && out.protocol == UsbLaserOptions::Protocol::kHidRelay) {
        if (!ParseDecimal(f, 1, 8, &out.relay_index)) {
          return error("relay index \"" + f + "\" is not 1..8");
        }
      } else {
        return error("unexpected field \"" + f + "\"");
      }
      ++positional;
      continue;
    }
    const std::string key = f.substr(0, eq), value = f.substr(eq + 1);
    if (key == "on" || key == "off") {
      if (out.protocol != UsbLaserOptions::Protocol::kVendor) {
        return error(key + "= is only for the vendor protocol");
      }
      THINSLAB_RETURN_IF_ERROR(ParseTransfer(spec, key, value, key == "on" ? &out.on : &out.off));
      (key == "on" ? have_on : have_off) = true;
    } else if (key == "timeout_ms") {
      if (!ParseDecimal(value, 1, 600000, &out.timeout_ms)) {
        return error("timeout_ms \"" + value + "\" is not 1..600000");
      }
    } else if (key == "interface") {
      if (!ParseDecimal(value, 0, 255, &out.interface_number)) {
        return error("interface \"" + value + "\" is not 0..255");
      }
    } else {
      return error("unknown field \"" + key + "\" (expected on, off, timeout_ms or interface)");
    }
  }
  if (out.protocol == UsbLaserOptions::Protocol::kVendor) {
    if (positional < 2) return error("vendor protocol needs <vid>:<pid>");
    if (!have_on || !have_off) return error("vendor protocol needs both on=... and off=...");
  } else if (positional == 1) {
    return error("give both <vid>:<pid> (or neither for 16c0:05df)");
  }
  *options = out;
  return Status::Ok();
}

std::string UsbLaser::device_name() const {
  return Hex4(options_.vendor_id) + ":" + Hex4(options_.product_id);
}

UsbLaser::~UsbLaser() {
  Disconnect();
  if (context_ != nullptr) libusb_exit(Ctx(context_));
}

void UsbLaser::Disconnect() {
  if (handle_ == nullptr) return;
  if (claimed_) libusb_release_interface(Handle(handle_), options_.interface_number);
  claimed_ = false;
  // Give the interface back to the kernel driver we took it from (usbhid for relay boards).
  if (reattach_kernel_driver_) {
    libusb_attach_kernel_driver(Handle(handle_), options_.interface_number);
  }
  reattach_kernel_driver_ = false;
  libusb_close(Handle(handle_));
  handle_ = nullptr;
}

Status UsbLaser::Connect() {
  const std::string name = "USB laser trigger " + device_name();
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(Ctx(context_), &list);
  if (count < 0) {
    return Status::Error(name + ": listing USB devices failed: " + UsbError(int(count)));
  }
  libusb_device* found = nullptr;
  for (ssize_t i = 0; i < count && found == nullptr; ++i) {
    libusb_device_descriptor desc;
    if (libusb_get_device_descriptor(list[i], &desc) == 0 &&
        desc.idVendor == options_.vendor_id && desc.idProduct == options_.product_id) {
      found = list[i];
    }
  }
  libusb_device_handle* handle = nullptr;
  const int open = found != nullptr ? libusb_open(found, &handle) : LIBUSB_ERROR_NOT_FOUND;
  libusb_free_device_list(list, 1);
  if (found == nullptr) {
    return Status::Error(name + ": no such USB device connected (" + std::to_string(count) +
                         " USB devices present; check `lsusb` and the VID:PID in --laser)");
  }
  if (open != 0) {
    return Status::Error(name + ": cannot open: " + UsbError(open) +
                         (open == LIBUSB_ERROR_ACCESS
                              ? "; give the user access with a udev rule (docs/drivers.md)"
                              : ""));
  }
  handle_ = handle;
  const int active = libusb_kernel_driver_active(handle, options_.interface_number);
  if (active == 1) {
    const int d = libusb_detach_kernel_driver(handle, options_.interface_number);
    if (d != 0) {
      Disconnect();
      return Status::Error(name + ": cannot detach the kernel driver from interface " +
                           std::to_string(options_.interface_number) + ": " + UsbError(d));
    }
    reattach_kernel_driver_ = true;
  }
  const int claim = libusb_claim_interface(handle, options_.interface_number);
  if (claim != 0) {
    Disconnect();
    return Status::Error(name + ": cannot claim interface " +
                         std::to_string(options_.interface_number) + ": " + UsbError(claim));
  }
  claimed_ = true;
  return Status::Ok();
}

int UsbLaser::SendSwitch(bool on, std::string* error) {
  if (handle_ == nullptr) {
    *error = "device not open";
    return LIBUSB_ERROR_NO_DEVICE;
  }
  int r;
  size_t expected;
  if (options_.protocol == UsbLaserOptions::Protocol::kHidRelay) {
    uint8_t report[8] = {on ? kRelayOn : kRelayOff, static_cast<uint8_t>(options_.relay_index),
                         0, 0, 0, 0, 0, 0};
    expected = sizeof(report);
    r = libusb_control_transfer(
        Handle(handle_), LIBUSB_ENDPOINT_OUT | LIBUSB_REQUEST_TYPE_CLASS | LIBUSB_RECIPIENT_INTERFACE,
        kHidSetReport, kFeatureReport0, static_cast<uint16_t>(options_.interface_number), report,
        sizeof(report), options_.timeout_ms);
  } else {
    UsbControlTransfer t = on ? options_.on : options_.off;
    expected = t.data.size();
    r = libusb_control_transfer(Handle(handle_), t.request_type, t.request, t.value, t.index,
                                t.data.empty() ? nullptr : t.data.data(),
                                static_cast<uint16_t>(t.data.size()), options_.timeout_ms);
  }
  if (r < 0) {
    *error = UsbError(r) + (r == LIBUSB_ERROR_TIMEOUT
                                ? " after " + std::to_string(options_.timeout_ms) + " ms"
                                : "");
    return r;
  }
  if (static_cast<size_t>(r) != expected) {
    *error = "short transfer: " + std::to_string(r) + " of " + std::to_string(expected) + " bytes";
    return LIBUSB_ERROR_IO;
  }
  return 0;
}

Status UsbLaser::SetEmission(bool on) {
  const std::string name = "USB laser trigger " + device_name();
  std::string error;
  int r = SendSwitch(on, &error);
  if (r == LIBUSB_ERROR_NO_DEVICE || r == LIBUSB_ERROR_IO) {
    // A relay board that browned out or was replugged gets a new device address: find it again
    // and retry once. Anything that fails twice is reported.
    Disconnect();
    const Status reopened = Connect();
    if (!reopened.ok()) {
      return Status::Error(name + ": switching " + (on ? "on" : "off") + " failed (" + error +
                           ") and reconnecting failed: " + reopened.message());
    }
    ++reconnects_;
    r = SendSwitch(on, &error);
  }
  if (r != 0) {
    return Status::Error(name + ": switching " + (on ? "on" : "off") + " failed: " + error);
  }
  if (options_.verify && options_.protocol == UsbLaserOptions::Protocol::kHidRelay) {
    bool state = false;
    THINSLAB_RETURN_IF_ERROR(ReadEmission(&state));
    if (state != on) {
      return Status::Error(name + ": relay " + std::to_string(options_.relay_index) + " reads " +
                           (state ? "on" : "off") + " after switching it " + (on ? "on" : "off"));
    }
  }
  return Status::Ok();
}

Status UsbLaser::ReadEmission(bool* on) {
  const std::string name = "USB laser trigger " + device_name();
  if (options_.protocol != UsbLaserOptions::Protocol::kHidRelay) {
    return Status::Error(name + ": the vendor protocol defines no state read-back");
  }
  if (handle_ == nullptr) return Status::Error(name + ": device not open");
  uint8_t report[8] = {};
  const int r = libusb_control_transfer(
      Handle(handle_), LIBUSB_ENDPOINT_IN | LIBUSB_REQUEST_TYPE_CLASS | LIBUSB_RECIPIENT_INTERFACE,
      kHidGetReport, kFeatureReport0, static_cast<uint16_t>(options_.interface_number), report,
      sizeof(report), options_.timeout_ms);
  if (r < 0) return Status::Error(name + ": reading the relay state failed: " + UsbError(r));
  if (r != static_cast<int>(sizeof(report))) {
    return Status::Error(name + ": relay state report has " + std::to_string(r) +
                         " bytes, expected 8");
  }
  // Bytes 0-4: board serial; byte 7: one bit per relay, bit 0 = relay 1.
  *on = ((report[7] >> (options_.relay_index - 1)) & 1) != 0;
  return Status::Ok();
}

Status OpenUsbLaser(const UsbLaserOptions& options, std::unique_ptr<UsbLaser>* out) {
  std::unique_ptr<UsbLaser> laser(new UsbLaser());
  laser->options_ = options;
  const std::string name = "USB laser trigger " + laser->device_name();
  if (options.protocol == UsbLaserOptions::Protocol::kHidRelay &&
      (options.relay_index < 1 || options.relay_index > 8)) {
    return Status::Error(name + ": relay index " + std::to_string(options.relay_index) +
                         " is not 1..8");
  }
  if (options.protocol == UsbLaserOptions::Protocol::kVendor &&
      ((options.on.request_type & 0x80) != 0 || (options.off.request_type & 0x80) != 0 ||
       options.on.data.size() > 4096 || options.off.data.size() > 4096)) {
    return Status::Error(name +
                         ": vendor on/off transfers must be host-to-device with <= 4096 bytes");
  }
  if (options.timeout_ms <= 0 || options.interface_number < 0 || options.interface_number > 255) {
    return Status::Error(name + ": timeout_ms must be positive and interface 0..255");
  }
  libusb_context* ctx = nullptr;
  const int init = libusb_init(&ctx);
  if (init != 0) return Status::Error(name + ": libusb_init failed: " + UsbError(init));
  laser->context_ = ctx;
  THINSLAB_RETURN_IF_ERROR(laser->Connect());
  *out = std::move(laser);
  return Status::Ok();
}

}  // namespace thinslab
