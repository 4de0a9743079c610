// SPDX-License-Identifier: Apache-2.0
// AravisCamera end to end against Aravis's own GigE Vision fake camera (ArvGvFakeCamera),
// started in this process on 127.0.0.1 and opened by IP through the real GigE Vision stack
// (GVCP control, GVSP stream) over loopback. Its frames come from a callback: test patterns,
// or the simulated shadow-map rig, so a whole capture session runs through the stack. No
// discovery broadcast is ever sent; all traffic stays on 127.0.0.1.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <cmath>
#include <iomanip>
#include <cstdlib>
#include <sstream>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "thinslab/acquire/capture_with_retries.h"
#include "thinslab/acquire/session_journal.h"
#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/aravis_camera.h"
#include "thinslab/drivers/aravis_fake_camera.h"
#include "thinslab/sim/contamination_pattern.h"
#include "thinslab/sim/shadow_map_rig.h"
#include <opencv2/imgcodecs.hpp>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/xvfb_server.h"

namespace thinslab {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;

// A pattern that differs per frame and uses the high byte, so byte order and frame mix-ups show.
Image TestPattern(int width, int height, uint64_t index, double max_dn) {
  Image image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double v = std::fmod(257.0 * x + 31.0 * y + 1009.0 * static_cast<double>(index), max_dn + 1);
      image.at(x, y) = static_cast<float>(v);
    }
  }
  return image;
}

// Serves TestPattern and remembers every image it handed to the fake.
class PatternSource {
 public:
  explicit PatternSource(double max_dn) : max_dn_(max_dn) {}
  AravisFakeFrameSource callback() {
    return [this](const AravisFakeFrameRequest& request, Image* raw_dn) {
      *raw_dn = TestPattern(request.width_px, request.height_px, request.index, max_dn_);
      std::lock_guard<std::mutex> lock(mutex_);
      requests_.push_back(request);
      images_.push_back(*raw_dn);
      return Status::Ok();
    };
  }
  Image image(size_t i) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return images_.at(i);
  }
  AravisFakeFrameRequest request(size_t i) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return requests_.at(i);
  }
  size_t count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return images_.size();
  }

 private:
  double max_dn_;
  mutable std::mutex mutex_;
  std::vector<AravisFakeFrameRequest> requests_;
  std::vector<Image> images_;
};

AravisCameraOptions CameraOptions(const AravisFakeCamera& fake) {
  AravisCameraOptions options;
  options.address = fake.address();
  options.width_px = kWidth;
  options.height_px = kHeight;
  options.frame_timeout_s = 0.5;
  options.connect_timeout_s = 0.5;
  return options;
}

bool SameImage(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height()) return false;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      if (a.at(x, y) != b.at(x, y)) return false;
    }
  }
  return true;
}

double Mean(const Image& image) {
  double sum = 0;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) sum += image.at(x, y);
  }
  return sum / (static_cast<double>(image.width()) * image.height());
}

double Stat(const std::map<std::string, double>& stats, const std::string& key) {
  const auto it = stats.find(key);
  EXPECT_NE(it, stats.end()) << "statistics() lacks \"" << key << "\"";
  return it == stats.end() ? -1 : it->second;
}

// The driver's own counters appear once they first count.
double StatOrZero(const std::map<std::string, double>& stats, const std::string& key) {
  const auto it = stats.find(key);
  return it == stats.end() ? 0 : it->second;
}

// A private X server for the SDL window of `--display 0`, made the process's DISPLAY.
void StartXvfbForTheWindow(int width, int height, XvfbServer* xvfb) {
  std::string error;
  ASSERT_TRUE(xvfb->Start(width, height, &error)) << error;
  setenv("DISPLAY", xvfb->display().c_str(), 1);
#ifdef __SANITIZE_ADDRESS__
  setenv("SDL_RENDER_DRIVER", "software", 1);  // No Mesa GL under LeakSanitizer (pattern_window_test).
  setenv("SDL_FRAMEBUFFER_ACCELERATION", "0", 1);
#endif
}

TEST(AravisFakeCamera, OpensByIpAndDeliversTheInjectedMono16ImageExactly) {
  PatternSource source(65535);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> camera;
  const Status open = OpenAravisCamera(CameraOptions(*fake), &camera);
  ASSERT_TRUE(open.ok()) << open.message();

  EXPECT_EQ(camera->info().width_px, kWidth);
  EXPECT_EQ(camera->info().height_px, kHeight);
  EXPECT_EQ(camera->info().model, "aravis");
  EXPECT_EQ(camera->info().serial, "TSFAKE01");
  EXPECT_EQ(camera->info().bit_depth, 16);
  EXPECT_EQ(camera->info().saturation_dn, 65535);
  EXPECT_NE(camera->device_name().find("127.0.0.1"), std::string::npos);
  // Packet size read back from the camera (the fake's default is 1400 bytes).
  EXPECT_GT(camera->packet_size_bytes(), 0);

  for (int i = 0; i < 3; ++i) {
    CapturedFrame frame;
    const Status status = camera->Capture(&frame);
    ASSERT_TRUE(status.ok()) << status.message();
    ASSERT_EQ(source.count(), static_cast<size_t>(i + 1));
    EXPECT_TRUE(SameImage(frame.raw_dn, source.image(i))) << "frame " << i;
    EXPECT_EQ(frame.timestamp_utc.size(), 24u) << frame.timestamp_utc;  // 2026-11-23T18:00:00.000Z
  }
  const auto stats = camera->statistics();
  EXPECT_EQ(Stat(stats, "completed_buffers"), 3);
  EXPECT_EQ(Stat(stats, "failed_buffers"), 0);
  EXPECT_EQ(Stat(stats, "missing_packets"), 0);
  EXPECT_EQ(Stat(stats, "timeouts"), 0);
  EXPECT_EQ(Stat(stats, "packet_size_bytes"), camera->packet_size_bytes());
  EXPECT_EQ(fake->source_errors(), 0u) << fake->last_source_error();
}

TEST(AravisFakeCamera, Mono8AndAnExplicitPacketSizeAreReadBack) {
  PatternSource source(255);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.pixel_format = "Mono8";
  options.packet_size = 4000;  // Loopback carries it; a real link needs jumbo frames for this.
  std::unique_ptr<AravisCamera> camera;
  const Status open = OpenAravisCamera(options, &camera);
  ASSERT_TRUE(open.ok()) << open.message();
  EXPECT_EQ(camera->info().bit_depth, 8);
  EXPECT_EQ(camera->packet_size_bytes(), 4000);
  CapturedFrame frame;
  const Status status = camera->Capture(&frame);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(source.request(0).pixel_format, "Mono8");
  EXPECT_TRUE(SameImage(frame.raw_dn, source.image(0)));
}

TEST(AravisFakeCamera, UnofferedOrUnreadablePixelFormatsAreRefusedByName) {
  PatternSource source(65535);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> probe;
  ASSERT_TRUE(OpenAravisCamera(CameraOptions(*fake), &probe).ok());
  const std::vector<std::string> offered = probe->offered_pixel_formats();
  probe.reset();
  const bool offers_mono12 = std::find(offered.begin(), offered.end(), "Mono12") != offered.end();

  AravisCameraOptions options = CameraOptions(*fake);
  options.pixel_format = "Mono12";
  std::unique_ptr<AravisCamera> camera;
  const Status mono12 = OpenAravisCamera(options, &camera);
  if (offers_mono12) {
    ASSERT_TRUE(mono12.ok()) << mono12.message();
    EXPECT_EQ(camera->info().bit_depth, 12);
    camera.reset();
  } else {
    // Aravis 0.8.26's fake offers Mono8, Mono16, RGB8 and Bayer*8, not Mono12.
    ASSERT_FALSE(mono12.ok());
    EXPECT_NE(mono12.message().find("127.0.0.1"), std::string::npos) << mono12.message();
    EXPECT_NE(mono12.message().find("'Mono12' is not offered"), std::string::npos) << mono12.message();
    EXPECT_NE(mono12.message().find("Mono8"), std::string::npos) << mono12.message();
    EXPECT_NE(mono12.message().find("Mono16"), std::string::npos) << mono12.message();
  }

  options.pixel_format = "RGB8";  // Offered, but not a single-channel format.
  const Status rgb = OpenAravisCamera(options, &camera);
  ASSERT_FALSE(rgb.ok());
  EXPECT_NE(rgb.message().find("'RGB8' is offered but thinslab reads only"), std::string::npos) << rgb.message();
}

// `thinslab acquire --camera aravis:127.0.0.1` (a child process talking to this process's fake
// camera over loopback): --pixel-format, --gain-db and --packet-size reach the camera, the values
// it applied are recorded in the manifest, and ones it refuses fail naming the camera before
// OUTPUT is touched. The bracket kind needs a display: a private Xvfb.
// (The fake accepts any gain, so an out-of-range gain is not tested here.)
TEST(AravisFakeCamera, AcquireCommandSetsPixelFormatGainAndPacketSize) {
  // A still scene (the synchronisation settles on two agreeing frames); requests are recorded.
  std::mutex mutex;
  std::vector<AravisFakeFrameRequest> requests;
  AravisFakeFrameSource still = [&](const AravisFakeFrameRequest& request, Image* raw_dn) {
    *raw_dn = TestPattern(request.width_px, request.height_px, 0, 255);
    std::lock_guard<std::mutex> lock(mutex);
    requests.push_back(request);
    return Status::Ok();
  };
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), still, &fake).ok());
  TempDir dir;
  const std::string camera = " --camera aravis:" + fake->address() + " --camera-timeout-s 1 --quiet";
  struct Refusal {
    std::string options, named;
  };
  for (const Refusal& r : {Refusal{"--pixel-format Mono12", "'Mono12' is not offered"},
                           Refusal{"--packet-size 100", "packet_size = 100"}}) {
    const RunResult refused = RunThinslab("acquire bracket" + camera + " " + r.options + " " + dir / "refused");
    EXPECT_NE(refused.exit_code, 0) << refused.output;
    EXPECT_NE(refused.output.find(r.named), std::string::npos) << refused.output;
    EXPECT_NE(refused.output.find("aravis:" + fake->address()), std::string::npos) << refused.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "refused")) << r.options;
  }

  XvfbServer xvfb;
  ASSERT_NO_FATAL_FAILURE(StartXvfbForTheWindow(320, 240, &xvfb));
  // The operator confirms the sample state (none: nothing in the light path) with Enter.
  const std::string enter = dir / "enter.txt";
  ASSERT_TRUE(WriteFileAtomically(enter, "\n\n").ok());
  const RunResult ok = RunThinslab("acquire bracket" + camera +
                                   " --display 0 --pixel-format Mono8 --gain-db 2 --packet-size 1400"
                                   " --exposures-us 1000,2000 --capture-dark false " + dir / "s",
                                   enter);
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  const CameraInfo& cam0 = session.rig.cameras.at(0);
  EXPECT_EQ(cam0.bit_depth, 8);
  EXPECT_EQ(cam0.saturation_dn, 255);
  EXPECT_EQ(cam0.stream_statistics.at("packet_size_bytes"), 1400);
  ASSERT_EQ(session.frames.size(), 2u);
  for (const FrameRecord& f : session.frames) EXPECT_EQ(f.gain_db, 2) << "frame " << f.index;
  {
    std::lock_guard<std::mutex> lock(mutex);
    ASSERT_FALSE(requests.empty());
    EXPECT_EQ(requests.back().pixel_format, "Mono8");
    EXPECT_EQ(requests.back().gain, 2);
  }
  // A resume with another pixel format is another plan: refused.
  const RunResult other = RunThinslab("acquire bracket" + camera +
                                      " --display 0 --pixel-format Mono16 --gain-db 2 --packet-size 1400"
                                      " --exposures-us 1000,2000 --capture-dark false --resume " + dir / "s",
                                      enter);
  EXPECT_NE(other.exit_code, 0) << other.output;
  EXPECT_NE(other.output.find("acquisition.plan"), std::string::npos) << other.output;
}

TEST(AravisFakeCamera, ExposureIsReadBackAsTheCameraRoundedIt) {
  PatternSource source(65535);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(CameraOptions(*fake), &camera).ok());
  double applied_us = 0;
  ASSERT_TRUE(camera->SetExposure(12345.6, &applied_us).ok());
  EXPECT_EQ(applied_us, 12345);  // The fake keeps whole microseconds.
  CapturedFrame frame;
  ASSERT_TRUE(camera->Capture(&frame).ok());
  EXPECT_EQ(frame.exposure_time_us, 12345);
  EXPECT_EQ(source.request(0).exposure_time_us, 12345);  // What the camera exposed with.

  const Status too_long = camera->SetExposure(1e9, &applied_us);
  ASSERT_FALSE(too_long.ok());
  EXPECT_NE(too_long.message().find("127.0.0.1"), std::string::npos) << too_long.message();
  EXPECT_NE(too_long.message().find("outside the camera's range"), std::string::npos) << too_long.message();
}

TEST(AravisFakeCamera, FrameIdsIncreaseAcrossTheSixteenBitWrap) {
  PatternSource source(65535);
  AravisFakeCameraOptions fake_options;
  fake_options.frame_period_us = 2000;
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(fake_options, source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(CameraOptions(*fake), &camera).ok());
  // The fake's GVSP block ids start near 65400, so 150 frames cross the 16-bit wrap.
  uint64_t previous = 0;
  for (int i = 0; i < 150; ++i) {
    CapturedFrame frame;
    const Status status = camera->Capture(&frame);
    ASSERT_TRUE(status.ok()) << "frame " << i << ": " << status.message();
    ASSERT_TRUE(frame.frame_id.has_value()) << "frame " << i;
    if (i > 0) {
      ASSERT_EQ(*frame.frame_id, previous + 1) << "frame " << i;
    }
    previous = *frame.frame_id;
  }
  EXPECT_GT(previous, 0xffffu);
}

// A whole shadow-map session (acquire/shadow_map_session, unchanged) through the GigE stack:
// the simulated rig renders each frame inside the fake camera's fill callback, at the
// exposure the session set over GVCP, in the light state the session's projector and sample
// changer chose.
TEST(AravisFakeCamera, ShadowMapSessionRunsThroughTheGigEStackAndLogsStreamStatistics) {
  SimShadowMapOptions rig_options;
  rig_options.camera_width_px = kWidth;
  rig_options.camera_height_px = kHeight;
  rig_options.render_supersample = 1;
  rig_options.monte_carlo.num_photons = 20000;
  ContaminationPatternOptions pattern;
  pattern.width_px = 40;
  pattern.height_px = 30;
  const Image tau = GenerateContaminationPattern(pattern);
  std::unique_ptr<SimShadowMapRig> rig;
  const Status created = SimShadowMapRig::Create(rig_options, tau, &rig);
  ASSERT_TRUE(created.ok()) << created.message();

  std::mutex mutex;
  std::vector<Image> served;
  Camera* sim_camera = rig->camera();
  AravisFakeFrameSource render = [&](const AravisFakeFrameRequest& request, Image* raw_dn) {
    double applied = 0;
    THINSLAB_RETURN_IF_ERROR(sim_camera->SetExposure(request.exposure_time_us, &applied));
    CapturedFrame frame;
    THINSLAB_RETURN_IF_ERROR(sim_camera->Capture(&frame));
    *raw_dn = frame.raw_dn;
    std::lock_guard<std::mutex> lock(mutex);
    served.push_back(frame.raw_dn);
    return Status::Ok();
  };
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), render, &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.bit_depth = rig->rig_info().cameras[0].bit_depth;  // 12-bit sensor in a Mono16 container.
  std::unique_ptr<AravisCamera> camera;
  const Status open = OpenAravisCamera(options, &camera);
  ASSERT_TRUE(open.ok()) << open.message();

  TempDir dir;
  Session header;
  header.name = "aravis_fake";
  header.kind = "shadow_map";
  header.software = "aravis_fake_camera_test";
  header.rig = rig->rig_info();
  CameraInfo& cam0 = header.rig.cameras[0];
  ASSERT_EQ(cam0.id, camera->info().id);
  cam0.model = camera->info().model;
  cam0.serial = camera->info().serial;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", header).ok());
  ShadowMapSessionOptions session_options;
  session_options.frames_per_state = 2;
  session_options.dark_frames = 1;
  const Status run = RunShadowMapSession(session_options, camera.get(), rig->projector(), rig->sample_changer(), &writer);
  ASSERT_TRUE(run.ok()) << run.message();
  ASSERT_TRUE(writer.Save().ok());
  EXPECT_EQ(fake->source_errors(), 0u) << fake->last_source_error();

  Session session;
  const Status read = ReadSession(dir / "s", &session);
  ASSERT_TRUE(read.ok()) << read.message();
  ASSERT_EQ(session.frames.size(), 5u);
  // The fake served every capture; the display-camera synchronisation discarded the first ones
  // (the settle of the first frame) and any frame still showing the previous light state.
  const int discarded = writer.session().acquisition.discarded_frames;
  ASSERT_EQ(served.size(), 5u + static_cast<size_t>(discarded));
  const double black = session.rig.cameras[0].black_level_dn;
  std::vector<double> means;
  std::vector<int> served_index;
  for (size_t i = 0; i < session.frames.size(); ++i) {
    const FrameRecord& f = session.frames[i];
    EXPECT_EQ(f.status, FrameStatus::kOk) << f.error;
    EXPECT_EQ(f.exposure_time_us, 20000);
    Image loaded;
    ASSERT_TRUE(LoadFrame(dir / "s", session, f, &loaded).ok());
    // The stored frame is one of the rig's images, through GVSP, to the DN, in serving order.
    int found = -1;
    for (size_t j = served_index.empty() ? 0 : served_index.back() + 1; j < served.size() && found < 0; ++j) {
      Image expected = served[j];
      for (float& v : expected.data()) v = static_cast<float>(std::round(v) - black);
      if (SameImage(loaded, expected)) found = static_cast<int>(j);
    }
    ASSERT_GE(found, 0) << "frame " << i << " (" << f.kind << ") is none of the images served after the last";
    served_index.push_back(found);
    means.push_back(Mean(loaded));
  }
  // The camera's frame ids and device timestamps reached the manifest: ids increase by one per
  // buffer served (the discarded ones count too: no buffer was lost), timestamps increase.
  for (size_t i = 0; i < session.frames.size(); ++i) {
    const FrameRecord& f = session.frames[i];
    ASSERT_TRUE(f.camera_frame_id.has_value()) << "frames[" << i << "].camera_frame_id missing";
    ASSERT_TRUE(f.camera_timestamp_ns.has_value()) << "frames[" << i << "].camera_timestamp_ns missing";
    if (i == 0) continue;
    EXPECT_EQ(*f.camera_frame_id - *session.frames[i - 1].camera_frame_id,
              static_cast<uint64_t>(served_index[i] - served_index[i - 1]))
        << "frame " << i;
    EXPECT_GT(*f.camera_timestamp_ns, *session.frames[i - 1].camera_timestamp_ns) << "frame " << i;
  }
  // The light state reached the frames: dark < shadow < reference.
  EXPECT_LT(means[0], 0.2 * means[1]);
  EXPECT_LT(means[3], means[1]);

  const auto& stats = session.rig.cameras[0].stream_statistics;
  ASSERT_FALSE(stats.empty()) << "session.json lacks rig.cameras[0].stream_statistics";
  // Recorded with the last frame: every buffer served completed, nothing lost.
  EXPECT_EQ(Stat(stats, "completed_buffers"), static_cast<double>(served.size()));
  EXPECT_EQ(Stat(stats, "failed_buffers"), 0);
  EXPECT_EQ(Stat(stats, "missing_packets"), 0);
  EXPECT_EQ(Stat(stats, "timeouts"), 0);
  EXPECT_EQ(Stat(stats, "packet_size_bytes"), camera->packet_size_bytes());
}

// Captures `count` frames with CaptureWithRetries into a session and returns it.
void CaptureFrames(Camera* camera, int count, int max_retries, const std::string& dir, Session* session) {
  Session header;
  header.name = "lossy";
  header.kind = "test";
  header.rig.cameras = {camera->info()};
  header.rig.sample.region_min_m = Eigen::Vector2d(-1e-3, -1e-3);
  header.rig.sample.region_max_m = Eigen::Vector2d(1e-3, 1e-3);
  header.rig.sample.pixel_pitch_m = 1e-4;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir, header).ok());
  FrameRecord templ;
  templ.camera_id = camera->info().id;
  templ.kind = "reference";
  templ.sample_state = "clean";
  for (int i = 0; i < count; ++i) {
    const Status status = CaptureWithRetries(camera, templ, max_retries, &writer);
    ASSERT_TRUE(status.ok()) << status.message();
  }
  ASSERT_TRUE(writer.Save().ok());
  ASSERT_TRUE(ReadSession(dir, session).ok());
}

// Every usable frame of `session` must be exactly one of the images the fake served.
void ExpectUsableFramesAreComplete(const std::string& dir, const Session& session, const PatternSource& source) {
  int usable = 0;
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) continue;
    ++usable;
    Image loaded;
    ASSERT_TRUE(LoadFrame(dir, session, f, &loaded).ok());
    bool found = false;
    for (size_t i = 0; i < source.count() && !found; ++i) found = SameImage(loaded, source.image(i));
    EXPECT_TRUE(found) << "frame " << f.index << " matches no served image: delivered incomplete";
  }
  EXPECT_EQ(usable, 6);
}

// gvsp-lost-ratio drops 2% of GVSP packets: a 160x120 Mono16 frame is 30 packets, so about
// 45% of frames lose one. With resend on, Aravis asks for the missing packets; Aravis 0.8.26's
// fake camera does not answer PACKET_RESEND (its control loop has no case for it), so the
// frames still fail, and CaptureWithRetries records them and triggers again.
TEST(AravisFakeCamera, LostPacketsWithResendOnAreCountedAndOnlyCompleteFramesAreKept) {
  PatternSource source(65535);
  AravisFakeCameraOptions fake_options;
  fake_options.gvsp_lost_ratio = 0.02;
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(fake_options, source.callback(), &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.packet_resend = 1;
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(options, &camera).ok());
  TempDir dir;
  Session session;
  CaptureFrames(camera.get(), 6, 15, dir / "s", &session);
  ExpectUsableFramesAreComplete(dir / "s", session, source);

  const auto& stats = session.rig.cameras[0].stream_statistics;
  EXPECT_GT(Stat(stats, "missing_packets"), 0);
  EXPECT_GT(Stat(stats, "resend_requests"), 0);
  EXPECT_GE(Stat(stats, "resent_packets"), 0);  // 0 with this fake; counted on real cameras.
  EXPECT_GT(Stat(stats, "failed_buffers"), 0);
  EXPECT_EQ(Stat(stats, "completed_buffers"), 6);
  int failed = 0;
  for (const FrameRecord& f : session.frames) {
    if (f.status != FrameStatus::kFailed) continue;
    ++failed;
    EXPECT_NE(f.error.find("incomplete"), std::string::npos) << f.error;
    EXPECT_NE(f.error.find("127.0.0.1"), std::string::npos) << f.error;
  }
  EXPECT_EQ(failed, Stat(stats, "failed_buffers"));
}

TEST(AravisFakeCamera, LostPacketsWithResendOffFailAndAreRecordedAsFailed) {
  PatternSource source(65535);
  AravisFakeCameraOptions fake_options;
  fake_options.gvsp_lost_ratio = 0.02;
  fake_options.random_seed = 7;
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(fake_options, source.callback(), &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.packet_resend = 0;
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(options, &camera).ok());
  TempDir dir;
  Session session;
  CaptureFrames(camera.get(), 6, 15, dir / "s", &session);
  ExpectUsableFramesAreComplete(dir / "s", session, source);

  const auto& stats = session.rig.cameras[0].stream_statistics;
  EXPECT_GT(Stat(stats, "missing_packets"), 0);
  EXPECT_EQ(Stat(stats, "resend_requests"), 0);
  int failed = 0, retried = 0;
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) {
      ++failed;
      EXPECT_NE(f.error.find("packet resend off"), std::string::npos) << f.error;
    }
    if (f.status == FrameStatus::kRetried) ++retried;
  }
  EXPECT_GT(failed, 0);
  EXPECT_GT(retried, 0);
  EXPECT_EQ(failed, Stat(stats, "failed_buffers"));
}

// Idle gaps between triggers longer than both the frame timeout and the camera's heartbeat
// timeout: Aravis's heartbeat keeps control and the stream stays armed. Had the heartbeat
// stopped, the camera would have cleared its privilege register and stopped streaming (the fake
// checks the heartbeat's age on the next control packet), and the capture would have needed a
// re-arm.
TEST(AravisFakeCamera, CaptureAfterAnIdleGapLongerThanTheHeartbeatTimeout) {
  PatternSource source(65535);
  AravisFakeCameraOptions fake_options;
  fake_options.heartbeat_timeout_ms = 1500;
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(fake_options, source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(CameraOptions(*fake), &camera).ok());
  CapturedFrame frame;
  ASSERT_TRUE(camera->Capture(&frame).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));
  EXPECT_TRUE(fake->ControlHeld()) << "the camera dropped control during the idle gap: no heartbeat reached it";
  const Status status = camera->Capture(&frame);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_TRUE(SameImage(frame.raw_dn, source.image(1)));
  const auto stats = camera->statistics();
  EXPECT_EQ(Stat(stats, "timeouts"), 0);
  EXPECT_EQ(StatOrZero(stats, "rearms"), 0);
  EXPECT_EQ(StatOrZero(stats, "control_regained"), 0);
  EXPECT_TRUE(fake->ControlHeld());
}

// A frame that arrives after its capture gave up on it (the camera stalled longer than the
// frame timeout): the capture times out, re-arms and triggers again, and the late frame is
// never delivered as the answer to a later trigger. The fake serves GVCP and GVSP from one
// thread, so while its frame source stalls, the re-arm's commands wait too (Aravis resends
// them), as with a camera busy with a long readout.
TEST(AravisFakeCamera, LateFrameIsNeverTakenForALaterTrigger) {
  PatternSource source(65535);
  AravisFakeFrameSource pattern = source.callback();
  AravisFakeFrameSource stalling = [&pattern](const AravisFakeFrameRequest& request, Image* raw_dn) {
    if (request.index == 1) std::this_thread::sleep_for(std::chrono::milliseconds(800));
    return pattern(request, raw_dn);
  };
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), stalling, &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.frame_timeout_s = 0.3;
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(options, &camera).ok());
  CapturedFrame frame;
  ASSERT_TRUE(camera->Capture(&frame).ok());
  ASSERT_TRUE(SameImage(frame.raw_dn, source.image(0)));

  // The stalled trigger: its frame (index 1) comes late; the re-armed trigger's frame (index 2)
  // follows. Either answers this capture (both were taken after it was asked for).
  Status status = camera->Capture(&frame);
  ASSERT_TRUE(status.ok()) << status.message();
  auto stats = camera->statistics();
  EXPECT_EQ(Stat(stats, "timeouts"), 1);
  EXPECT_EQ(Stat(stats, "rearms"), 1);
  ASSERT_GE(source.count(), 2u);
  const bool late_frame = SameImage(frame.raw_dn, source.image(1));
  const bool retriggered = source.count() >= 3 && SameImage(frame.raw_dn, source.image(2));
  EXPECT_TRUE(late_frame || retriggered) << "the re-armed capture returned neither of its triggers' frames";

  // The next capture (after 100 ms: the fake, like a busy camera, merges a software trigger into
  // the frame it is still serving) gets the frame of its own trigger, the newest served, never
  // the one left over, which may still be in flight when the capture drains the stream (it was,
  // under the sanitizers on a loaded machine): the capture skips it by its frame id.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  status = camera->Capture(&frame);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_GE(source.count(), 3u);
  EXPECT_TRUE(SameImage(frame.raw_dn, source.image(source.count() - 1)))
      << "served " << source.count() << " frames; the capture did not return the last";
  stats = camera->statistics();
  EXPECT_GE(Stat(stats, "stale_buffers_dropped"), 1);
  EXPECT_EQ(Stat(stats, "timeouts"), 1);
}

// The camera drops our control channel during an idle gap (heartbeat lost, camera reset):
// the next Capture retakes control, restarts acquisition and still delivers the frame.
TEST(AravisFakeCamera, ControlLostDuringAnIdleGapIsRegainedByTheNextCapture) {
  PatternSource source(65535);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(CameraOptions(*fake), &camera).ok());
  CapturedFrame frame;
  ASSERT_TRUE(camera->Capture(&frame).ok());
  fake->DropControl();
  // Longer than Aravis's 1 s heartbeat period, so the loss is seen before the next trigger.
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  const Status status = camera->Capture(&frame);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_EQ(source.count(), 2u);
  EXPECT_TRUE(SameImage(frame.raw_dn, source.image(1)));
  const auto stats = camera->statistics();
  EXPECT_GE(Stat(stats, "control_regained"), 1);
  EXPECT_GE(Stat(stats, "rearms"), 1);
  // And the camera keeps working afterwards.
  ASSERT_TRUE(camera->Capture(&frame).ok());
  EXPECT_TRUE(SameImage(frame.raw_dn, source.image(2)));
}

// The camera goes away mid-session (cable pulled, power lost): the fake is destroyed between
// two frames of an acquisition run. Every GVCP command then goes unanswered; the capture and its
// retry fail naming the camera, and the manifest says which device failed, keeps the frames
// taken before, records the failed attempts and the stream statistics.
TEST(AravisFakeCamera, CameraLostMidSessionLeavesAManifestThatNamesIt) {
  PatternSource source(65535);
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source.callback(), &fake).ok());
  AravisCameraOptions options = CameraOptions(*fake);
  options.frame_timeout_s = 0.3;
  std::unique_ptr<AravisCamera> camera;
  ASSERT_TRUE(OpenAravisCamera(options, &camera).ok());

  TempDir dir;
  Session header;
  header.name = "camera_lost";
  header.kind = "test";
  header.rig.cameras = {camera->info()};
  header.rig.sample.region_min_m = Eigen::Vector2d(-1e-3, -1e-3);
  header.rig.sample.region_max_m = Eigen::Vector2d(1e-3, 1e-3);
  header.rig.sample.pixel_pitch_m = 1e-4;
  AcquisitionRunOptions run;
  run.session_dir = dir / "s";
  run.plan = "test frames=6";
  run.planned_frames = 6;
  run.camera_name = "aravis:" + fake->address();
  constexpr int kFramesBeforeLoss = 3;
  const SessionScript script = [&](Camera* recording, SessionWriter* writer) {
    for (int i = 0; i < 6; ++i) {
      if (i == kFramesBeforeLoss) fake.reset();  // Unplugged.
      FrameRecord templ;
      templ.camera_id = recording->info().id;
      templ.kind = "reference";
      templ.sample_state = "clean";
      THINSLAB_RETURN_IF_ERROR(CaptureWithRetries(recording, templ, /*max_retries=*/1, writer));
    }
    return Status::Ok();
  };
  AcquisitionResult result;
  const Status status = RunAcquisition(run, header, camera.get(), script, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("aravis camera 127.0.0.1"), std::string::npos) << status.message();
  EXPECT_EQ(result.state, "failed");

  Session session;
  const Status read = ReadSession(dir / "s", &session);
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(session.acquisition.state, "failed");
  ASSERT_FALSE(session.acquisition.events.empty());
  const AcquisitionEvent& last = session.acquisition.events.back();
  EXPECT_EQ(last.event, "failed");
  EXPECT_EQ(last.device, "camera 'cam0' (aravis:127.0.0.1)");
  EXPECT_NE(last.message.find("aravis camera 127.0.0.1"), std::string::npos) << last.message;
  EXPECT_NE(last.message.find("does not answer"), std::string::npos) << last.message;
  // The frames before the loss are on disk as served; then the two attempts at the next frame.
  ASSERT_EQ(session.frames.size(), static_cast<size_t>(kFramesBeforeLoss + 2));
  for (int i = 0; i < kFramesBeforeLoss; ++i) {
    const FrameRecord& f = session.frames[i];
    ASSERT_EQ(f.status, FrameStatus::kOk) << f.error;
    Image loaded;
    ASSERT_TRUE(LoadFrame(dir / "s", session, f, &loaded).ok());
    EXPECT_TRUE(SameImage(loaded, source.image(i))) << "frame " << i;
  }
  for (size_t i = kFramesBeforeLoss; i < session.frames.size(); ++i) {
    EXPECT_EQ(session.frames[i].status, FrameStatus::kFailed);
    EXPECT_NE(session.frames[i].error.find("aravis camera 127.0.0.1"), std::string::npos) << session.frames[i].error;
  }
  const auto& stats = session.rig.cameras[0].stream_statistics;
  EXPECT_EQ(Stat(stats, "completed_buffers"), kFramesBeforeLoss);
  EXPECT_EQ(Stat(stats, "frames_captured"), kFramesBeforeLoss);
}

TEST(AravisCamera, UnreachableAddressFailsFastNamingIt) {
  AravisCameraOptions options;
  options.address = "127.0.0.2";  // Loopback, nothing listening on UDP 3956.
  options.connect_timeout_s = 0.3;
  std::unique_ptr<AravisCamera> camera;
  const auto start = std::chrono::steady_clock::now();
  const Status status = OpenAravisCamera(options, &camera);
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(camera, nullptr);
  EXPECT_NE(status.message().find("aravis camera 127.0.0.2"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("3956"), std::string::npos) << status.message();
  EXPECT_LT(elapsed_s, 1.0);
}

// A host that swallows GVCP without answering (a firewall dropping it, a PC at the camera's
// address): a UDP socket on 127.0.0.3:3956 that never replies.
TEST(AravisCamera, SilentAddressTimesOutNamingIt) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in silent{};
  silent.sin_family = AF_INET;
  silent.sin_port = htons(3956);
  ASSERT_EQ(::inet_pton(AF_INET, "127.0.0.3", &silent.sin_addr), 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&silent), sizeof(silent)), 0) << std::strerror(errno);
  AravisCameraOptions options;
  options.address = "127.0.0.3";
  options.connect_timeout_s = 0.3;
  std::unique_ptr<AravisCamera> camera;
  const auto start = std::chrono::steady_clock::now();
  const Status status = OpenAravisCamera(options, &camera);
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("aravis camera 127.0.0.3: no GigE Vision reply on UDP port 3956 within 0.3 s"),
            std::string::npos)
      << status.message();
  EXPECT_GE(elapsed_s, 0.25);
  EXPECT_LT(elapsed_s, 1.0);
  // What arrived was a GVCP READREG command (key 0x42, command 0x0080), not a broadcast.
  unsigned char packet[64];
  const ssize_t got = ::recv(fd, packet, sizeof(packet), MSG_DONTWAIT);
  ::close(fd);
  ASSERT_GE(got, 12);
  EXPECT_EQ(packet[0], 0x42);
  EXPECT_EQ(packet[2], 0x00);
  EXPECT_EQ(packet[3], 0x80);
}

TEST(AravisCamera, BadOptionsNameTheField) {
  AravisCameraOptions options;
  std::unique_ptr<AravisCamera> camera;
  Status status = OpenAravisCamera(options, &camera);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("AravisCameraOptions::address"), std::string::npos) << status.message();
  options.address = "127.0.0.1";
  options.packet_size = 100;
  status = OpenAravisCamera(options, &camera);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("AravisCameraOptions::packet_size = 100"), std::string::npos) << status.message();
}

}  // namespace
}  // namespace thinslab

namespace thinslab {
namespace {

// `thinslab acquire preview --camera aravis:127.0.0.1` (issue #28, item 1) under a private Xvfb:
// the window read back (--snapshot) shows the fake's image with its saturated block in red, a
// ramp in grey at the preview's display gamma, the histogram with its saturated bin in red and
// the focus bar; stdout has one line of statistics per frame.
TEST(AravisFakeCamera, PreviewShowsTheLiveImageWithSaturationHistogramAndFocus) {
  AravisFakeFrameSource source = [](const AravisFakeFrameRequest& request, Image* raw_dn) {
    *raw_dn = Image(request.width_px, request.height_px);
    for (int y = 0; y < request.height_px; ++y) {
      for (int x = 0; x < request.width_px; ++x) {
        const bool block = x >= 10 && x < 30 && y >= 10 && y < 30;
        raw_dn->at(x, y) = block ? 65535.0f : static_cast<float>(1000 + 40 * (x % 256));
      }
    }
    return Status::Ok();
  };
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), source, &fake).ok());
  XvfbServer xvfb;
  ASSERT_NO_FATAL_FAILURE(StartXvfbForTheWindow(1280, 1024, &xvfb));
  TempDir dir;
  const std::string snapshot = dir / "preview.png";
  const RunResult r = RunThinslab("acquire preview --camera aravis:" + fake->address() +
                                  " --camera-timeout-s 1 --pixel-format Mono16 --exposure-us 2000 --frames 3 --snapshot " +
                                  snapshot);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("preview frame 3 (2000 us): saturated "), std::string::npos) << r.output;
  const cv::Mat shown = cv::imread(snapshot, cv::IMREAD_COLOR);
  ASSERT_FALSE(shown.empty()) << snapshot;
  const int width = shown.cols, frame_height = shown.rows - 72;  // Histogram 64 + focus bar 8.
  ASSERT_GT(width, 300);
  ASSERT_GT(frame_height, 40);
  // The saturated fraction printed is the block's.
  const double block_percent = 100.0 * 400 / (static_cast<double>(width) * frame_height);
  std::ostringstream expected;
  expected << std::setprecision(3) << "saturated " << block_percent << " %";
  EXPECT_NE(r.output.find(expected.str()), std::string::npos) << expected.str() << " not in\n" << r.output;
  const cv::Vec3b red(0, 0, 255);  // BGR.
  EXPECT_EQ(shown.at<cv::Vec3b>(20, 20), red);
  // The ramp: grey (value - black) / 65535 at gamma 1 / 2.2.
  for (int x : {40, 100, 200}) {
    const double f = (1000 + 40.0 * (x % 256)) / 65535;
    const int grey = static_cast<int>(std::lround(255 * std::pow(f, 1 / 2.2)));
    const cv::Vec3b p = shown.at<cv::Vec3b>(50, x);
    EXPECT_NEAR(p[0], grey, 1) << "x " << x;
    EXPECT_EQ(p[0], p[1]);
    EXPECT_EQ(p[1], p[2]);
  }
  // Histogram strip: the saturated bin (right end) red at its foot, white bars of the ramp's bins.
  EXPECT_EQ(shown.at<cv::Vec3b>(frame_height + 63, width - 1), red);
  int white = 0;
  for (int x = 0; x < width; ++x) white += shown.at<cv::Vec3b>(frame_height + 63, x) == cv::Vec3b(255, 255, 255);
  EXPECT_GT(white, 10);
  // Focus bar: a steady scene is at its best focus, full length.
  EXPECT_EQ(shown.at<cv::Vec3b>(frame_height + 68, width - 2), cv::Vec3b(0, 200, 255));
}

// `acquire bracket --exposures-us auto` (issue #28, item 2) through the GigE Vision stack and the
// SDL window under Xvfb: the probe measures the pattern through the fake camera, whose frames
// are a still ramp scene lit in proportion to the exposure it was set to, and the planned
// bracket puts the brightest pixel near 5 % of the range in its shortest exposure and the dimmest
// lit pixels near 95 % in its longest (the response recovery's weighted range), one stop apart.
constexpr double kRampRange = 65535, kRampPeakDnPerUs = 0.164;  // The brightest pixel at 5 % in 20 ms.

TEST(AravisFakeCamera, ResponseBracketIsPlannedFromAProbeThroughTheCamera) {
  AravisFakeFrameSource ramp = [](const AravisFakeFrameRequest& request, Image* raw_dn) {
    *raw_dn = Image(request.width_px, request.height_px);
    for (int y = 0; y < request.height_px; ++y) {
      for (int x = 0; x < request.width_px; ++x) {
        const double rate = kRampPeakDnPerUs * (0.5 + 0.5 * x / (request.width_px - 1.0));
        raw_dn->at(x, y) = static_cast<float>(std::min(kRampRange, rate * request.exposure_time_us));
      }
    }
    return Status::Ok();
  };
  std::unique_ptr<AravisFakeCamera> fake;
  ASSERT_TRUE(AravisFakeCamera::Start(AravisFakeCameraOptions(), ramp, &fake).ok());
  XvfbServer xvfb;
  ASSERT_NO_FATAL_FAILURE(StartXvfbForTheWindow(320, 240, &xvfb));
  TempDir dir;
  const std::string enter = dir / "enter.txt";
  ASSERT_TRUE(WriteFileAtomically(enter, "\n\n\n\n").ok());
  const RunResult r = RunThinslab("acquire bracket --camera aravis:" + fake->address() +
                                      " --camera-timeout-s 2 --quiet --display 0 --pixel-format Mono16"
                                      " --exposures-us auto --capture-dark false " +
                                      dir / "s",
                                  enter);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("exposure plan: planned-exposures-us = "), std::string::npos) << r.output;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_NE(session.acquisition.plan.find("the response's high end"), std::string::npos) << session.acquisition.plan;
  const auto frames = session.UsableFrames("bracket");
  ASSERT_GE(frames.size(), 3u);
  for (size_t k = 1; k < frames.size(); ++k) {
    EXPECT_LE(frames[k]->exposure_time_us / frames[k - 1]->exposure_time_us, 2.2) << "frame " << k;
  }
  Image shortest, longest;
  ASSERT_TRUE(LoadFrame(dir / "s", session, *frames.front(), &shortest).ok());
  ASSERT_TRUE(LoadFrame(dir / "s", session, *frames.back(), &longest).ok());
  const double brightest = *std::max_element(shortest.data().begin(), shortest.data().end()) / kRampRange;
  EXPECT_GT(brightest, 0.02) << frames.front()->exposure_time_us << " us";
  EXPECT_LT(brightest, 0.10) << frames.front()->exposure_time_us << " us";
  std::vector<float> values = longest.data();
  std::sort(values.begin(), values.end());
  const double dimmest = values[values.size() / 20] / kRampRange;  // 5th percentile: the whole ramp is lit.
  EXPECT_GT(dimmest, 0.85) << frames.back()->exposure_time_us << " us";
  EXPECT_LT(dimmest, 0.999) << frames.back()->exposure_time_us << " us";
}

}  // namespace
}  // namespace thinslab
