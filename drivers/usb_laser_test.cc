// SPDX-License-Identifier: Apache-2.0
// UsbLaser with real libusb calls against a scripted USB device in a umockdev testbed: the
// testbed provides /sys/bus/usb (enumeration, descriptors) and /dev/bus/usb/001/001, whose
// usbdevfs ioctls (URB submit/reap/discard, claim, kernel driver queries) are answered by
// ScriptedRelay below, which records every control transfer byte for byte.
//
// umockdev works by LD_PRELOAD of libumockdev-preload.so; main() re-executes this binary with
// it when it is missing, so both ctest and a plain run work. Under AddressSanitizer the preload
// library comes before libasan, which ASan accepts with verify_asan_link_order=0 (set only for
// this re-executed process).
#include "thinslab/drivers/usb_laser.h"

#include <errno.h>
#include <gtest/gtest.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <umockdev.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace thinslab {
namespace {

using Bytes = std::vector<uint8_t>;

// A HID relay board (or any device with the given ids): one configuration, one HID interface.
std::string DeviceDescription(uint16_t vid, uint16_t pid) {
  char ids[16];
  std::snprintf(ids, sizeof(ids), "%02x%02x%02x%02x", vid & 0xff, vid >> 8, pid & 0xff, pid >> 8);
  // Device (18 bytes): USB 1.1, class per interface, EP0 8 bytes, VID, PID, bcdDevice 1.00,
  // 1 configuration. Configuration (34 bytes total): 1 interface, bus powered, 100 mA.
  // Interface 0: HID, 1 endpoint. HID descriptor 1.01, 22-byte report descriptor.
  // Endpoint 0x81 interrupt IN, 8 bytes, 10 ms.
  const std::string descriptors = std::string("1201100100000008") + ids +
                                  "000101020001"
                                  "09022200010100803209040000010300000009210101000122160007058103"
                                  "08000a";
  return "P: /devices/usb1\n"
         "N: bus/usb/001/001\n"
         "E: SUBSYSTEM=usb\n"
         "E: DRIVER=usb\n"
         "E: BUSNUM=001\n"
         "E: DEVNUM=001\n"
         "E: DEVNAME=/dev/bus/usb/001/001\n"
         "E: DEVTYPE=usb_device\n"
         "A: bConfigurationValue=1\\n\n"
         "A: busnum=1\\n\n"
         "A: devnum=1\\n\n"
         "A: speed=12\\n\n"
         "H: descriptors=" +
         descriptors + "\n";
}

struct ScriptedRelay {
  std::mutex mutex;
  // Every control transfer submitted: the 8 setup bytes followed by the OUT data.
  std::vector<Bytes> transfers;
  uint8_t relays = 0;             // Bit n-1 = relay n closed.
  bool stuck = false;             // Relay ignores commands (welded contact).
  bool hang = false;              // Never completes a URB (device stopped answering).
  int fail_submits = 0;           // The next N submits fail with ENODEV (unplugged / replugged).
  bool gone = false;              // Every submit fails with ENODEV.
  std::string driver = "usbhid";  // Kernel driver bound to interface 0.
  int detaches = 0, reattaches = 0, claims = 0, releases = 0;

  struct Urb {
    UMockdevIoctlData* data;
    int actual_length;
  };
  std::deque<Urb> done, flying, discarded;

  ~ScriptedRelay() {
    for (auto* q : {&done, &flying, &discarded}) {
      for (Urb& u : *q) umockdev_ioctl_data_unref(u.data);
    }
  }

  static gboolean Handle(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<ScriptedRelay*>(self)->OnIoctl(client);
  }

  gboolean OnIoctl(UMockdevIoctlClient* client) {
    std::lock_guard<std::mutex> lock(mutex);
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
        *reinterpret_cast<guint32*>(d->data) = USBDEVFS_CAP_BULK_CONTINUATION |
                                          USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                          USBDEVFS_CAP_REAP_AFTER_DISCONNECT;
        umockdev_ioctl_data_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
        (request == USBDEVFS_CLAIMINTERFACE ? claims : releases) += 1;
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      case USBDEVFS_GETDRIVER: {
        UMockdevIoctlData* d =
            umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_getdriver), nullptr);
        auto* g = reinterpret_cast<usbdevfs_getdriver*>(d->data);
        if (driver.empty()) {
          umockdev_ioctl_client_complete(client, -1, ENODATA);
        } else {
          std::snprintf(g->driver, sizeof(g->driver), "%s", driver.c_str());
          umockdev_ioctl_client_complete(client, 0, 0);
        }
        umockdev_ioctl_data_unref(d);
        return TRUE;
      }
      case USBDEVFS_IOCTL: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_ioctl), nullptr);
        const int code = reinterpret_cast<usbdevfs_ioctl*>(d->data)->ioctl_code;
        umockdev_ioctl_data_unref(d);
        if (code == int(USBDEVFS_DISCONNECT)) {
          driver.clear();
          ++detaches;
        } else if (code == int(USBDEVFS_CONNECT)) {
          driver = "usbhid";
          ++reattaches;
        } else {
          return FALSE;
        }
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_SUBMITURB:
        return Submit(client, arg);
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: {
        std::deque<Urb>* from = !discarded.empty() ? &discarded : !done.empty() ? &done : nullptr;
        if (from == nullptr) {
          umockdev_ioctl_client_complete(client, -1, EAGAIN);
          return TRUE;
        }
        Urb u = from->front();
        from->pop_front();
        auto* urb = reinterpret_cast<usbdevfs_urb*>(u.data->data);
        urb->status = from == &discarded ? -ENOENT : 0;
        urb->actual_length = from == &discarded ? 0 : u.actual_length;
        UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), nullptr);
        umockdev_ioctl_data_set_ptr(ptr, 0, u.data);
        umockdev_ioctl_client_complete(client, 0, 0);
        umockdev_ioctl_data_unref(ptr);
        umockdev_ioctl_data_unref(u.data);
        return TRUE;
      }
      case USBDEVFS_DISCARDURB: {
        const gulong addr = reinterpret_cast<gulong>(*reinterpret_cast<void**>(arg->data));
        for (auto it = flying.begin(); it != flying.end(); ++it) {
          if (it->data->client_addr == addr) {
            discarded.push_back(*it);
            flying.erase(it);
            umockdev_ioctl_client_complete(client, 0, 0);
            return TRUE;
          }
        }
        umockdev_ioctl_client_complete(client, -1, EINVAL);
        return TRUE;
      }
      default:
        return FALSE;
    }
  }

  gboolean Submit(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    if (gone || fail_submits > 0) {
      if (fail_submits > 0) --fail_submits;
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return TRUE;
    }
    UMockdevIoctlData* urb_data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
    auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
    if (urb->type != USBDEVFS_URB_TYPE_CONTROL || urb->buffer_length < 8) {
      umockdev_ioctl_data_unref(urb_data);
      return FALSE;
    }
    UMockdevIoctlData* buf = umockdev_ioctl_data_resolve(
        urb_data, G_STRUCT_OFFSET(usbdevfs_urb, buffer), urb->buffer_length, nullptr);
    uint8_t* b = reinterpret_cast<uint8_t*>(buf->data);
    const uint8_t request_type = b[0], request = b[1];
    const uint16_t value = uint16_t(b[2] | (b[3] << 8)), length = uint16_t(b[6] | (b[7] << 8));
    const bool in = (request_type & 0x80) != 0;
    transfers.push_back(Bytes(b, b + (in ? 8 : 8 + length)));
    int actual = length;
    if (request_type == 0x21 && request == 0x09 && value == 0x0300 && length == 8 && !stuck) {
      // SET_REPORT feature: [0xFF, n] closes relay n, [0xFD, n] opens it.
      const int n = b[9];
      if (n >= 1 && n <= 8 && b[8] == 0xFF) relays |= uint8_t(1u << (n - 1));
      if (n >= 1 && n <= 8 && b[8] == 0xFD) relays &= uint8_t(~(1u << (n - 1)));
    } else if (request_type == 0xA1 && request == 0x01 && value == 0x0300 && length >= 8) {
      // GET_REPORT feature: serial "THNSL" then the relay bits in byte 7.
      const uint8_t report[8] = {'T', 'H', 'N', 'S', 'L', 0, 0, relays};
      std::memcpy(b + 8, report, 8);
      actual = 8;
    }
    umockdev_ioctl_data_unref(buf);
    (hang ? flying : done).push_back({urb_data, actual});
    umockdev_ioctl_client_complete(client, 0, 0);
    return TRUE;
  }
};

Bytes SetReport(uint8_t command, uint8_t relay) {
  return {0x21, 0x09, 0x00, 0x03, 0x00, 0x00, 0x08, 0x00, command, relay, 0, 0, 0, 0, 0, 0};
}
const Bytes kGetReport = {0xA1, 0x01, 0x00, 0x03, 0x00, 0x00, 0x08, 0x00};

class UsbLaserUmockdevTest : public ::testing::Test {
 protected:
  void SetUp() override {
    testbed_ = umockdev_testbed_new();
    // True once the testbed exists ($UMOCKDEV_DIR) and the preload library is loaded.
    ASSERT_TRUE(umockdev_in_mock_environment()) << "libumockdev-preload.so is not preloaded";
    handler_ = umockdev_ioctl_base_new();
    g_signal_connect_after(handler_, "handle-ioctl", G_CALLBACK(&ScriptedRelay::Handle), &relay_);
  }
  void AddDevice(uint16_t vid, uint16_t pid) {
    GError* error = nullptr;
    // The ioctl handler first: libusb may open the node as soon as the device appears.
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, "/dev/bus/usb/001/001", handler_, &error))
        << (error ? error->message : "");
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, DeviceDescription(vid, pid).c_str(),
                                                 &error))
        << (error ? error->message : "");
  }
  void TearDown() override {
    if (handler_ != nullptr) g_object_unref(handler_);
    if (testbed_ != nullptr) g_object_unref(testbed_);
  }

  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  ScriptedRelay relay_;
};

TEST_F(UsbLaserUmockdevTest, HidRelaySendsTheExactReportsAndVerifiesState) {
  AddDevice(0x16c0, 0x05df);
  UsbLaserOptions options;
  ASSERT_TRUE(ParseUsbLaserSpec("hid-relay:16c0:05df:2", &options).ok());
  std::unique_ptr<UsbLaser> laser;
  Status s = OpenUsbLaser(options, &laser);
  ASSERT_TRUE(s.ok()) << s.message();
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    EXPECT_EQ(relay_.detaches, 1);  // usbhid was bound and had to let go.
    EXPECT_EQ(relay_.claims, 1);
  }
  s = laser->SetEmission(true);
  ASSERT_TRUE(s.ok()) << s.message();
  s = laser->SetEmission(false);
  ASSERT_TRUE(s.ok()) << s.message();
  s = laser->SetEmission(true);
  ASSERT_TRUE(s.ok()) << s.message();
  bool on = false;
  ASSERT_TRUE(laser->ReadEmission(&on).ok());
  EXPECT_TRUE(on);
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    EXPECT_EQ(relay_.relays, 0x02);
    const std::vector<Bytes> expected = {SetReport(0xFF, 2), kGetReport, SetReport(0xFD, 2),
                                         kGetReport,         SetReport(0xFF, 2), kGetReport,
                                         kGetReport};
    EXPECT_EQ(relay_.transfers, expected);
  }
  laser.reset();
  std::lock_guard<std::mutex> lock(relay_.mutex);
  EXPECT_EQ(relay_.releases, 1);
  EXPECT_EQ(relay_.reattaches, 1);  // usbhid gets the interface back.
  EXPECT_EQ(relay_.driver, "usbhid");
}

TEST_F(UsbLaserUmockdevTest, VendorProtocolSendsConfiguredControlTransfers) {
  AddDevice(0x1234, 0x5678);
  UsbLaserOptions options;
  ASSERT_TRUE(ParseUsbLaserSpec("vendor:1234:5678:on=40,01,0001,0000,aa,55:off=41,02,0000,00ff",
                                &options)
                  .ok());
  std::unique_ptr<UsbLaser> laser;
  Status s = OpenUsbLaser(options, &laser);
  ASSERT_TRUE(s.ok()) << s.message();
  ASSERT_TRUE(laser->SetEmission(true).ok());
  ASSERT_TRUE(laser->SetEmission(false).ok());
  bool on;
  EXPECT_FALSE(laser->ReadEmission(&on).ok());
  std::lock_guard<std::mutex> lock(relay_.mutex);
  const std::vector<Bytes> expected = {{0x40, 0x01, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0xaa, 0x55},
                                       {0x41, 0x02, 0x00, 0x00, 0xff, 0x00, 0x00, 0x00}};
  EXPECT_EQ(relay_.transfers, expected);
}

TEST_F(UsbLaserUmockdevTest, ReconnectsOnceAfterNoDevice) {
  AddDevice(0x16c0, 0x05df);
  UsbLaserOptions options;
  std::unique_ptr<UsbLaser> laser;
  ASSERT_TRUE(OpenUsbLaser(options, &laser).ok());
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    relay_.fail_submits = 1;
  }
  Status s = laser->SetEmission(true);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(laser->reconnects(), 1);
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    EXPECT_EQ(relay_.relays, 0x01);
    EXPECT_EQ(relay_.claims, 2);
    EXPECT_EQ(relay_.transfers, (std::vector<Bytes>{SetReport(0xFF, 1), kGetReport}));
    relay_.gone = true;  // Unplugged for good.
  }
  s = laser->SetEmission(false);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("16c0:05df"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("LIBUSB_ERROR_NO_DEVICE"), std::string::npos) << s.message();
}

TEST_F(UsbLaserUmockdevTest, TimeoutAndStuckRelayAreErrors) {
  AddDevice(0x16c0, 0x05df);
  UsbLaserOptions options;
  ASSERT_TRUE(ParseUsbLaserSpec("hid-relay:16c0:05df:1:timeout_ms=100", &options).ok());
  std::unique_ptr<UsbLaser> laser;
  ASSERT_TRUE(OpenUsbLaser(options, &laser).ok());
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    relay_.stuck = true;
  }
  Status s = laser->SetEmission(true);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("relay 1 reads off after switching it on"), std::string::npos)
      << s.message();
  {
    std::lock_guard<std::mutex> lock(relay_.mutex);
    relay_.hang = true;
  }
  s = laser->SetEmission(true);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("LIBUSB_ERROR_TIMEOUT"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("after 100 ms"), std::string::npos) << s.message();
}

TEST_F(UsbLaserUmockdevTest, AbsentDeviceNamesVidPid) {
  AddDevice(0x16c0, 0x05df);
  UsbLaserOptions options;
  ASSERT_TRUE(ParseUsbLaserSpec("hid-relay:abcd:0001", &options).ok());
  std::unique_ptr<UsbLaser> laser;
  const Status s = OpenUsbLaser(options, &laser);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("abcd:0001"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("no such USB device"), std::string::npos) << s.message();
  EXPECT_EQ(laser, nullptr);
}

TEST_F(UsbLaserUmockdevTest, OpenFailureNamesVidPid) {
  AddDevice(0x16c0, 0x05df);
  // The device is enumerated but its usbfs node cannot be opened (replaced by a directory:
  // tests run as root, so permissions cannot make open() fail).
  gchar* root = umockdev_testbed_get_root_dir(testbed_);
  const std::string node = std::string(root) + "/dev/bus/usb/001/001";
  g_free(root);
  ASSERT_EQ(unlink(node.c_str()), 0) << node;
  ASSERT_EQ(mkdir(node.c_str(), 0755), 0) << node;
  UsbLaserOptions options;
  std::unique_ptr<UsbLaser> laser;
  const Status s = OpenUsbLaser(options, &laser);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("16c0:05df: cannot open: LIBUSB_ERROR_"), std::string::npos)
      << s.message();
  std::printf("open failure reads: %s\n", s.message().c_str());
  rmdir(node.c_str());
}

TEST(UsbLaserSpecTest, ParsesAndRejectsSpecs) {
  UsbLaserOptions o;
  ASSERT_TRUE(ParseUsbLaserSpec("hid-relay", &o).ok());
  EXPECT_EQ(o.protocol, UsbLaserOptions::Protocol::kHidRelay);
  EXPECT_EQ(o.vendor_id, 0x16c0);
  EXPECT_EQ(o.product_id, 0x05df);
  EXPECT_EQ(o.relay_index, 1);
  ASSERT_TRUE(ParseUsbLaserSpec("hid-relay:16c0:05DF:4:interface=1", &o).ok());
  EXPECT_EQ(o.relay_index, 4);
  EXPECT_EQ(o.interface_number, 1);
  ASSERT_TRUE(ParseUsbLaserSpec("vendor:1234:5678:on=40,01,0001,0000:off=40,01,0000,0000", &o).ok());
  EXPECT_EQ(o.protocol, UsbLaserOptions::Protocol::kVendor);
  EXPECT_EQ(o.on.value, 1);
  EXPECT_EQ(o.off.value, 0);
  EXPECT_TRUE(o.on.data.empty());
  for (const char* bad :
       {"serial:1", "hid-relay:16c0", "hid-relay:16c0:05df:9", "hid-relay:xyz:05df",
        "hid-relay:16c0:05df:1:on=40,1,0,0", "vendor:1234:5678:on=40,01,0001,0000",
        "vendor:1234:5678:on=c0,01,0001,0000:off=40,01,0000,0000",
        "vendor:1234:5678:on=40,01,10001,0000:off=40,01,0000,0000",
        "vendor:1234:5678:on=40,01,0001,0000,100:off=40,01,0000,0000",
        "hid-relay:16c0:05df:1:timeout_ms=0", "hid-relay:16c0:05df:1:speed=3"}) {
    const Status s = ParseUsbLaserSpec(bad, &o);
    EXPECT_FALSE(s.ok()) << bad;
    EXPECT_NE(s.message().find(bad), std::string::npos) << s.message();
  }
}

}  // namespace
}  // namespace thinslab

int main(int argc, char** argv) {
  // Re-execute under the umockdev preload library (see the file comment).
  const char* preload = getenv("LD_PRELOAD");
  if (preload == nullptr || std::strstr(preload, "libumockdev-preload") == nullptr) {
    std::string value = "libumockdev-preload.so.0";
    if (preload != nullptr && preload[0] != '\0') value += std::string(":") + preload;
    setenv("LD_PRELOAD", value.c_str(), 1);
    const char* asan = getenv("ASAN_OPTIONS");
    std::string asan_options = asan != nullptr ? asan : "";
    asan_options += std::string(asan_options.empty() ? "" : ":") + "verify_asan_link_order=0";
    setenv("ASAN_OPTIONS", asan_options.c_str(), 1);
    execv("/proc/self/exe", argv);
    std::perror("usb_laser_test: re-executing under libumockdev-preload failed");
    return 1;
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
