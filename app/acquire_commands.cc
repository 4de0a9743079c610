// SPDX-License-Identifier: Apache-2.0
// `thinslab acquire <kind> [--camera sim|aravis:<ip>|v4l2:<device>] [--display <n>]
//  [--laser <spec>] [--resume] [kind options] OUTPUT` (docs/cli.md, "Acquisition").
// The session scripts of acquire/ run through the driver interfaces on either the simulated
// rigs (the default; the same rigs and scripts as `thinslab sim`) or real devices. With
// --camera sim, --display and --laser drive the real display or laser trigger alongside the
// simulated ones (a dry run of the device; the frames come from the simulation).
// Devices are opened before the session folder is touched, so a device that cannot be opened
// leaves no folder (new session) or the folder as it was (resume).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "thinslab/acquire/display_gamma_session.h"
#include "thinslab/acquire/dot_scan_session.h"
#include "thinslab/acquire/exposure_plan.h"
#include "thinslab/acquire/laser_lobe_session.h"
#include "thinslab/acquire/live_preview.h"
#include "thinslab/acquire/session_journal.h"
#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/pipeline/capture_check.h"
// The device back-ends this build has (CMake options THINSLAB_WITH_*; app/CMakeLists.txt).
#if THINSLAB_WITH_ARAVIS
#include "thinslab/drivers/aravis_camera.h"
#endif
#if THINSLAB_WITH_SDL
#include <opencv2/imgproc.hpp>

#include "thinslab/core/png_io.h"
#include "thinslab/drivers/pattern_window.h"
#include "thinslab/drivers/preview_window.h"
#endif
#if THINSLAB_WITH_USB
#include "thinslab/drivers/usb_laser.h"
#endif
#if THINSLAB_WITH_V4L2
#include "thinslab/drivers/v4l2_camera.h"
#endif
#include "thinslab/sim/laser_lobe_rig.h"
#include "thinslab/sim/shadow_map_rig.h"
#include "thinslab/sim/sim_board_camera.h"
#include "thinslab/sim/sim_dot_monitor.h"
#include "thinslab/sim/sim_session.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"

namespace thinslab {
namespace {

// SIGINT/SIGTERM stop the session between frames; the manifest then says "interrupted".
std::atomic<int> g_stop_signal{0};
extern "C" void OnStopSignal(int signal) { g_stop_signal.store(signal); }

std::string StopReason() {
  const int s = g_stop_signal.load();
  if (s == 0) return "";
  return std::string("interrupted by ") + (s == SIGINT ? "SIGINT" : s == SIGTERM ? "SIGTERM" : "a signal");
}

// The plan: kind plus every option except the ones naming devices, the folder or run control.
std::string PlanText(const std::string& kind, const std::string& ini) {
  static const char* kNotPlan[] = {"OUTPUT", "camera", "display", "laser", "resume", "quiet", "camera-timeout-s", "sim-realtime",
                                   "check"};
  std::ostringstream plan;
  plan << kind;
  std::istringstream lines(ini);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::string key = line.substr(0, line.find(" = "));
    bool skip = false;
    for (const char* k : kNotPlan) skip = skip || key == k;
    // No table: the plan reads as before the option existed, so older sessions still resume.
    skip = skip || line == "gamma-table = ";
    if (!skip) plan << "; " << line;
  }
  return plan.str();
}

// Drives a real device and the simulated one together (--camera sim with --display/--laser).
class TeeProjector : public Projector {
 public:
  TeeProjector(Projector* sim, Projector* real) : sim_(sim), real_(real) {}
  Status ShowPattern(const std::string& pattern) override {
    THINSLAB_RETURN_IF_ERROR(real_->ShowPattern(pattern));
    return sim_->ShowPattern(pattern);
  }
  double refresh_period_s() const override { return sim_->refresh_period_s(); }

 private:
  Projector* sim_;
  Projector* real_;
};

class TeeLaser : public Laser {
 public:
  TeeLaser(Laser* sim, Laser* real) : sim_(sim), real_(real) {}
  Status SetEmission(bool on) override {
    THINSLAB_RETURN_IF_ERROR(real_->SetEmission(on));
    return sim_->SetEmission(on);
  }

 private:
  Laser* sim_;
  Laser* real_;
};

// A simulated camera that takes as long as a real one: each capture lasts its exposure.
class RealtimeCamera : public Camera {
 public:
  explicit RealtimeCamera(Camera* camera) : camera_(camera) {}
  const CameraInfo& info() const override { return camera_->info(); }
  Status SetExposure(double requested_us, double* applied_us) override {
    return camera_->SetExposure(requested_us, applied_us);
  }
  Status Capture(CapturedFrame* frame) override {
    const auto start = std::chrono::steady_clock::now();
    THINSLAB_RETURN_IF_ERROR(camera_->Capture(frame));
    std::this_thread::sleep_until(start + std::chrono::microseconds(static_cast<int64_t>(frame->exposure_time_us)));
    return Status::Ok();
  }
  std::map<std::string, double> statistics() const override { return camera_->statistics(); }

 private:
  Camera* camera_;
};

// Sample changes at a real rig are done by the operator: a prompt on stderr, confirmed with
// Enter on stdin.
SampleChanger OperatorSampleChanger() {
  auto current = std::make_shared<std::string>();
  return [current](const std::string& state) {
    if (*current == state) return Status::Ok();
    const std::string what = state == "none" ? "Remove the sample from the light path"
                             : state == "clean" ? "Put the CLEAN glass in place"
                                                : "Put the sample under test (" + state + ") in place";
    std::cerr << what << ", then press Enter... " << std::flush;
    std::string line;
    if (!std::getline(std::cin, line)) {
      return Status::Error("sample stage (operator): no confirmation for sample state '" + state +
                           "' (end of input on stdin)");
    }
    *current = state;
    return Status::Ok();
  };
}

SampleChanger AnySampleState() {
  return [](const std::string& state) {
    if (state != "clean" && state != "contaminated" && state != "none") {
      return Status::Error("sample stage (sim): unknown sample state '" + state + "'");
    }
    return Status::Ok();
  };
}

struct CommonOptions {
  std::string camera = "sim";
  int display = -1;
  std::string laser;
  bool resume = false;
  bool quiet = false;
  bool check = true;  // Run the session check (pipeline/capture_check.h) on the finished capture.
  bool sim_realtime = false;
  double camera_timeout_s = 2;
  // Real cameras (docs/cli.md): "" = the driver's default (Aravis Mono16, V4L2 the deepest
  // offered); gain and packet size are GigE Vision (Aravis) only.
  std::string pixel_format;
  double gain_db = 0;
  int packet_size = 0;  // 0 = negotiate.
  int bit_depth = 0;    // 0 = from the pixel format.
  double black_level_dn = 0;
  int max_retries = 2;
  std::string name;
  std::string out;
  std::string gamma_table;  // Display gamma table applied by every display (docs/drivers.md, "Gamma").
  // Rig description for real cameras (the simulated rigs describe themselves).
  std::string region_mm = "-10,-10,10,10";
  double pitch_mm = 0.1;
  double board_distance_mm = 0;
  double board_albedo = 0.9;
  double beam_radius_mm = 0;
  double wavelength_nm = 0;
};

void AddCommonOptions(OptionParser* parser, CommonOptions* o, bool sim) {
  parser->AddPositional("OUTPUT", &o->out, "session folder to write (new or empty; with --resume, the interrupted one)");
  parser->AddString("camera", &o->camera, "sim | aravis:<ip or device id> | v4l2:<device path>");
  parser->AddInt("display", &o->display, "index of the display used as projector/monitor (-1: none)");
  parser->AddString("laser", &o->laser, "USB laser trigger spec, e.g. hid-relay:16c0:05df:1 (docs/drivers.md)");
  parser->AddBool("resume", &o->resume, "continue the interrupted or failed session in OUTPUT");
  parser->AddBool("quiet", &o->quiet, "no progress on stderr");
  parser->AddBool("check", &o->check,
                  "check the finished capture (thinslab check: saturation, exposure, motion, flicker, geometry)");
  parser->AddDouble("camera-timeout-s", &o->camera_timeout_s, "real cameras: connect and frame timeout [s]");
  parser->AddInt("max-retries", &o->max_retries, "further attempts after a failed capture");
  parser->AddString("gamma-table", &o->gamma_table,
                    "display gamma table (thinslab calib gamma) applied by the display, real or simulated");
  if (sim) {
    parser->AddBool("sim-realtime", &o->sim_realtime,
                    "the simulated camera takes its exposure time per capture, like a real one");
  } else {
    parser->AddString("pixel-format", &o->pixel_format,
                      "camera pixel format: Aravis Mono8|Mono10|Mono12|Mono14|Mono16 (default Mono16), "
                      "V4L2 GREY|Y10|Y12|Y16 (default the deepest offered)");
    parser->AddDouble("gain-db", &o->gain_db, "Aravis: analog gain in the camera's Gain units (dB on SFNC cameras)");
    parser->AddInt("packet-size", &o->packet_size, "Aravis: GVSP packet size [bytes], 576..16384; 0 = negotiate");
    parser->AddInt("bit-depth", &o->bit_depth, "Aravis: sensor bits in the pixel format's container (0: the format's)");
    parser->AddDouble("black-level-dn", &o->black_level_dn, "Aravis: camera black level [DN] for the manifest");
    parser->AddString("name", &o->name, "session name");
    parser->AddString("region-mm", &o->region_mm, "sample region x0,y0,x1,y1 on the sample plane [mm]");
    parser->AddDouble("pitch-mm", &o->pitch_mm, "pitch of the rectified sample grid [mm]");
    parser->AddDouble("board-distance-mm", &o->board_distance_mm, "sample-to-board distance [mm] (0: no board)");
    parser->AddDouble("board-albedo", &o->board_albedo, "board albedo (0, 1]");
    parser->AddDouble("beam-radius-mm", &o->beam_radius_mm, "laser beam radius [mm] (0: unknown)");
    parser->AddDouble("wavelength-nm", &o->wavelength_nm, "laser wavelength [nm] (0: unknown)");
  }
}

// The real devices named on the command line, opened before anything is written.
struct RealDevices {
  std::unique_ptr<Camera> camera;
  std::unique_ptr<Projector> window;
  int window_width = 0, window_height = 0;
  std::unique_ptr<Laser> laser;
  std::string display_name, laser_name;
  GammaTable gamma_table = IdentityGammaTable();  // --gamma-table, read before any device opens.
};

// The error for a device whose back-end this build left out.
[[maybe_unused]] Status NotBuilt(const std::string& device, const std::string& option) {
  return Status::Error(device + ": this thinslab was built without " + option +
                       " (reconfigure with -D" + option + "=ON and the library installed; docs/drivers.md)");
}

Status OpenRealCamera(const CommonOptions& o, [[maybe_unused]] RealDevices* devices) {
  if (o.camera == "sim") return Status::Ok();
  if (!(o.camera_timeout_s > 0)) {
    return Status::Error("thinslab acquire: option --camera-timeout-s must be > 0");
  }
  if (o.camera.rfind("aravis:", 0) == 0) {
#if THINSLAB_WITH_ARAVIS
    AravisCameraOptions options;
    options.address = o.camera.substr(7);
    options.frame_timeout_s = o.camera_timeout_s;
    options.connect_timeout_s = o.camera_timeout_s;
    if (!o.pixel_format.empty()) options.pixel_format = o.pixel_format;
    options.gain_db = o.gain_db;
    options.packet_size = o.packet_size;
    options.bit_depth = o.bit_depth;
    options.black_level_dn = o.black_level_dn;
    if (options.address.empty()) return Status::Error("thinslab acquire: --camera aravis: needs an address");
    std::string error;  // Names the option's field, e.g. AravisCameraOptions::packet_size for --packet-size.
    if (!options.Check(&error)) return Status::Error("camera " + o.camera + ": " + error);
    std::unique_ptr<AravisCamera> camera;
    THINSLAB_RETURN_IF_ERROR(OpenAravisCamera(options, &camera).WithContext("camera " + o.camera));
    devices->camera = std::move(camera);
    return Status::Ok();
#else
    return NotBuilt("camera " + o.camera, "THINSLAB_WITH_ARAVIS");
#endif
  }
  if (o.camera.rfind("v4l2:", 0) == 0) {
#if THINSLAB_WITH_V4L2
    V4l2CameraOptions options;
    options.device = o.camera.substr(5);
    options.timeout_s = o.camera_timeout_s;
    options.pixel_format = o.pixel_format;
    if (o.gain_db != 0 || o.packet_size != 0 || o.bit_depth != 0 || o.black_level_dn != 0) {
      return Status::Error("camera " + o.camera +
                           ": --gain-db, --packet-size, --bit-depth and --black-level-dn are Aravis options; "
                           "the V4L2 driver sets none of them");
    }
    if (options.device.empty()) return Status::Error("thinslab acquire: --camera v4l2: needs a device path");
    std::unique_ptr<V4l2Camera> camera;
    THINSLAB_RETURN_IF_ERROR(OpenV4l2Camera(options, &camera).WithContext("camera " + o.camera));
    devices->camera = std::move(camera);
    return Status::Ok();
#else
    return NotBuilt("camera " + o.camera, "THINSLAB_WITH_V4L2");
#endif
  }
  return Status::Error("thinslab acquire: option --camera = '" + o.camera +
                       "': expected sim, aravis:<ip or device id> or v4l2:<device path>");
}

// Camera first (the device every kind needs), then display and laser.
Status OpenRealDevices(const CommonOptions& o, RealDevices* devices) {
  if (!o.gamma_table.empty()) {
    THINSLAB_RETURN_IF_ERROR(ReadGammaTable(o.gamma_table, &devices->gamma_table).WithContext("option --gamma-table"));
  }
  THINSLAB_RETURN_IF_ERROR(OpenRealCamera(o, devices));
  if (o.display >= 0) {
#if THINSLAB_WITH_SDL
    PatternWindowOptions options;
    options.display_index = o.display;
    options.gamma_table_path = o.gamma_table;
    std::unique_ptr<PatternWindow> window;
    THINSLAB_RETURN_IF_ERROR(OpenPatternWindow(options, &window).WithContext("display " + std::to_string(o.display)));
    devices->window_width = window->width();
    devices->window_height = window->height();
    devices->window = std::move(window);
#else
    return NotBuilt("display " + std::to_string(o.display), "THINSLAB_WITH_SDL");
#endif
    devices->display_name = "display " + std::to_string(o.display);
  } else if (o.display < -1) {
    return Status::Error("thinslab acquire: option --display = " + std::to_string(o.display) +
                         ": display indices are >= 0 (-1 = none)");
  }
  if (!o.laser.empty()) {
#if THINSLAB_WITH_USB
    UsbLaserOptions options;
    THINSLAB_RETURN_IF_ERROR(ParseUsbLaserSpec(o.laser, &options).WithContext("laser '" + o.laser + "'"));
    std::unique_ptr<UsbLaser> laser;
    THINSLAB_RETURN_IF_ERROR(OpenUsbLaser(options, &laser).WithContext("laser '" + o.laser + "'"));
    devices->laser_name = "laser " + laser->device_name();
    devices->laser = std::move(laser);
#else
    return NotBuilt("laser '" + o.laser + "'", "THINSLAB_WITH_USB");
#endif
  }
  return Status::Ok();
}

// Rig description for a real camera from the command line.
Status RealRig(const CommonOptions& o, const CameraInfo& camera, RigInfo* rig) {
  double v[4];
  char tail = 0;
  if (std::sscanf(o.region_mm.c_str(), "%lf,%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &v[3], &tail) != 4 ||
      !(v[2] > v[0]) || !(v[3] > v[1])) {
    return Status::Error("thinslab acquire: option --region-mm = '" + o.region_mm +
                         "': expected x0,y0,x1,y1 with x1 > x0 and y1 > y0");
  }
  if (!(o.pitch_mm > 0)) return Status::Error("thinslab acquire: option --pitch-mm must be > 0");
  rig->cameras = {camera};
  rig->sample.region_min_m = Eigen::Vector2d(v[0], v[1]) * 1e-3;
  rig->sample.region_max_m = Eigen::Vector2d(v[2], v[3]) * 1e-3;
  rig->sample.pixel_pitch_m = o.pitch_mm * 1e-3;
  if (o.board_distance_mm > 0) {
    if (!(o.board_albedo > 0 && o.board_albedo <= 1)) {
      return Status::Error("thinslab acquire: option --board-albedo must be in (0, 1]");
    }
    rig->board.present = true;
    rig->board.distance_m = o.board_distance_mm * 1e-3;
    rig->board.albedo = o.board_albedo;
  }
  return Status::Ok();
}

Session MakeHeader(const std::string& name, const std::string& kind, const RigInfo& rig, bool sim) {
  Session header;
  header.name = name;
  header.kind = kind;
  header.software = std::string("thinslab ") + THINSLAB_VERSION_STRING + " acquire" + (sim ? " (sim rig)" : "") +
                    " (" + THINSLAB_GIT_HASH + ")";
  header.rig = rig;
  return header;
}

// Runs the script and reports; shared tail of every kind.
int Finish(const std::string& kind, const CommonOptions& common, const std::string& plan, int planned_frames,
           const Session& header, Camera* camera, const std::string& camera_name, const SessionScript& script,
           DeviceFailureTracker* tracker, SimBoardCamera* sim_camera = nullptr) {
  // A resumed simulation continues the device frame counter of the runs before it, so its
  // frames are the ones an uninterrupted run would have taken (per-capture seeded noise).
  if (sim_camera != nullptr && common.resume && FileExists(JoinPath(common.out, kSessionManifestName))) {
    Session previous;
    // The counter of the last frame journaled: the manifest may be older (docs/acquisition.md).
    if (ReadSessionWithJournal(common.out, &previous).ok()) {
      sim_camera->set_frame_counter(previous.acquisition.camera_captures);
    }
  }
  AcquisitionRunOptions run;
  run.session_dir = common.out;
  run.resume = common.resume;
  run.plan = plan;
  if (!common.gamma_table.empty()) {
    // The table's entries, not only its path, say which table drove the display.
    GammaTable table;
    const Status read = ReadGammaTable(common.gamma_table, &table);
    if (!read.ok()) {
      std::cerr << "error: " << read.WithContext("option --gamma-table").message() << "\n";
      return 1;
    }
    run.plan += "; gamma-table-entries = " + GammaTableCompactText(table);
  }
  run.planned_frames = planned_frames;
  run.camera_name = camera_name;
  run.label = "acquire " + kind;
  run.progress = common.quiet ? nullptr : &std::cerr;
  run.progress_is_terminal = ::isatty(STDERR_FILENO) != 0;
  run.stop_check = StopReason;
  run.tracker = tracker;
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
  AcquisitionResult result;
  RealtimeCamera realtime(camera);
  const Status status = RunAcquisition(run, header, common.sim_realtime ? &realtime : camera, script, &result);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!status.ok()) return CommandFailed(status);
  if (result.already_complete) {
    std::cout << common.out << ": session is already complete; nothing to resume\n";
    return 0;
  }
  std::cout << "wrote " << kind << " session " << common.out << " (" << result.frames_captured << " frames captured"
            << (result.frames_on_disk_before > 0 ? ", " + std::to_string(result.frames_on_disk_before) + " kept from before"
                                                 : std::string())
            << ")\n";
  if (common.check) {
    // Before the sample leaves the rig: what the frames show (issue #28). The capture is written
    // either way; `thinslab check` gives the verdict as its exit status.
    CaptureCheck check;
    const Status checked = CheckCapture(common.out, CaptureCheckOptions(), &check);
    if (!checked.ok()) {
      std::cerr << "error: session check: " << checked.message() << "\n";
      return 1;
    }
    std::cout << check.Describe();
  }
  return 0;
}

// ---------------------------------------------------------------------------------------

void AddSyncOptions(OptionParser* parser, DisplaySyncOptions* sync) {
  parser->AddInt("settle-captures", &sync->settle_captures, "captures before an invisible change counts as settled");
  parser->AddInt("max-sync-captures", &sync->max_sync_captures, "captures before display-camera sync gives up");
  parser->AddDouble("min-change-dn", &sync->min_change_dn, "smallest 3x3-mean change that shows a new pattern [DN]");
  parser->AddDouble("sync-read-noise-dn", &sync->read_noise_dn,
                    "camera read noise assumed by the synchronisation (the simulated rigs use their sensor's if larger) [DN]");
}

// The simulated cameras expose whole steps (sim/sensor_model.h), like real sensors' line periods.
void AddSimExposureStepOption(OptionParser* parser, SimSensorOptions* sensor) {
  parser->AddDouble("sim-exposure-step-us", &sensor->exposure_step_us,
                    "granularity of the simulated camera's exposure: the request is rounded to a multiple [us]");
}

Status CheckSimExposureStep(const SimSensorOptions& sensor) {
  if (sensor.exposure_step_us > 0 && std::isfinite(sensor.exposure_step_us)) return Status::Ok();
  return Status::Error("thinslab acquire: option --sim-exposure-step-us = " + std::to_string(sensor.exposure_step_us) +
                       ": expected a step > 0 us");
}

constexpr char kPlannedExposuresKey[] = "; planned-exposures-us = ";
constexpr char kPlannedFlatExposuresKey[] = "; planned-flat-exposures-us = ";
constexpr char kPlannedLongestFramesKey[] = "; planned-longest-exposure-frames = ";

// `--exposures-us auto` (issue #28, item 2): the bracket from a probe of the rig
// (acquire/exposure_plan.h), appended to the plan text (session.json acquisition.plan) with the
// reasons. A resume takes the exposures and reasons of the run it continues, without probing.
// `flat_exposures_us` (laser sessions; nullptr: none) receives the flat field's planned exposure,
// `longest_frames` (dot scans; nullptr: none) the frames planned at the longest exposure.
Status PlanBracketFromProbe(const CommonOptions& common, const std::function<Status(ExposurePlan*)>& probe,
                            std::vector<double>* exposures_us, std::vector<double>* flat_exposures_us,
                            int* longest_frames, std::string* plan) {
  std::string planned;
  if (common.resume && FileExists(JoinPath(common.out, kSessionManifestName))) {
    Session previous;
    THINSLAB_RETURN_IF_ERROR(ReadSessionWithJournal(common.out, &previous));
    const size_t at = previous.acquisition.plan.find(kPlannedExposuresKey);
    if (at == std::string::npos) {
      return Status::Error(common.out + ": the session to resume was not planned with --exposures-us auto");
    }
    planned = previous.acquisition.plan.substr(at);
    auto read_list = [&planned](const std::string& key, std::vector<double>* values) -> Status {
      const size_t from = planned.find(key);
      if (from == std::string::npos) return Status::Ok();
      const size_t list = from + key.size(), end = planned.find(';', list);
      return ParseExposureList(planned.substr(list, end - list), key.substr(2, key.size() - 5), values);
    };
    THINSLAB_RETURN_IF_ERROR(read_list(kPlannedExposuresKey, exposures_us));
    if (flat_exposures_us != nullptr) THINSLAB_RETURN_IF_ERROR(read_list(kPlannedFlatExposuresKey, flat_exposures_us));
    const size_t frames_at = planned.find(kPlannedLongestFramesKey);
    if (longest_frames != nullptr && frames_at != std::string::npos) {
      const size_t from = frames_at + std::strlen(kPlannedLongestFramesKey);
      const std::string text = planned.substr(from, planned.find(';', from) - from);
      char* end = nullptr;
      const long value = std::strtol(text.c_str(), &end, 10);
      if (end == text.c_str() || *end != '\0' || value < 1 || value > 1000) {
        return Status::Error(common.out + "/session.json: acquisition.plan: planned-longest-exposure-frames = '" +
                             text + "': expected a whole number in 1..1000");
      }
      *longest_frames = static_cast<int>(value);
    }
  } else {
    ExposurePlan result;
    THINSLAB_RETURN_IF_ERROR(probe(&result));
    *exposures_us = result.exposures_us;
    auto list = [](const std::vector<double>& values) {
      std::ostringstream text;
      text << std::setprecision(10);
      for (size_t k = 0; k < values.size(); ++k) text << (k ? "," : "") << values[k];
      return text.str();
    };
    std::string why = result.why;
    std::replace(why.begin(), why.end(), ';', ',');  // The plan text separates its fields by ';'.
    planned = kPlannedExposuresKey + list(result.exposures_us);
    if (flat_exposures_us != nullptr && !result.flat_exposures_us.empty()) {
      *flat_exposures_us = result.flat_exposures_us;
      planned += kPlannedFlatExposuresKey + list(result.flat_exposures_us);
    }
    if (longest_frames != nullptr) {
      *longest_frames = result.longest_frames;
      planned += kPlannedLongestFramesKey + std::to_string(result.longest_frames);
    }
    planned += "; exposure-plan = " + why;
  }
  *plan += planned;
  std::cout << "exposure plan:" << planned.substr(1) << "\n";
  return Status::Ok();
}

Status PlanDotScanBracket(const CommonOptions& common, DotScanSessionOptions& dots, int max_longest_frames,
                          Camera* camera, Projector* projector, const SampleChanger& change, double refresh_period_s,
                          std::string* plan) {
  return PlanBracketFromProbe(
      common,
      [&](ExposurePlan* result) {
        ExposurePlanOptions options;
        options.max_exposure_us = dots.bracket.max_exposure_us;
        options.min_exposure_us = dots.bracket.min_exposure_us;
        options.max_longest_frames = max_longest_frames;
        // Probe dots: the grid's centre and the centres of its four quadrants.
        const std::vector<Eigen::Vector2d> grid = DotScanGrid(dots);
        std::vector<Eigen::Vector2d> probe;
        for (const auto& [fx, fy] : std::vector<std::pair<double, double>>{
                 {0.5, 0.5}, {0.25, 0.25}, {0.75, 0.25}, {0.25, 0.75}, {0.75, 0.75}}) {
          const int i = static_cast<int>(std::lround(fx * (dots.grid_nx - 1)));
          const int j = static_cast<int>(std::lround(fy * (dots.grid_ny - 1)));
          probe.push_back(grid.at(static_cast<size_t>(j * dots.grid_nx + i)));
        }
        return ProbeAndPlanDotScanExposures(camera, projector, change, DotScanGridPattern(dots), probe,
                                            dots.sample_state, refresh_period_s, options, result);
      },
      &dots.bracket.exposures_us, nullptr, &dots.longest_exposure_frames, plan);
}

// `acquire bracket|gamma --exposures-us auto`: the bracket from `probe` (the response bracket of
// ProbeAndPlanResponseBracket, or ProbeAndPlanDisplayGammaExposures) within min..max_exposure_us.
using CalibrationProbe = std::function<Status(const ExposurePlanOptions& options, ExposurePlan* plan)>;
Status PlanCalibrationBracket(const CommonOptions& common, const CalibrationProbe& probe, double min_exposure_us,
                              double max_exposure_us, ExposureBracketOptions* bracket, std::string* plan) {
  return PlanBracketFromProbe(
      common,
      [&](ExposurePlan* result) {
        ExposurePlanOptions options;
        options.min_exposure_us = min_exposure_us;
        options.max_exposure_us = max_exposure_us;
        return probe(options, result);
      },
      &bracket->exposures_us, nullptr, nullptr, plan);
}

// The laser bracket from a probe: the spot through clean glass (or the sample) sets the
// shortest, the lobe's ring at the fit's outermost angle the longest. The ring is found through
// the camera's pose: the simulated rig's, or a calibrated capture's (`--plan-rig`).
struct LaserPlanText {
  double max_exposure_us = 1e7;
  double outer_angle_deg = 60;
  double ring_standard_errors = 100;  // 10 left sigma_g 1.1-1.5x the fixed bracket's (docs/acquisition.md).
  std::string rig_capture;
};

Status PlanLaserBracket(const CommonOptions& common, const LaserPlanText& text, const RigInfo& rig,
                        LaserLobeSessionOptions& session, Camera* camera, Laser* laser, Projector* flat_source,
                        const SampleChanger& change, std::string* plan) {
  return PlanBracketFromProbe(
      common,
      [&](ExposurePlan* result) {
        LaserProbeGeometry geometry;
        RigInfo from = rig;
        if (!text.rig_capture.empty()) {
          Session capture;
          THINSLAB_RETURN_IF_ERROR(ReadSessionWithJournal(text.rig_capture, &capture).WithContext("option --plan-rig"));
          from = capture.rig;
          if (from.cameras.empty()) return Status::Error("option --plan-rig: " + text.rig_capture + " has no camera");
          // Its calib/rig.json (intrinsics, pose) where it has one.
          SessionCalibration calibration;
          THINSLAB_RETURN_IF_ERROR(
              LoadSessionCalibration(text.rig_capture, SessionCalibrationOptions(), &from.cameras[0], &calibration)
                  .WithContext("option --plan-rig"));
        } else if (common.camera != "sim") {
          return Status::Error(
              "thinslab acquire laser: --exposures-us auto finds the lobe's ring through the camera's "
              "pose: give --plan-rig CAPTURE (a calibrated capture of this rig, `thinslab calib pose`)");
        }
        if (from.cameras.empty() || !from.board.present || !from.laser.present) {
          return Status::Error(
              "thinslab acquire laser: --exposures-us auto: the rig has no camera, board or laser to "
              "find the lobe's ring with");
        }
        geometry.camera = from.cameras[0];
        geometry.laser = from.laser;
        geometry.board_distance_m = from.board.distance_m;
        geometry.outer_angle_deg = text.outer_angle_deg;
        ExposurePlanOptions options;
        options.max_exposure_us = text.max_exposure_us;
        options.edge_sigmas = text.ring_standard_errors;
        return ProbeAndPlanLaserExposures(camera, laser, session.capture_flat ? flat_source : nullptr, change,
                                          session.capture_clean ? "clean" : "contaminated", geometry, options, result);
      },
      &session.exposure_times_us, &session.flat_exposure_times_us, nullptr, plan);
}

int AcquireShadowMaps(int argc, char** argv, bool sim) {
  CommonOptions common;
  SyntheticShadowSessionOptions simulated;  // Rig options (sim) and the session script's options.
  ShadowMapSessionOptions& session = simulated.session;
  double board_distance_mm = simulated.rig.board_distance_m * 1e3;
  std::string tau_path;
  OptionParser parser("acquire shadow-maps");
  AddCommonOptions(&parser, &common, sim);
  if (sim) {
    AddSimShadowOptions(&parser, &simulated, &board_distance_mm, &tau_path);
    AddSimExposureStepOption(&parser, &simulated.rig.sensor);
  } else {
    parser.AddInt("frames", &session.frames_per_state, "frames per state (shadow, reference)");
    parser.AddInt("dark-frames", &session.dark_frames, "dark frames (projector off)");
    parser.AddInt("validation-frames", &session.validation_frames,
                  "further shadow frames marked validation (not fitted; fit tau reports how well it predicts them)");
  }
  std::string exposure = "20000";
  parser.AddString(
      "exposure-us", &exposure,
      "exposure [us]; auto = planned from a probe: the flat field through clean glass at 80 % of the range "
      "in its brightest pixel");
  double max_exposure_us = 1e7;
  parser.AddDouble("max-exposure-us", &max_exposure_us, "--exposure-us auto: longest exposure allowed [us]");
  AddSyncOptions(&parser, &session.sync);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = CheckSimExposureStep(simulated.rig.sensor);
  const bool plan_exposure = exposure == "auto";
  if (status.ok() && !plan_exposure) {
    std::vector<double> one;
    status = ParseExposureList(exposure, "exposure-us", &one);
    if (status.ok() && one.size() != 1) {
      status = Status::Error("thinslab acquire shadow-maps: option --exposure-us = '" + exposure +
                             "': expected one exposure [us] or auto");
    }
    if (status.ok()) session.exposure_time_us = one[0];
  }
  if (!status.ok()) return CommandFailed(status);
  session.sync.max_retries = common.max_retries;
  std::string error;
  if (!session.Check(&error)) return CommandFailed(Status::Error(error));
  std::string plan = PlanText("shadow-maps", parser.ToIni());
  const int planned = static_cast<int>(PlanShadowMapSession(session).size());
  auto plan_shadow_exposure = [&](Camera* camera, Projector* projector, const SampleChanger& change) {
    std::vector<double> planned_exposure;
    const Status planned_status = PlanBracketFromProbe(
        common,
        [&](ExposurePlan* result) {
          ExposurePlanOptions options;
          options.peak_fill = 0.8;          // One exposure, no bracket: as much signal as the range allows.
          options.max_dark_fraction = 0.2;  // A projector-off frame above this is worth a warning.
          options.max_exposure_us = max_exposure_us;
          return ProbeAndPlanShadowMapExposure(camera, projector, change, options, result);
        },
        &planned_exposure, nullptr, nullptr, &plan);
    if (planned_status.ok()) session.exposure_time_us = planned_exposure.at(0);
    return planned_status;
  };

  RealDevices devices;
  status = OpenRealDevices(common, &devices);
  if (!status.ok()) return CommandFailed(status);
  DeviceFailureTracker tracker;
  if (sim) {
    simulated.rig.board_distance_m = board_distance_mm * 1e-3;
    // The simulated light: reference_fill at this exposure (the default's with auto).
    simulated.rig.exposure_time_us = session.exposure_time_us;
    Image tau;
    status = LoadOrGenerateTau(tau_path, simulated.rig.seed, &tau);
    std::unique_ptr<SimShadowMapRig> rig;
    if (status.ok()) status = SimShadowMapRig::Create(simulated.rig, tau, &rig);
    if (!status.ok()) return CommandFailed(status);
    session.sync = SyncForSensor(session.sync, simulated.rig.sensor);
    TeeProjector tee(rig->projector(), devices.window.get());
    TrackedProjector projector(devices.window ? static_cast<Projector*>(&tee) : rig->projector(),
                               devices.window ? devices.display_name : "projector (sim)", &tracker);
    const SampleChanger change = rig->sample_changer();
    if (plan_exposure) {
      status = plan_shadow_exposure(rig->camera(), &projector, change);
      if (!status.ok()) return CommandFailed(status);
    }
    return Finish("shadow-maps", common, plan, planned, MakeHeader(simulated.name, "shadow_map", rig->rig_info(), true),
                  rig->camera(), "sim",
                  [&](Camera* camera, SessionWriter* writer) {
                    return RunShadowMapSession(session, camera, &projector, change, writer);
                  },
                  &tracker, dynamic_cast<SimBoardCamera*>(rig->camera()));
  }
  if (!devices.window)
    return CommandFailed(
        Status::Error("thinslab acquire shadow-maps: a real camera needs --display <n> (the projector)"));
  RigInfo rig;
  status = RealRig(common, devices.camera->info(), &rig);
  if (!status.ok()) return CommandFailed(status);
  rig.projector.present = true;
  TrackedProjector projector(devices.window.get(), devices.display_name, &tracker);
  const SampleChanger change = OperatorSampleChanger();
  if (plan_exposure) {
    status = plan_shadow_exposure(devices.camera.get(), &projector, change);
    if (!status.ok()) return CommandFailed(status);
  }
  return Finish("shadow-maps", common, plan, planned,
                MakeHeader(common.name.empty() ? "shadow_map" : common.name, "shadow_map", rig, false),
                devices.camera.get(), common.camera,
                [&](Camera* camera, SessionWriter* writer) {
                  return RunShadowMapSession(session, camera, &projector, change, writer);
                },
                &tracker);
}

int AcquireLaser(int argc, char** argv, bool sim) {
  CommonOptions common;
  SimLaserLobeOptions simulated;
  LaserLobeSessionOptions session;
  std::string name = "laser_lobe", exposures;
  double distance_mm = simulated.board_distance_m * 1e3, beam_radius_mm = simulated.beam_radius_m * 1e3;
  OptionParser parser("acquire laser");
  AddCommonOptions(&parser, &common, sim);
  if (sim) {
    // The `thinslab sim laser` rig options (app/phase_commands.cc) that matter for acquisition.
    parser.AddString("name", &name, "session name");
    parser.AddDouble("tau", &simulated.layer_tau, "layer optical thickness (0 = clean glass)");
    parser.AddDouble("albedo", &simulated.layer_albedo, "layer single-scattering albedo");
    parser.AddDouble("g", &simulated.layer_g, "layer HG g");
    parser.AddDouble("board-distance-mm", &distance_mm, "layer-to-board distance d [mm]");
    parser.AddDouble("beam-radius-mm", &beam_radius_mm, "laser beam radius [mm]");
    parser.AddInt("photons", &simulated.monte_carlo.num_photons, "Monte Carlo photons");
    parser.AddInt("camera-width-px", &simulated.camera_width_px, "camera image width");
    parser.AddInt("camera-height-px", &simulated.camera_height_px, "camera image height");
    parser.AddBool("noise", &simulated.sensor.enable_noise, "simulate shot and read noise");
    parser.AddUint64("seed", &simulated.seed, "seed of every random choice");
    AddSimExposureStepOption(&parser, &simulated.sensor);
  }
  parser.AddString(
      "exposures-us", &exposures,
      "bracket exposures, comma-separated (default 20,200,...,2000000); auto = planned from a probe: the "
      "spot unsaturated in the shortest, the lobe's ring at --plan-outer-angle-deg measured in the longest");
  LaserPlanText laser_plan;
  parser.AddDouble("max-exposure-us", &laser_plan.max_exposure_us,
                   "--exposures-us auto: longest exposure allowed [us]");
  parser.AddDouble("plan-outer-angle-deg", &laser_plan.outer_angle_deg,
                   "--exposures-us auto: the fit's outermost ring, measured in the longest exposure [deg]");
  parser.AddDouble("plan-ring-standard-errors", &laser_plan.ring_standard_errors,
                   "--exposures-us auto: the ring's mean over its standard error in the longest exposure");
  parser.AddString(
      "plan-rig", &laser_plan.rig_capture,
      "--exposures-us auto with a real camera: a calibrated capture of this rig (camera pose, board, beam)");
  double sim_laser_power = 0;
  if (sim) {
    parser.AddDouble("sim-laser-power", &sim_laser_power,
                     "simulated laser power: 1 = the spot fills half the range in 20 us; 0 = in the bracket's shortest "
                     "exposure (20 us with --exposures-us auto)");
  }
  parser.AddInt("frames-per-exposure", &session.frames_per_exposure, "frames per bracket exposure");
  parser.AddBool("capture-clean", &session.capture_clean, "also capture the clean glass");
  parser.AddBool("capture-flat", &session.capture_flat, "also capture the board flat field");
  parser.AddBool("capture-validation", &session.capture_validation,
                 "also capture a second contaminated bracket marked validation (fit phase reports how well it predicts it)");
  AddSyncOptions(&parser, &session.sync);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  const bool plan_exposures = exposures == "auto";
  if (status.ok() && !exposures.empty() && !plan_exposures) {
    status = ParseExposureList(exposures, "exposures-us", &session.exposure_times_us);
  }
  if (status.ok()) status = CheckSimExposureStep(simulated.sensor);
  if (status.ok() && !(sim_laser_power >= 0 && std::isfinite(sim_laser_power))) {
    status = Status::Error("thinslab acquire laser: option --sim-laser-power = " + std::to_string(sim_laser_power) +
                           ": expected >= 0");
  }
  if (!status.ok()) return CommandFailed(status);
  session.sync.max_retries = common.max_retries;
  std::string error;
  if (!session.Check(&error)) return CommandFailed(Status::Error(error));
  std::string plan = PlanText("laser", parser.ToIni());

  RealDevices devices;
  status = OpenRealDevices(common, &devices);
  if (!status.ok()) return CommandFailed(status);
  DeviceFailureTracker tracker;
  if (sim) {
    simulated.board_distance_m = distance_mm * 1e-3;
    simulated.beam_radius_m = beam_radius_mm * 1e-3;
    simulated.shortest_exposure_us =
        sim_laser_power > 0 ? 20 / sim_laser_power
        : plan_exposures    ? 20
                            : *std::min_element(session.exposure_times_us.begin(), session.exposure_times_us.end());
    std::unique_ptr<SimLaserLobeRig> rig;
    status = SimLaserLobeRig::Create(simulated, &rig);
    if (!status.ok()) return CommandFailed(status);
    session.sync = SyncForSensor(session.sync, simulated.sensor);
    TeeProjector tee_projector(rig->flat_source(), devices.window.get());
    TeeLaser tee_laser(rig->laser(), devices.laser.get());
    TrackedProjector flat(devices.window ? static_cast<Projector*>(&tee_projector) : rig->flat_source(),
                          devices.window ? devices.display_name : "flat-field source (sim)", &tracker);
    TrackedLaser laser(devices.laser ? static_cast<Laser*>(&tee_laser) : rig->laser(),
                       devices.laser ? devices.laser_name : "laser (sim)", &tracker);
    const SampleChanger change = rig->sample_changer();
    if (plan_exposures) {
      status =
          PlanLaserBracket(common, laser_plan, rig->rig_info(), session, rig->camera(), &laser, &flat, change, &plan);
      if (!status.ok()) return CommandFailed(status);
    }
    const int planned = static_cast<int>(PlanLaserLobeSession(session, flat.refresh_period_s()).size());
    return Finish("laser", common, plan, planned, MakeHeader(name, "laser_lobe", rig->rig_info(), true), rig->camera(),
                  "sim",
                  [&](Camera* camera, SessionWriter* writer) {
                    return RunLaserLobeSession(session, camera, &laser, &flat, change, writer);
                  },
                  &tracker, dynamic_cast<SimBoardCamera*>(rig->camera()));
  }
  if (!devices.laser) return CommandFailed(Status::Error("thinslab acquire laser: a real camera needs --laser <spec>"));
  if (session.capture_flat && !devices.window) {
    return CommandFailed(
        Status::Error("thinslab acquire laser: --capture-flat needs --display <n> (the flat-field source); "
                      "or give --capture-flat false"));
  }
  RigInfo rig;
  status = RealRig(common, devices.camera->info(), &rig);
  if (!status.ok()) return CommandFailed(status);
  rig.laser.present = true;
  rig.laser.beam_radius_m = common.beam_radius_mm * 1e-3;
  rig.laser.wavelength_m = common.wavelength_nm * 1e-9;
  rig.laser.origin_in_sample = Eigen::Vector3d(0, 0, 0.5);
  // No flat-field source: ShowPattern("") only (the script shows "" when capture_flat is off).
  class NoProjector : public Projector {
   public:
    Status ShowPattern(const std::string& pattern) override {
      if (pattern.empty()) return Status::Ok();
      return Status::Error("flat-field source: none given (--display)");
    }
  } none;
  TrackedProjector flat(devices.window ? static_cast<Projector*>(devices.window.get()) : &none,
                        devices.window ? devices.display_name : "flat-field source", &tracker);
  TrackedLaser laser(devices.laser.get(), devices.laser_name, &tracker);
  const SampleChanger change = OperatorSampleChanger();
  if (plan_exposures) {
    status = PlanLaserBracket(common, laser_plan, rig, session, devices.camera.get(), &laser, &flat, change, &plan);
    if (!status.ok()) return CommandFailed(status);
  }
  const int planned = static_cast<int>(PlanLaserLobeSession(session, flat.refresh_period_s()).size());
  return Finish("laser", common, plan, planned, MakeHeader(common.name.empty() ? "laser_lobe" : common.name,
                                                           "laser_lobe", rig, false),
                devices.camera.get(), common.camera,
                [&](Camera* camera, SessionWriter* writer) {
                  return RunLaserLobeSession(session, camera, &laser, &flat, change, writer);
                },
                &tracker);
}

// Options shared by dot-scan and bracket: the bracket and the synchronisation rule.
void AddBracketOptions(OptionParser* parser, ExposureBracketOptions* bracket, std::string* exposures) {
  parser->AddString("exposures-us", exposures,
                    "exposures, comma-separated [us] (default: geometric min..max); auto = planned from a probe of "
                    "the rig within min..max (bracket, gamma: one refresh period .. 10 s unless given)");
  parser->AddDouble("min-exposure-us", &bracket->min_exposure_us, "shortest exposure of the geometric bracket [us]");
  parser->AddDouble("max-exposure-us", &bracket->max_exposure_us, "longest exposure of the geometric bracket [us]");
  parser->AddInt("exposure-steps", &bracket->steps, "exposures in the geometric bracket");
}

// The simulated monitor of `thinslab acquire` is a real-looking display, not the ideal linear
// one of the synthetic sessions: a "gamma 2.2" curve, 8-bit drive and 0.2 % of full light at
// drive 0 (a 500:1 panel), so that `acquire gamma` has something to measure and --gamma-table
// something to correct (docs/drivers.md, "Gamma").
struct SimDisplayText {
  std::string transfer = "power:2.2/8bit";
  double black_fraction = 0.002;
  std::string sensor_response = "linear";  // The camera's tone curve (sim/sensor_model.h).
};

void AddSimMonitorOptions(OptionParser* parser, SimDotMonitorOptions* monitor, SimDisplayText* display) {
  parser->AddString("sim-display-transfer", &display->transfer,
                    "simulated display curve: linear, power:<exponent> or srgb, optionally /<n>bit drive quantisation");
  parser->AddDouble("sim-display-black", &display->black_fraction,
                    "light the simulated display emits at drive 0, as a fraction of full light [0, 1)");
  parser->AddString("sensor-response", &display->sensor_response,
                    "simulated camera response: linear, gamma or s_curve (sim/sensor_model.h)");
  parser->AddInt("monitor-width-px", &monitor->monitor_width_px, "simulated monitor width [px]");
  parser->AddInt("monitor-height-px", &monitor->monitor_height_px, "simulated monitor height [px]");
  parser->AddDouble("dot-radiance", &monitor->dot_radiance, "radiance of a lit monitor pixel (relative)");
  parser->AddInt("camera-width-px", &monitor->camera_width_px, "simulated camera width [px]");
  parser->AddInt("camera-height-px", &monitor->camera_height_px, "simulated camera height [px]");
  parser->AddBool("noise", &monitor->sensor.enable_noise, "simulate shot and read noise");
  parser->AddUint64("seed", &monitor->seed, "seed of the sensor noise");
  AddSimExposureStepOption(parser, &monitor->sensor);
}

Status ApplySimDisplay(const SimDisplayText& display, SimDotMonitorOptions* monitor) {
  THINSLAB_RETURN_IF_ERROR(CheckSimExposureStep(monitor->sensor));
  THINSLAB_RETURN_IF_ERROR(ParseSimDisplayTransfer(display.transfer, "sim-display-transfer", &monitor->display_transfer));
  if (!(display.black_fraction >= 0 && display.black_fraction < 1)) {
    return Status::Error("thinslab acquire: option --sim-display-black = " + std::to_string(display.black_fraction) +
                         ": expected a fraction in [0, 1)");
  }
  monitor->black_radiance = display.black_fraction * monitor->dot_radiance;
  if (display.sensor_response == "linear") {
    monitor->sensor.response = SimResponseCurve::kLinear;
  } else if (display.sensor_response == "gamma") {
    monitor->sensor.response = SimResponseCurve::kGamma;
  } else if (display.sensor_response == "s_curve") {
    monitor->sensor.response = SimResponseCurve::kSCurve;
  } else {
    return Status::Error("thinslab acquire: option --sensor-response = '" + display.sensor_response +
                         "': expected linear, gamma or s_curve");
  }
  return Status::Ok();
}

enum class DisplayKind { kDotScan, kBracket, kGamma };

// dot-scan, bracket and gamma: display-driven, synchronised sessions.
int AcquireDisplaySession(int argc, char** argv, bool sim, DisplayKind which) {
  const bool dot_scan = which == DisplayKind::kDotScan, gamma = which == DisplayKind::kGamma;
  const std::string kind = dot_scan ? "dot-scan" : gamma ? "gamma" : "bracket";
  CommonOptions common;
  SimDotMonitorOptions monitor;
  SimDisplayText sim_display;
  DotScanSessionOptions dots;
  int validation_dots = 0;  // DotScanValidationDots of the grid (dot-scan only).
  // --exposures-us auto: at most this many frames at the longest exposure. 4 took the 0.2 %
  // black display's 10 x 10 scan from 36 to 64 points ok (74 on a black one), 16 to 65 at four
  // times the session time (docs/acquisition.md, "Exposure planning").
  int max_longest_frames = 4;
  BracketSessionOptions bracket_session;
  DisplayGammaSessionOptions gamma_session;
  ExposureBracketOptions& bracket = dot_scan ? dots.bracket : gamma ? gamma_session.bracket : bracket_session.bracket;
  DisplaySyncOptions& sync = dot_scan ? dots.sync : gamma ? gamma_session.sync : bracket_session.sync;
  if (gamma) {
    // Level 1 fills ~40 % of full well in one refresh period (the shortest exposure); exposures
    // 1, 4 and 16 periods bring level 1/16 of a gamma 2.2 display to ~1.4 % of full well.
    monitor.dot_radiance = 0.05;
    bracket.min_exposure_us = 1e6 / 85;
    bracket.max_exposure_us = 16e6 / 85;
    bracket.steps = 3;
  } else if (dot_scan) {
    // A dot's peak pixel then collects ~40 % of full well in one refresh period, so the shortest
    // exposure of the bracket (and the all-dots frame) is unsaturated for `calib dots`.
    monitor.dot_radiance = 0.05;
  } else {
    // The simulated monitor's flat field fills ~5 % of full well in one refresh period.
    monitor.dot_radiance = 0.005;
    bracket.min_exposure_us = 10000;
    bracket.max_exposure_us = 160000;
    bracket.steps = 5;
  }
  std::string name = dot_scan ? "dot_scan" : gamma ? "display_gamma" : "exposure_bracket", exposures;
  bool sim_sample = false;
  SyntheticDotScanOptions sample_sim;  // --sim-sample: the sample and its truth (sim/synthesize_dot_scan_session.h).
  int sim_photons_k = static_cast<int>(sample_sim.sample.photons_per_region / 1000);
  OptionParser parser("acquire " + kind);
  AddCommonOptions(&parser, &common, sim);
  if (sim) {
    parser.AddString("name", &name, "session name");
    AddSimMonitorOptions(&parser, &monitor, &sim_display);
  }
  AddBracketOptions(&parser, &bracket, &exposures);
  AddSyncOptions(&parser, &sync);
  if (dot_scan) {
    parser.AddInt("grid-nx", &dots.grid_nx, "dots per row");
    parser.AddInt("grid-ny", &dots.grid_ny, "dot rows");
    parser.AddDouble("margin-fraction", &dots.margin_fraction, "monitor fraction left free on each side");
    parser.AddInt("validation-dots", &validation_dots,
                  "dots at grid-cell centres captured after the grid as validation frames (not fitted)");
    parser.AddBool("capture-all-dots", &dots.capture_all_dots, "capture the all-dots frame without sample");
    parser.AddBool("capture-dark", &dots.capture_dark, "capture a dark bracket with the sample");
    parser.AddString("sample-state", &dots.sample_state, "sample state of the dot frames");
    parser.AddInt("longest-exposure-frames", &dots.longest_exposure_frames,
                  "frames of every dot and of the dark bracket at the longest exposure (averaged: a glowing display "
                  "black's shot noise falls as 1/sqrt(frames)); with --exposures-us auto the plan chooses");
    parser.AddInt("max-longest-exposure-frames", &max_longest_frames,
                  "--exposures-us auto: most frames the plan may take at the longest exposure");
    if (sim) {
      parser.AddBool("sim-sample", &sim_sample, "put the region sample of `thinslab sim dot-scan` in the simulated "
                                                "light path (Monte Carlo tables; writes ground_truth/)");
      parser.AddInt("sim-photons-k", &sim_photons_k, "--sim-sample: Monte Carlo photons per rough region, thousands");
    }
  } else if (gamma) {
    parser.AddInt("steps", &gamma_session.steps, "drive levels 0, 1/steps, ..., 1");
    parser.AddInt("repeats", &gamma_session.repeats, "measurements of every level, each repeat in a new random order");
    parser.AddUint64("order-seed", &gamma_session.order_seed, "seed of the level order");
    parser.AddInt("dark-frames", &gamma_session.dark_frames, "dark (display black) frames per exposure");
  } else {
    parser.AddString("pattern", &bracket_session.pattern, "pattern of the bracket frames (drivers/pattern_id.h)");
    parser.AddBool("capture-dark", &bracket_session.capture_dark, "also capture a dark bracket");
    parser.AddInt("frames-per-exposure", &bracket_session.frames_per_exposure, "frames per exposure");
  }
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  const bool plan_exposures = exposures == "auto";
  // bracket and gamma plan within the bracket options only where given (their defaults are the
  // fixed bracket's ends): else from one refresh period to 10 s.
  const double plan_min_us = parser.IsSet("min-exposure-us") ? bracket.min_exposure_us : 0;
  const double plan_max_us = parser.IsSet("max-exposure-us") ? bracket.max_exposure_us : 1e7;
  if (status.ok() && !exposures.empty() && !plan_exposures) {
    status = ParseExposureList(exposures, "exposures-us", &bracket.exposures_us);
  }
  if (status.ok() && plan_exposures && dots.longest_exposure_frames != 1) {
    status = Status::Error(
        "thinslab acquire dot-scan: option --longest-exposure-frames: with --exposures-us auto the "
        "plan chooses the frames (within --max-longest-exposure-frames); give one or the other");
  }
  if (status.ok() && dot_scan && (max_longest_frames < 1 || max_longest_frames > 1000)) {
    status = Status::Error("thinslab acquire dot-scan: option --max-longest-exposure-frames = " +
                           std::to_string(max_longest_frames) + ": expected 1..1000");
  }
  if (status.ok() && sim) status = ApplySimDisplay(sim_display, &monitor);
  if (status.ok() && gamma && !common.gamma_table.empty()) {
    status = Status::Error("thinslab acquire gamma: option --gamma-table: the gamma measurement drives the display "
                           "through the identity table; give the table to the other kinds");
  }
  if (!status.ok()) return CommandFailed(status);
  sync.max_retries = common.max_retries;
  std::string plan = PlanText(kind, parser.ToIni());

  RealDevices devices;
  status = OpenRealDevices(common, &devices);
  if (!status.ok()) return CommandFailed(status);
  DeviceFailureTracker tracker;
  std::unique_ptr<SimDotMonitor> sim_monitor;
  Projector* display = nullptr;
  Camera* camera = nullptr;
  RigInfo rig;
  SampleChanger change;
  std::shared_ptr<const SlabSample> sample;
  if (sim && sim_sample) {
    if (sim_photons_k < 1)
      return CommandFailed(Status::Error("thinslab acquire: option --sim-photons-k: must be >= 1"));
    monitor.gamma_table = devices.gamma_table;
    sample_sim.rig = monitor;
    sample_sim.sample.photons_per_region = static_cast<int64_t>(sim_photons_k) * 1000;
    sample_sim.name = name;
    status = BuildDotScanRig(sample_sim, &sim_monitor, &sample);
    if (!status.ok()) return CommandFailed(status);
    display = sim_monitor.get();
    camera = sim_monitor->camera();
    rig = sim_monitor->rig();
    // The sample rectangle and the truth's grid, as `thinslab sim dot-scan` records them.
    rig.sample.region_min_m = sample->options().min_m;
    rig.sample.region_max_m = sample->options().max_m;
    rig.sample.pixel_pitch_m = sample_sim.truth_pitch_m;
    rig.sample.glass_ior = sample->options().regions.front().material.eta;
    change = sim_monitor->sample_changer();
    sync = SyncForSensor(sync, monitor.sensor);
  } else if (sim) {
    monitor.gamma_table = devices.gamma_table;
    status = SimDotMonitor::Create(monitor, &sim_monitor);
    if (!status.ok()) return CommandFailed(status);
    display = sim_monitor.get();
    camera = sim_monitor->camera();
    rig = sim_monitor->rig();
    if (!(rig.sample.pixel_pitch_m > 0)) {
      // The simulated monitor rig leaves the sample region to the session: the screen's
      // footprint around the sample origin, at the monitor's pixel pitch.
      const double half_w = 0.5 * monitor.monitor_width_px * monitor.monitor_pixel_pitch_m;
      const double half_h = 0.5 * monitor.monitor_height_px * monitor.monitor_pixel_pitch_m;
      rig.sample.region_min_m = Eigen::Vector2d(-half_w, -half_h);
      rig.sample.region_max_m = Eigen::Vector2d(half_w, half_h);
      rig.sample.pixel_pitch_m = monitor.monitor_pixel_pitch_m;
    }
    change = AnySampleState();
    sync = SyncForSensor(sync, monitor.sensor);
  } else {
    if (!devices.window)
      return CommandFailed(Status::Error("thinslab acquire " + kind + ": a real camera needs --display <n>"));
    display = devices.window.get();
    camera = devices.camera.get();
    status = RealRig(common, camera->info(), &rig);
    if (!status.ok()) return CommandFailed(status);
    change = OperatorSampleChanger();
    if (!common.name.empty()) name = common.name;
  }
  TeeProjector tee(display, devices.window.get());
  const bool teed = sim && devices.window;
  TrackedProjector projector(teed ? static_cast<Projector*>(&tee) : display,
                             devices.window ? devices.display_name : "monitor (sim)", &tracker);
  if (dot_scan) {
    dots.monitor_width_px = sim ? monitor.monitor_width_px : devices.window_width;
    dots.monitor_height_px = sim ? monitor.monitor_height_px : devices.window_height;
    if (validation_dots < 0 || validation_dots > 10000) {
      return CommandFailed(Status::Error("thinslab acquire dot-scan: --validation-dots must be in [0, 10000], got " +
                                         std::to_string(validation_dots)));
    }
    dots.validation_dots_px = DotScanValidationDots(dots, validation_dots);
  }
  std::string error;
  const bool checked = dot_scan ? dots.Check(&error) : gamma ? gamma_session.Check(&error) : bracket_session.Check(&error);
  if (!checked) return CommandFailed(Status::Error(error));
  // After the checks: the probe's dots come from the grid.
  if (plan_exposures) {
    status = dot_scan ? PlanDotScanBracket(common, dots, max_longest_frames, camera, &projector, change,
                                           display->refresh_period_s(), &plan)
             : gamma  ? PlanCalibrationBracket(
                            common,
                            [&](const ExposurePlanOptions& options, ExposurePlan* result) {
                             return ProbeAndPlanDisplayGammaExposures(camera, &projector, change, gamma_session.steps,
                                                                       options, result);
                           },
                            plan_min_us, plan_max_us, &gamma_session.bracket, &plan)
                     : PlanCalibrationBracket(
                           common,
                           [&](const ExposurePlanOptions& options, ExposurePlan* result) {
                             return ProbeAndPlanResponseBracket(camera, &projector, change, bracket_session.pattern,
                                                                options, ResponseBracketPlanOptions(), result);
                           },
                           plan_min_us, plan_max_us, &bracket_session.bracket, &plan);
    if (!status.ok()) return CommandFailed(status);
  }
  const double period = display->refresh_period_s();
  const int planned = static_cast<int>(dot_scan ? PlanDotScan(dots, period).size()
                                       : gamma  ? PlanDisplayGammaSession(gamma_session, period).size()
                                                : PlanBracketSession(bracket_session, period).size());
  const std::string session_kind = dot_scan ? "dot_scan" : gamma ? "display_gamma" : "exposure_bracket";
  const int session_exit_code = Finish(
      kind, common, plan, planned, MakeHeader(name, session_kind, rig, sim), camera, sim ? "sim" : common.camera,
      [&](Camera* cam, SessionWriter* writer) {
        return dot_scan ? RunDotScanSession(dots, cam, &projector, change, writer)
               : gamma  ? RunDisplayGammaSession(gamma_session, cam, &projector, change, writer)
                        : RunBracketSession(bracket_session, cam, &projector, change, writer);
      },
      &tracker);
  // The truth of --sim-sample, once the capture is complete (not before: a new session's folder
  // must be empty when the acquisition starts).
  if (session_exit_code == 0 && sample && !FileExists(JoinPath(common.out, "ground_truth/truth.json"))) {
    const Status truth = WriteDotScanTruth(sample_sim, *sample, *sim_monitor, 0, common.out);
    if (!truth.ok()) return CommandFailed(truth);
  }
  return session_exit_code;
}

int FoldJournal(int argc, char** argv) {
  std::string session_dir;
  OptionParser parser("acquire fold-journal");
  parser.AddPositional("OUTPUT", &session_dir, "session folder of a running-then-killed or ended `thinslab acquire`");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  JournalFoldResult fold;
  if (status.ok()) status = FoldJournalIntoManifest(session_dir, &fold);
  if (!status.ok()) return CommandFailed(status);
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (fold.folded_frames == 0) {
    std::cout << manifest << ": already holds every journaled frame (" << fold.frames << "); nothing written\n";
  } else {
    std::cout << manifest << ": " << fold.folded_frames << " frames folded in from " << kSessionJournalName << " ("
              << fold.frames << " in all; state '" << fold.state << "' kept)\n";
  }
  return 0;
}

// The camera option decides whether the simulated rig's options apply (their --help too).
// The camera decides which options the command has (a simulated rig's or a real one's): its
// --camera, from the command line or the --config file, is read first.
bool SimulatedCamera(const std::string& command, int argc, char** argv) {
  std::string camera = "sim";
  OptionParser::PeekValue(command, argc, argv, "camera", &camera);
  return camera == "sim";
}
int AcquireShadowMapsCommand(int argc, char** argv) {
  return AcquireShadowMaps(argc, argv, SimulatedCamera("acquire shadow-maps", argc, argv));
}
int AcquireLaserCommand(int argc, char** argv) {
  return AcquireLaser(argc, argv, SimulatedCamera("acquire laser", argc, argv));
}
int AcquireDotScanCommand(int argc, char** argv) {
  return AcquireDisplaySession(argc, argv, SimulatedCamera("acquire dot-scan", argc, argv), DisplayKind::kDotScan);
}
int AcquireBracketCommand(int argc, char** argv) {
  return AcquireDisplaySession(argc, argv, SimulatedCamera("acquire bracket", argc, argv), DisplayKind::kBracket);
}
int AcquireGammaCommand(int argc, char** argv) {
  return AcquireDisplaySession(argc, argv, SimulatedCamera("acquire gamma", argc, argv), DisplayKind::kGamma);
}

}  // namespace

// `thinslab acquire preview` (issue #28, item 1): the live camera image in a window, saturated
// pixels red, the expected sample region outlined, a histogram and a focus bar
// (acquire/live_preview.h); one line of statistics per frame on stdout.
int AcquirePreview(int argc, char** argv) {
  CommonOptions common;
  double exposure_us = 10000;
  int frames = 0;
  std::string snapshot, rig_capture;
  OptionParser parser("acquire preview");
  parser.AddString("camera", &common.camera, "sim | aravis:<ip or device id> | v4l2:<device path>");
  parser.AddDouble("camera-timeout-s", &common.camera_timeout_s, "real cameras: connect and frame timeout [s]");
  parser.AddString("pixel-format", &common.pixel_format, "real cameras: pixel format (default: the driver's)");
  parser.AddDouble("gain-db", &common.gain_db, "Aravis: analogue gain [dB]");
  parser.AddInt("packet-size", &common.packet_size, "Aravis: GigE Vision packet size [bytes] (0: negotiate)");
  parser.AddDouble("exposure-us", &exposure_us, "exposure of the preview frames [us]");
  parser.AddInt("frames", &frames, "frames to show before exiting (0: until the window is closed, q or Ctrl-C)");
  parser.AddString("snapshot", &snapshot, "write the last picture, as the window shows it, to this PNG");
  parser.AddString("rig", &rig_capture, "outline the sample region of this capture's rig (its session.json)");
  parser.AddString("region-mm", &common.region_mm, "without --rig: sample region x0,y0,x1,y1 [mm] to outline");
  parser.AddDouble("board-distance-mm", &common.board_distance_mm, "without --rig: board distance [mm] (0: none)");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && (!(exposure_us > 0) || !std::isfinite(exposure_us))) {
    status = Status::Error("thinslab acquire preview: option --exposure-us must be > 0");
  }
  if (status.ok() && frames < 0) status = Status::Error("thinslab acquire preview: option --frames must be >= 0");
  if (status.ok() && !snapshot.empty()) status = CheckOutputFile(snapshot, {});
  if (!status.ok()) return CommandFailed(status);
#if THINSLAB_WITH_SDL
  RealDevices devices;
  status = OpenRealCamera(common, &devices);
  if (!status.ok()) return CommandFailed(status);
  std::unique_ptr<SimDotMonitor> sim_monitor;
  Camera* camera = devices.camera.get();
  RigInfo rig;
  if (common.camera == "sim") {
    // The simulated monitor rig showing a 10 x 10 grid of dots, its screen outlined.
    SimDotMonitorOptions monitor;
    monitor.dot_radiance = 0.05;  // As `acquire dot-scan`.
    DotScanSessionOptions dots;
    dots.grid_nx = dots.grid_ny = 10;
    dots.monitor_width_px = monitor.monitor_width_px;
    dots.monitor_height_px = monitor.monitor_height_px;
    status = SimDotMonitor::Create(monitor, &sim_monitor);
    if (status.ok()) status = sim_monitor->ShowPattern(DotScanGridPattern(dots));
    if (!status.ok()) return CommandFailed(status);
    camera = sim_monitor->camera();
    rig = sim_monitor->rig();
    const double half_w = 0.5 * monitor.monitor_width_px * monitor.monitor_pixel_pitch_m;
    const double half_h = 0.5 * monitor.monitor_height_px * monitor.monitor_pixel_pitch_m;
    rig.sample.region_min_m = Eigen::Vector2d(-half_w, -half_h);
    rig.sample.region_max_m = Eigen::Vector2d(half_w, half_h);
  } else {
    status = RealRig(common, camera->info(), &rig);
    if (!status.ok()) return CommandFailed(status);
  }
  CameraInfo geometry = camera->info();
  if (!rig_capture.empty()) {
    Session session;
    status = ReadSessionWithJournal(rig_capture, &session);
    if (!status.ok()) return CommandFailed(status.WithContext("option --rig"));
    rig = session.rig;
    if (rig.cameras.empty()) return CommandFailed(Status::Error("option --rig: " + rig_capture + " has no camera"));
    const CameraInfo& c = rig.cameras.front();
    if (c.width_px != geometry.width_px || c.height_px != geometry.height_px) {
      return CommandFailed(
          Status::Error("option --rig: camera '" + c.id + "' of " + rig_capture + " is " + std::to_string(c.width_px) +
                        " x " + std::to_string(c.height_px) + " px, camera " + common.camera + " delivers " +
                        std::to_string(geometry.width_px) + " x " + std::to_string(geometry.height_px)));
    }
    geometry.fx_px = c.fx_px, geometry.fy_px = c.fy_px, geometry.cx_px = c.cx_px, geometry.cy_px = c.cy_px;
    geometry.distortion = c.distortion;
    geometry.cam_from_sample = c.cam_from_sample;
  }
  double applied_us = 0;
  status = camera->SetExposure(exposure_us, &applied_us);
  if (!status.ok()) return CommandFailed(status.WithContext("camera " + common.camera));
  std::unique_ptr<PreviewWindow> window;
  status = OpenPreviewWindow(geometry.width_px, geometry.height_px + kPreviewHistogramHeight + kPreviewFocusBarHeight,
                             "thinslab preview: " + common.camera, &window);
  if (!status.ok()) return CommandFailed(status);
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
  double best_focus = 0;
  PreviewPicture picture;
  for (int k = 1; frames == 0 || k <= frames; ++k) {
    if (window->CloseRequested() || !StopReason().empty()) break;
    CapturedFrame frame;
    status = camera->Capture(&frame);
    if (!status.ok()) break;
    const PreviewStatistics statistics = MeasurePreview(frame.raw_dn, geometry);
    best_focus = std::max(best_focus, statistics.focus);
    picture = ComposePreview(frame.raw_dn, geometry, rig, statistics, best_focus);
    status = window->Show(picture.rgb);
    if (!status.ok()) break;
    std::cout << "preview frame " << k << " (" << applied_us << " us): " << statistics.Describe() << std::endl;
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!status.ok()) return CommandFailed(status.WithContext("camera " + common.camera));
  if (!snapshot.empty() && !picture.rgb.empty()) {
    std::vector<uint8_t> shown;
    status = window->ReadBack(&shown);
    cv::Mat bgr(window->height(), window->width(), CV_8UC3);
    if (status.ok()) {
      cv::Mat rgb(window->height(), window->width(), CV_8UC3, shown.data());
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      status = WritePngAtomically(snapshot, bgr);
    }
    if (!status.ok()) return CommandFailed(status.WithContext("option --snapshot"));
    std::cout << "wrote " << snapshot << " (the window as shown)\n";
  }
  return 0;
#else
  return CommandFailed(NotBuilt("acquire preview", "THINSLAB_WITH_SDL"));
#endif
}

const std::vector<Subcommand>& AcquireSubcommands() {
  static const std::vector<Subcommand> table = {
      {"shadow-maps", AcquireShadowMapsCommand, "OUTPUT", "shadow maps: projector patterns through the sample"},
      {"laser", AcquireLaserCommand, "OUTPUT", "laser lobes through the layer, exposure brackets"},
      {"dot-scan", AcquireDotScanCommand, "OUTPUT", "single monitor dots behind the sample (Dai et al. 2009)"},
      {"bracket", AcquireBracketCommand, "OUTPUT", "exposure brackets of display states (camera response)"},
      {"gamma", AcquireGammaCommand, "OUTPUT", "display drive levels for the display gamma table"},
      {"fold-journal", FoldJournal, "OUTPUT", "write the journaled frames of a killed capture into session.json"},
      {"preview", AcquirePreview, "", "live camera image: saturation, histogram, focus, the sample region outlined"},
  };
  return table;
}

int RunAcquire(int argc, char** argv) {
  return DispatchSubcommand("acquire", AcquireSubcommands(), argc, argv, "session kind",
                            "  options: [--camera sim|aravis:<ip>|v4l2:<device>] [--display <n>] [--laser <spec>]\n"
                            "           [--gamma-table <file>] [--resume]; <kind> --help lists a kind's options (and "
                            "its simulated rig's).\n");
}

}  // namespace thinslab
