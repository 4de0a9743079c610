// SPDX-License-Identifier: Apache-2.0
// V4l2Camera against a simulated kernel driver (FakeV4l2Device): the same ioctl structures and
// errno conventions as videodev2.h, a real buffer queue, controls that round, and failure modes.
#include "thinslab/drivers/v4l2_camera.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <set>

namespace thinslab {
namespace {

constexpr int kFd = 42;

class FakeV4l2Device : public V4l2Io {
 public:
  std::string path = "/dev/video7";
  std::vector<uint32_t> formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y12};
  uint32_t width = 64, height = 48, stride_pad = 16;  // Bytes of padding per row.
  uint32_t pixelformat = V4L2_PIX_FMT_YUYV;
  uint32_t caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  // Exposure control: units of 100 us, step 3, range [1, 3001], auto on at start.
  int exposure = 100, exposure_auto = V4L2_EXPOSURE_APERTURE_PRIORITY;
  int frames_to_deliver = 1 << 30;  // Stops delivering after this many frames.
  std::set<uint32_t> skip_sequences;  // Sequence numbers the "sensor" drops.
  std::set<uint32_t> error_sequences;  // Delivered with V4L2_BUF_FLAG_ERROR.
  bool mmap_fails = false;

  // Bookkeeping the tests inspect.
  bool open = false, streaming = false;
  int mapped = 0;
  std::vector<std::vector<uint8_t>> buffers;
  std::deque<uint32_t> queued;
  uint32_t sequence = 0;
  std::vector<int> exposure_at_frame;

  static uint16_t Pixel(uint32_t x, uint32_t y, uint32_t seq) { return (x * 7 + y * 13 + seq) & 0xfff; }
  uint32_t BytesPerPixel() const { return pixelformat == V4L2_PIX_FMT_GREY ? 1 : 2; }
  uint32_t Stride() const { return width * BytesPerPixel() + stride_pad; }

  int Open(const std::string& p, int flags) override {
    EXPECT_TRUE(flags & O_NONBLOCK);
    if (p != path) {
      errno = ENOENT;
      return -1;
    }
    open = true;
    return kFd;
  }
  int Close(int fd) override {
    EXPECT_EQ(fd, kFd);
    open = false;
    return 0;
  }
  void* Mmap(size_t length, int, int, int fd, off_t offset) override {
    EXPECT_EQ(fd, kFd);
    const size_t index = static_cast<size_t>(offset) / 4096;
    if (mmap_fails || index >= buffers.size() || length != buffers[index].size()) {
      errno = ENOMEM;
      return MAP_FAILED;
    }
    ++mapped;
    return buffers[index].data();
  }
  int Munmap(void*, size_t) override {
    --mapped;
    return 0;
  }
  int Poll(int fd, short, short* revents, int) override {  // NOLINT
    EXPECT_EQ(fd, kFd);
    *revents = 0;
    if (!streaming || queued.empty() || frames_to_deliver <= 0) return 0;  // Timed out.
    *revents = POLLIN;
    return 1;
  }
  int Fail(int e) {
    errno = e;
    return -1;
  }
  int Ioctl(int fd, unsigned long request, void* arg) override {  // NOLINT
    if (fd != kFd) return Fail(EBADF);
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* cap = static_cast<v4l2_capability*>(arg);
        std::memset(cap, 0, sizeof(*cap));
        std::strcpy(reinterpret_cast<char*>(cap->card), "Fake Mono");
        std::strcpy(reinterpret_cast<char*>(cap->bus_info), "usb-0000:00:14.0-1");
        cap->capabilities = caps | V4L2_CAP_DEVICE_CAPS;
        cap->device_caps = caps;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* d = static_cast<v4l2_fmtdesc*>(arg);
        if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= formats.size()) return Fail(EINVAL);
        d->pixelformat = formats[d->index];
        return 0;
      }
      case VIDIOC_G_FMT:
      case VIDIOC_S_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        if (request == VIDIOC_S_FMT) {
          if (streaming) return Fail(EBUSY);
          // Like real drivers: unknown formats fall back to the first, sizes clamp to 8..640.
          const bool known = std::find(formats.begin(), formats.end(), f->fmt.pix.pixelformat) !=
                             formats.end();
          pixelformat = known ? f->fmt.pix.pixelformat : formats[0];
          width = std::clamp<uint32_t>(f->fmt.pix.width & ~7u, 8, 640);
          height = std::clamp<uint32_t>(f->fmt.pix.height, 8, 480);
        }
        f->fmt.pix.width = width;
        f->fmt.pix.height = height;
        f->fmt.pix.pixelformat = pixelformat;
        f->fmt.pix.bytesperline = Stride();
        f->fmt.pix.sizeimage = Stride() * height;
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        if (r->memory != V4L2_MEMORY_MMAP) return Fail(EINVAL);
        if (mapped > 0 && r->count > 0) return Fail(EBUSY);
        r->count = std::min<uint32_t>(r->count, 3);  // The driver grants at most 3.
        buffers.assign(r->count, std::vector<uint8_t>(Stride() * height + 100));
        queued.clear();
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= buffers.size()) return Fail(EINVAL);
        b->length = buffers[b->index].size();
        b->m.offset = b->index * 4096;
        return 0;
      }
      case VIDIOC_QBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= buffers.size()) return Fail(EINVAL);
        if (std::find(queued.begin(), queued.end(), b->index) != queued.end()) return Fail(EINVAL);
        queued.push_back(b->index);
        return 0;
      }
      case VIDIOC_DQBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (!streaming || queued.empty() || frames_to_deliver <= 0) return Fail(EAGAIN);
        while (skip_sequences.count(sequence) != 0) ++sequence;
        const uint32_t index = queued.front();
        queued.pop_front();
        --frames_to_deliver;
        std::vector<uint8_t>& mem = buffers[index];
        for (uint32_t y = 0; y < height; ++y) {
          for (uint32_t x = 0; x < width; ++x) {
            const uint16_t v = Pixel(x, y, sequence);
            uint8_t* p = &mem[y * Stride() + x * BytesPerPixel()];
            if (BytesPerPixel() == 1) {
              p[0] = v & 0xff;
            } else {
              p[0] = v & 0xff;
              p[1] = v >> 8;
            }
          }
        }
        b->index = index;
        b->bytesused = Stride() * height;
        b->sequence = sequence;
        b->flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC |
                   (error_sequences.count(sequence) ? V4L2_BUF_FLAG_ERROR : 0);
        b->timestamp.tv_sec = 1000 + sequence;
        exposure_at_frame.push_back(exposure);
        ++sequence;
        return 0;
      }
      case VIDIOC_STREAMON:
        streaming = true;
        return 0;
      case VIDIOC_STREAMOFF:
        streaming = false;
        return 0;
      case VIDIOC_QUERYCTRL: {
        auto* q = static_cast<v4l2_queryctrl*>(arg);
        if (q->id != V4L2_CID_EXPOSURE_ABSOLUTE) return Fail(EINVAL);
        q->minimum = 1;
        q->maximum = 3001;
        q->step = 3;
        return 0;
      }
      case VIDIOC_S_CTRL:
      case VIDIOC_G_CTRL: {
        auto* c = static_cast<v4l2_control*>(arg);
        int* target = c->id == V4L2_CID_EXPOSURE_ABSOLUTE ? &exposure
                      : c->id == V4L2_CID_EXPOSURE_AUTO   ? &exposure_auto
                                                          : nullptr;
        if (target == nullptr) return Fail(EINVAL);
        if (request == VIDIOC_G_CTRL) {
          c->value = *target;
          return 0;
        }
        if (c->id == V4L2_CID_EXPOSURE_ABSOLUTE) {
          // In auto mode the sensor ignores manual exposure, as UVC cameras do.
          if (exposure_auto != V4L2_EXPOSURE_MANUAL) return Fail(EBUSY);
          // The firmware rounds up to the next point of its 3-unit grid.
          *target = std::clamp(1 + 3 * ((c->value - 1) / 3 + 1), 1, 3001);
        } else {
          *target = c->value;
        }
        return 0;
      }
      default:
        return Fail(ENOTTY);
    }
  }
};

V4l2CameraOptions FakeOptions(const std::shared_ptr<FakeV4l2Device>& dev) {
  V4l2CameraOptions o;
  o.device = dev->path;
  o.io = dev;
  o.timeout_s = 0.05;
  return o;
}

TEST(V4l2CameraTest, NegotiatesDeepestMonoFormatAndStreams) {
  auto dev = std::make_shared<FakeV4l2Device>();
  V4l2CameraOptions options = FakeOptions(dev);
  options.width_px = 40;
  options.height_px = 30;
  std::unique_ptr<V4l2Camera> cam;
  const Status s = OpenV4l2Camera(options, &cam);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(cam->fourcc(), "Y12 ");  // Y12 preferred over GREY; YUYV ignored.
  EXPECT_EQ(cam->info().bit_depth, 12);
  EXPECT_EQ(cam->info().saturation_dn, 4095);
  EXPECT_EQ(cam->info().width_px, 40);
  EXPECT_EQ(cam->info().height_px, 30);
  EXPECT_EQ(cam->info().model, "v4l2");
  EXPECT_NE(cam->info().serial.find("Fake Mono"), std::string::npos);
  EXPECT_TRUE(dev->streaming);
  EXPECT_EQ(dev->mapped, 3);            // The driver granted 3 of the 4 buffers asked for.
  EXPECT_EQ(dev->queued.size(), 3u);

  dev->skip_sequences = {3, 4};
  dev->error_sequences = {6};
  std::vector<uint64_t> ids;
  for (int i = 0; i < 8; ++i) {
    CapturedFrame frame;
    const Status c = cam->Capture(&frame);
    ASSERT_TRUE(c.ok()) << c.message();
    ASSERT_EQ(frame.raw_dn.width(), 40);
    ASSERT_TRUE(frame.frame_id.has_value());
    ids.push_back(*frame.frame_id);
    // Every pixel, across the padded stride and little-endian 16-bit words.
    for (int y = 0; y < 30; y += 7) {
      for (int x = 0; x < 40; x += 3) {
        ASSERT_EQ(frame.raw_dn.at(x, y), FakeV4l2Device::Pixel(x, y, uint32_t(*frame.frame_id)));
      }
    }
    EXPECT_EQ(frame.timestamp_utc.size(), 27u);
    EXPECT_EQ(frame.timestamp_utc.back(), 'Z');
    // The driver's timestamp, as is (the fake stamps 1000 + sequence s).
    EXPECT_EQ(frame.device_timestamp_ns, (1000 + *frame.frame_id) * 1000000000ull);
    EXPECT_EQ(dev->queued.size(), 3u);  // Buffer handed back after every frame.
  }
  EXPECT_EQ(ids, (std::vector<uint64_t>{0, 1, 2, 5, 7, 8, 9, 10}));
  const auto stats = cam->statistics();
  EXPECT_EQ(stats.at("completed_buffers"), 8);
  EXPECT_EQ(stats.at("failed_buffers"), 1);
  EXPECT_EQ(stats.at("dropped_frames"), 3);  // 3, 4 never came; 6 came corrupt.
  cam.reset();
  EXPECT_FALSE(dev->open);
  EXPECT_FALSE(dev->streaming);
  EXPECT_EQ(dev->mapped, 0);
}

TEST(V4l2CameraTest, ExposureIsManualRoundedAndReadBack) {
  auto dev = std::make_shared<FakeV4l2Device>();
  std::unique_ptr<V4l2Camera> cam;
  ASSERT_TRUE(OpenV4l2Camera(FakeOptions(dev), &cam).ok());
  double applied = 0;
  const Status s = cam->SetExposure(12345, &applied);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(dev->exposure_auto, V4L2_EXPOSURE_MANUAL);
  // 123.45 units -> our rounding to the step grid gives 124, the device's firmware makes 127:
  // the value reported is what the device says, not what was asked for.
  EXPECT_EQ(dev->exposure, 127);
  EXPECT_EQ(applied, 12700);
  CapturedFrame frame;
  ASSERT_TRUE(cam->Capture(&frame).ok());
  EXPECT_EQ(frame.exposure_time_us, 12700);
  EXPECT_FALSE(cam->SetExposure(400e3, &applied).ok());  // Above 3001 units.
  const Status neg = cam->SetExposure(-1, &applied);
  ASSERT_FALSE(neg.ok());
  EXPECT_NE(neg.message().find("/dev/video7"), std::string::npos);
}

TEST(V4l2CameraTest, DeviceThatStopsDeliveringTimesOutNamingTheDevice) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->frames_to_deliver = 2;
  std::unique_ptr<V4l2Camera> cam;
  ASSERT_TRUE(OpenV4l2Camera(FakeOptions(dev), &cam).ok());
  CapturedFrame frame;
  ASSERT_TRUE(cam->Capture(&frame).ok());
  ASSERT_TRUE(cam->Capture(&frame).ok());
  const Status s = cam->Capture(&frame);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("/dev/video7"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("timeout"), std::string::npos) << s.message();
  EXPECT_EQ(cam->statistics().at("timeouts"), 1);
}

TEST(V4l2CameraTest, BadDevicesAndFormatsGiveClearErrors) {
  auto dev = std::make_shared<FakeV4l2Device>();
  std::unique_ptr<V4l2Camera> cam;
  V4l2CameraOptions options = FakeOptions(dev);
  options.device = "/dev/video9";
  Status s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("/dev/video9"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("No such file"), std::string::npos) << s.message();
  EXPECT_FALSE(dev->open);

  options = FakeOptions(dev);
  options.pixel_format = "RGB3";
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("unsupported pixel format \"RGB3\""), std::string::npos);
  EXPECT_NE(s.message().find("YUYV, GREY, Y12 "), std::string::npos) << s.message();
  EXPECT_FALSE(dev->open);  // Closed again on every error path.

  options.pixel_format = "Y16";
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("does not offer pixel format Y16"), std::string::npos) << s.message();

  options.pixel_format = "GREY";
  options.width_px = 41;  // The driver rounds widths to multiples of 8.
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("the driver set 40x"), std::string::npos) << s.message();

  dev->formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  options = FakeOptions(dev);
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("offers no monochrome format"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("MJPG"), std::string::npos) << s.message();

  dev->formats = {V4L2_PIX_FMT_GREY};
  dev->caps = V4L2_CAP_VIDEO_OUTPUT;
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("not a single-planar video capture device"), std::string::npos);

  dev->caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  dev->mmap_fails = true;
  s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("mmap of buffer 0"), std::string::npos) << s.message();
  EXPECT_FALSE(dev->open);

  dev->mmap_fails = false;
  s = OpenV4l2Camera(options, &cam);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(cam->fourcc(), "GREY");
  CapturedFrame frame;
  ASSERT_TRUE(cam->Capture(&frame).ok());
  EXPECT_EQ(frame.raw_dn.at(5, 3), FakeV4l2Device::Pixel(5, 3, 0) & 0xff);
}

TEST(V4l2CameraTest, RealSyscallsOnAMissingDeviceNameThePath) {
  V4l2CameraOptions options;
  options.device = "/nonexistent/video0";
  std::unique_ptr<V4l2Camera> cam;
  const Status s = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("/nonexistent/video0"), std::string::npos) << s.message();
  // /dev/null opens but is not a V4L2 device.
  options.device = "/dev/null";
  const Status n = OpenV4l2Camera(options, &cam);
  ASSERT_FALSE(n.ok());
  EXPECT_NE(n.message().find("/dev/null"), std::string::npos) << n.message();
  EXPECT_NE(n.message().find("VIDIOC_QUERYCAP"), std::string::npos) << n.message();
}

}  // namespace
}  // namespace thinslab
