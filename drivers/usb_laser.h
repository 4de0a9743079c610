// SPDX-License-Identifier: Apache-2.0
// UsbLaser: laser trigger (Laser, drivers/laser.h) through libusb-1.0. Two protocols:
//  - "hid-relay": the widely sold HID USB relay boards ("USBRelay1/2/4/8", V-USB firmware,
//    VID 0x16c0 PID 0x05df). Relay n (1-based) on = HID SET_REPORT feature report
//    [0xFF, n, 0, 0, 0, 0, 0, 0], off = [0xFD, n, 0, ...]; the state is read back with a
//    GET_REPORT feature report whose byte 7 holds one bit per relay (bit n-1).
//  - "vendor": one vendor/class control transfer for on and one for off, with configurable
//    bmRequestType, bRequest, wValue, wIndex and data bytes (host-to-device only).
// Tested with real libusb calls against a scripted device under umockdev; never run on a real
// relay board (docs/drivers.md, "Laser trigger").
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/status.h"
#include "thinslab/drivers/laser.h"

namespace thinslab {

struct UsbControlTransfer {
  uint8_t request_type = 0x40;  // bmRequestType; bit 7 must be 0 (host to device).
  uint8_t request = 0;          // bRequest
  uint16_t value = 0;           // wValue
  uint16_t index = 0;           // wIndex
  std::vector<uint8_t> data;    // Payload (wLength = data.size()).
};

struct UsbLaserOptions {
  enum class Protocol { kHidRelay, kVendor };
  Protocol protocol = Protocol::kHidRelay;
  uint16_t vendor_id = 0x16c0;
  uint16_t product_id = 0x05df;
  int relay_index = 1;           // kHidRelay: 1-based relay channel (1..8).
  int interface_number = 0;      // Interface claimed (the HID interface of the relay board).
  UsbControlTransfer on, off;    // kVendor only.
  int timeout_ms = 1000;         // Per transfer.
  bool verify = true;            // kHidRelay: read the state back after every switch.
};

// Parses CLI specs (docs/cli.md, "--laser"):
//   "hid-relay"  |  "hid-relay:<vid>:<pid>"  |  "hid-relay:<vid>:<pid>:<relay>"
//   "vendor:<vid>:<pid>:on=<rt>,<req>,<value>,<index>[,<data hex bytes>...]:off=..."
// vid, pid, rt, req, value, index and data bytes are hexadecimal without 0x; e.g.
//   "hid-relay:16c0:05df:1", "vendor:1234:5678:on=40,01,0001,0000:off=40,01,0000,0000".
// Optional trailing ":timeout_ms=<n>" and ":interface=<n>" fields (decimal).
Status ParseUsbLaserSpec(const std::string& spec, UsbLaserOptions* options);

class UsbLaser : public Laser {
 public:
  ~UsbLaser() override;
  // Switches emission; on LIBUSB_ERROR_NO_DEVICE or LIBUSB_ERROR_IO reopens the device once and
  // retries. With verify, a read-back mismatch is an error.
  Status SetEmission(bool on) override;
  // kHidRelay: reads the relay state (GET_REPORT). kVendor: error (no read-back defined).
  Status ReadEmission(bool* on);
  // "16c0:05df".
  std::string device_name() const;
  int reconnects() const { return reconnects_; }

 private:
  friend Status OpenUsbLaser(const UsbLaserOptions&, std::unique_ptr<UsbLaser>*);
  UsbLaser() = default;
  Status Connect();
  void Disconnect();
  // Returns the libusb error code (0 on success) so SetEmission can decide to reconnect.
  int SendSwitch(bool on, std::string* error);

  UsbLaserOptions options_;
  void* context_ = nullptr;  // libusb_context*
  void* handle_ = nullptr;   // libusb_device_handle*
  bool claimed_ = false;
  bool reattach_kernel_driver_ = false;
  int reconnects_ = 0;
};

// Finds the first device with options' VID:PID, detaches a kernel driver from the interface if
// one is bound, claims it. Errors name the VID:PID: absent, open failure (e.g. permissions:
// suggests a udev rule), claim failure, invalid options.
Status OpenUsbLaser(const UsbLaserOptions& options, std::unique_ptr<UsbLaser>* out);

}  // namespace thinslab
