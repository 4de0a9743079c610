// SPDX-License-Identifier: Apache-2.0
// `thinslab acquire` through the real binary: a session killed with SIGKILL mid-scan and
// resumed equals an uninterrupted run of the same seed, frame for frame and pixel for pixel;
// bad input (unknown kind or option, absent or unreachable devices, a non-empty folder) exits
// non-zero with one line naming the device, and leaves the session folder consistent.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/display_gamma.h"
#include "tests/testing/frame_record_matchers.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/xvfb_server.h"
#include "tests/testing/xwd_root.h"

extern char** environ;

namespace thinslab {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> Split(const std::string& args) {
  std::istringstream in(args);
  std::vector<std::string> out;
  std::string word;
  while (in >> word) out.push_back(word);
  return out;
}

// Frames on disk: the manifest's plus those journaled after its last write (the recovery rule
// of docs/format.md 10.2); 0 while the session does not exist yet.
int CountFrames(const std::string& session) {
  Session s;
  if (!ReadSessionWithJournal(session, &s).ok()) return 0;
  return static_cast<int>(s.frames.size());
}

// Starts `thinslab <args>` as a child process and returns once `min_frames` frames of `session`
// are on disk (or after 60 s); the child's pid, or -1.
pid_t SpawnUntil(const std::string& args, const std::string& session, int min_frames) {
  std::vector<std::string> words = Split(args);
  words.insert(words.begin(), ThinslabBinary());
  std::vector<char*> argv;
  for (auto& a : words) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (CountFrames(session) < min_frames && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return pid;
}

// SIGKILLs the child; returns the frames on disk after the kill (-1 if it had finished first).
int KillAndCount(pid_t pid, const std::string& session) {
  if (pid < 0) return -1;
  kill(pid, SIGKILL);
  int wstatus = 0;
  if (waitpid(pid, &wstatus, 0) != pid || !WIFSIGNALED(wstatus)) return -1;
  return CountFrames(session);
}

// Kills `thinslab <args>` once `min_frames` frames are on disk; the frames on disk after it.
int RunAndKillAfter(const std::string& args, const std::string& session, int min_frames) {
  return KillAndCount(SpawnUntil(args, session, min_frames), session);
}

// Lines of the output that start with "error: ". SDL's own stderr message about a missing
// XDG_RUNTIME_DIR (it probes Wayland before X11) is not thinslab's and is not counted.
int ErrorLines(const std::string& output) {
  int n = 0;
  std::istringstream in(output);
  std::string line;
  while (std::getline(in, line)) {
    n += line.rfind("error: ", 0) == 0 && line.find("XDG_RUNTIME_DIR") == std::string::npos;
  }
  return n;
}

class CliAcquireTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    ASSERT_EQ(RunThinslab("sim pattern " + *dir_ / "small.exr" + " --width-px 24 --height-px 24").exit_code, 0);
  }
  static void TearDownTestSuite() { delete dir_; }

  // A small simulated shadow-map acquisition; --sim-realtime makes every capture take its
  // exposure time, as at a real rig, so there is time to kill it mid-scan.
  static std::string ShadowArgs(const std::string& out, int exposure_us = 40000) {
    return "acquire shadow-maps --quiet --tau " + *dir_ / "small.exr" +
           " --camera-width-px 160 --camera-height-px 120 --photons 4000 --frames 8 --dark-frames 2"
           " --exposure-us " + std::to_string(exposure_us) + " --sim-realtime --seed 7 " + out;
  }
  static constexpr int kPlannedFrames = 2 + 2 * 8;

  void ExpectDeviceError(const std::string& args, const std::vector<std::string>& named, const std::string& out) {
    const RunResult r = RunThinslab(args);
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_EQ(ErrorLines(r.output), 1) << r.output;
    for (const auto& piece : named) {
      EXPECT_NE(r.output.find(piece), std::string::npos) << "'" << piece << "' not in: " << r.output;
    }
    EXPECT_FALSE(fs::exists(out)) << "a device that cannot be opened must leave no session folder";
  }

  static TempDir* dir_;
};

TempDir* CliAcquireTest::dir_ = nullptr;

TEST_F(CliAcquireTest, KilledMidScanAndResumedEqualsAnUninterruptedRun) {
  const std::string reference = *dir_ / "reference", resumed = *dir_ / "resumed";
  const RunResult ref = RunThinslab(ShadowArgs(reference));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;

  // The same acquisition as a child process, killed once 12 frames are on disk: the darks,
  // the clean references and the first contaminated frames.
  const int frames_at_kill = RunAndKillAfter(ShadowArgs(resumed), resumed, 12);
  ASSERT_GE(frames_at_kill, 12) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, kPlannedFrames) << "killed too late to test a resume";
  Session killed;
  ASSERT_TRUE(ReadSession(resumed, &killed).ok());  // Consistent even when killed.
  EXPECT_EQ(killed.acquisition.state, "running");
  // The manifest is rewritten at bounded intervals (32 frames at first): the frames after its
  // last write are in journal.log only, which is what the resume must recover.
  EXPECT_LT(killed.frames.size(), static_cast<size_t>(frames_at_kill));
  // `info` reads through the journal and says the capture is incomplete.
  const RunResult info = RunThinslab("info " + resumed);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("Frames: " + std::to_string(frames_at_kill) + " "), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("Capture: INCOMPLETE (state running"), std::string::npos) << info.output;
  // A fit refuses the incomplete capture, naming the way on; --allow-incomplete fits the frames
  // it has (journaled ones included) and says so in summary.json.
  const RunResult fit_refused = RunThinslab("fit tau " + resumed + " --out " + *dir_ / "fit_killed");
  EXPECT_NE(fit_refused.exit_code, 0);
  EXPECT_NE(fit_refused.output.find("the capture did not complete"), std::string::npos) << fit_refused.output;
  EXPECT_NE(fit_refused.output.find("--allow-incomplete"), std::string::npos) << fit_refused.output;
  EXPECT_FALSE(fs::exists(*dir_ / "fit_killed"));
  const RunResult fit_partial =
      RunThinslab("fit tau " + resumed + " --allow-incomplete --out " + *dir_ / "fit_killed");
  ASSERT_EQ(fit_partial.exit_code, 0) << fit_partial.output;
  EXPECT_NE(fit_partial.output.find("warning: "), std::string::npos) << fit_partial.output;
  std::string summary_text;
  ASSERT_TRUE(ReadFileToString(*dir_ / "fit_killed/summary.json", &summary_text).ok());
  const nlohmann::json capture = nlohmann::json::parse(summary_text)["capture"];
  EXPECT_EQ(capture["complete"], false);
  EXPECT_EQ(capture["state"], "running");
  EXPECT_EQ(capture["usable_frames"], frames_at_kill);
  EXPECT_EQ(capture["journaled_frames"], frames_at_kill - static_cast<int>(killed.frames.size()));

  // Without --resume the folder is refused; with it the scan completes.
  const RunResult refused = RunThinslab(ShadowArgs(resumed));
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("--resume"), std::string::npos) << refused.output;
  const RunResult again = RunThinslab(ShadowArgs(resumed) + " --resume");
  ASSERT_EQ(again.exit_code, 0) << again.output;

  Session a, b;
  ASSERT_TRUE(ReadSession(reference, &a).ok());
  ASSERT_TRUE(ReadSession(resumed, &b).ok());
  ASSERT_EQ(a.frames.size(), static_cast<size_t>(kPlannedFrames));
  ASSERT_EQ(b.frames.size(), a.frames.size()) << "frames lost or duplicated";
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const FrameRecord& fa = a.frames[i];
    const FrameRecord& fb = b.frames[i];
    ExpectSamePlannedFrame(fa, fb);
    // The simulated camera counts captures, and the resumed one continues the count.
    ASSERT_TRUE(fb.camera_frame_id.has_value());
    EXPECT_EQ(fa.camera_frame_id, fb.camera_frame_id);
    EXPECT_TRUE(fb.camera_timestamp_ns.has_value());
    Image ia, ib;
    ASSERT_TRUE(LoadFrame(reference, a, fa, &ia).ok());
    ASSERT_TRUE(LoadFrame(resumed, b, fb, &ib).ok());
    EXPECT_TRUE(ia.data() == ib.data()) << "pixel data of frame " << fa.index << " differs";
  }
  EXPECT_EQ(b.acquisition.state, "complete");
  const RunResult info_complete = RunThinslab("info " + resumed);
  EXPECT_NE(info_complete.output.find("Capture: complete"), std::string::npos) << info_complete.output;
  std::vector<std::string> events;
  for (const auto& e : b.acquisition.events) events.push_back(e.event);
  EXPECT_EQ(events, (std::vector<std::string>{"started", "resumed", "completed"}));
  EXPECT_NE(b.acquisition.events[1].message.find("killed"), std::string::npos) << b.acquisition.events[1].message;
  EXPECT_EQ(b.acquisition.camera_captures, a.acquisition.camera_captures);
  // No temporary left behind by the killed write.
  for (const auto& entry : fs::recursive_directory_iterator(resumed)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
  // A complete session resumes to nothing.
  const RunResult nothing = RunThinslab(ShadowArgs(resumed) + " --resume");
  EXPECT_EQ(nothing.exit_code, 0) << nothing.output;
  EXPECT_NE(nothing.output.find("already complete"), std::string::npos) << nothing.output;
  // Resuming with other options is refused, naming the plan.
  const RunResult other = RunThinslab(ShadowArgs(resumed) + " --resume --frames 9");
  EXPECT_NE(other.exit_code, 0);
  EXPECT_NE(other.output.find("acquisition.plan"), std::string::npos) << other.output;
}

TEST_F(CliAcquireTest, FoldJournalWritesAKilledCapturesFramesAndARunningCaptureKeepsOthersOut) {
  const std::string session = *dir_ / "folded";
  // 800 ms exposures: 18 frames take ~15 s, time to try the folder while the capture runs (at 300 ms
  // a slow machine under the sanitizers finished the capture before the kill).
  const pid_t pid = SpawnUntil(ShadowArgs(session, 800000), session, 4);
  ASSERT_GT(pid, 0);
  const std::string in_use = "in use by another thinslab acquire (process " + std::to_string(pid) + ")";
  const RunResult fold_running = RunThinslab("acquire fold-journal " + session);
  EXPECT_NE(fold_running.exit_code, 0);
  EXPECT_NE(fold_running.output.find(in_use), std::string::npos) << fold_running.output;
  const RunResult resume_running = RunThinslab(ShadowArgs(session, 800000) + " --resume");
  EXPECT_NE(resume_running.exit_code, 0);
  EXPECT_NE(resume_running.output.find(in_use), std::string::npos) << resume_running.output;
  // `info` tells a capture in progress from a killed one (both are state "running").
  const RunResult info_running = RunThinslab("info " + session);
  EXPECT_NE(info_running.output.find("Writer: thinslab acquire (process " + std::to_string(pid) + ") is capturing"),
            std::string::npos)
      << info_running.output;
  const int frames_at_kill = KillAndCount(pid, session);
  const RunResult info_killed = RunThinslab("info " + session);
  EXPECT_NE(info_killed.output.find("Writer: none"), std::string::npos) << info_killed.output;
  ASSERT_GE(frames_at_kill, 4) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, kPlannedFrames);

  Session manifest_only;
  ASSERT_TRUE(ReadSession(session, &manifest_only).ok());
  ASSERT_LT(manifest_only.frames.size(), static_cast<size_t>(frames_at_kill)) << "nothing left to fold";
  std::string journal_before;
  ASSERT_TRUE(ReadFileToString(session + "/journal.log", &journal_before).ok());
  const RunResult fold = RunThinslab("acquire fold-journal " + session);
  ASSERT_EQ(fold.exit_code, 0) << fold.output;
  const int folded = frames_at_kill - static_cast<int>(manifest_only.frames.size());
  EXPECT_NE(fold.output.find(std::to_string(folded) + " frames folded in from journal.log (" +
                             std::to_string(frames_at_kill) + " in all; state 'running' kept)"),
            std::string::npos)
      << fold.output;
  // session.json alone now has every frame the journal recorded, as the journal has them.
  Session folded_session, with_journal;
  ASSERT_TRUE(ReadSession(session, &folded_session).ok());
  ASSERT_TRUE(ReadSessionWithJournal(session, &with_journal).ok());
  ASSERT_EQ(folded_session.frames.size(), static_cast<size_t>(frames_at_kill));
  for (int i = 0; i < frames_at_kill; ++i) {
    ExpectSamePlannedFrame(with_journal.frames[i], folded_session.frames[i]);
    EXPECT_EQ(folded_session.frames[i].file, with_journal.frames[i].file);
    EXPECT_TRUE(FileExists(session + "/" + folded_session.frames[i].file)) << folded_session.frames[i].file;
  }
  EXPECT_EQ(folded_session.acquisition.state, "running");
  EXPECT_EQ(folded_session.acquisition.camera_captures, with_journal.acquisition.camera_captures);
  std::string journal_after;
  ASSERT_TRUE(ReadFileToString(session + "/journal.log", &journal_after).ok());
  // Kept, but for a last line the kill cut short (never a record).
  EXPECT_LE(journal_after.size(), journal_before.size());
  EXPECT_EQ(journal_before.substr(0, journal_after.size()), journal_after);
  const RunResult again = RunThinslab("acquire fold-journal " + session);
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("nothing written"), std::string::npos) << again.output;

  // The folded session resumes to the whole plan, nothing duplicated.
  const RunResult resumed = RunThinslab(ShadowArgs(session, 800000) + " --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  Session complete;
  ASSERT_TRUE(ReadSession(session, &complete).ok());
  EXPECT_EQ(complete.acquisition.state, "complete");
  ASSERT_EQ(complete.frames.size(), static_cast<size_t>(kPlannedFrames));
  for (int i = 0; i < kPlannedFrames; ++i) EXPECT_EQ(complete.frames[i].index, i);

  // Bad input: no session, and a session no acquisition wrote.
  const RunResult none = RunThinslab("acquire fold-journal " + *dir_ / "no_such_session");
  EXPECT_NE(none.exit_code, 0);
  EXPECT_NE(none.output.find("no_such_session: not a capture session (no session.json)"), std::string::npos)
      << none.output;
  EXPECT_FALSE(fs::exists(*dir_ / "no_such_session"));
  const RunResult sim = RunThinslab("sim shadow-maps " + *dir_ / "simulated" + " --tau " + *dir_ / "small.exr" +
                                    " --camera-width-px 160 --camera-height-px 120 --photons 4000 --frames 2 --dark-frames 1");
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const RunResult simulated = RunThinslab("acquire fold-journal " + *dir_ / "simulated");
  EXPECT_NE(simulated.exit_code, 0);
  EXPECT_NE(simulated.output.find("no \"acquisition\" record"), std::string::npos) << simulated.output;
  EXPECT_FALSE(fs::exists(*dir_ / "simulated/acquire.lock")) << "a refused fold must leave the folder as it was";
}

// Brightest 3x3 mean of an image and where it is.
Eigen::Vector2i Peak(const Image& image, double* peak) {
  Eigen::Vector2i at(0, 0);
  *peak = -1e30;
  for (int y = 1; y + 1 < image.height(); ++y) {
    for (int x = 1; x + 1 < image.width(); ++x) {
      double sum = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) sum += image.at(x + dx, y + dy);
      }
      if (sum / 9 > *peak) {
        *peak = sum / 9;
        at = Eigen::Vector2i(x, y);
      }
    }
  }
  return at;
}

double MeanOf(const Image& image) {
  double sum = 0;
  for (float v : image.data()) sum += v;
  return sum / static_cast<double>(image.data().size());
}

// The resumed session has the uninterrupted run's frame list (kinds, light, exposures, files,
// statuses; not timestamps or noise) and nothing else in frames/; every frame shows the same
// light up to noise: the same mean and, for frames of `spot_kind` (a dot, the laser lobe), the
// same brightest 3x3 spot in the same place.
void ExpectTheFramesOfTheUninterruptedRun(const std::string& reference, const std::string& resumed, int planned,
                                          const std::string& spot_kind, Session* b) {
  Session a;
  ASSERT_TRUE(ReadSession(reference, &a).ok());
  ASSERT_TRUE(ReadSession(resumed, b).ok());
  ASSERT_EQ(a.frames.size(), static_cast<size_t>(planned));
  ASSERT_EQ(b->frames.size(), a.frames.size()) << "frames lost or duplicated";
  EXPECT_EQ(b->acquisition.state, "complete");
  int files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(resumed + "/frames")) files += entry.is_regular_file();
  EXPECT_EQ(files, planned) << "frames/ holds files no frame record names";
  for (size_t i = 0; i < a.frames.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const FrameRecord& fa = a.frames[i];
    const FrameRecord& fb = b->frames[i];
    ExpectSamePlannedFrame(fa, fb);
    EXPECT_TRUE(fb.camera_frame_id.has_value());
    Image ia, ib;
    ASSERT_TRUE(LoadFrame(reference, a, fa, &ia).ok());
    ASSERT_TRUE(LoadFrame(resumed, *b, fb, &ib).ok());
    const double mean_a = MeanOf(ia), mean_b = MeanOf(ib);
    EXPECT_NEAR(mean_b, mean_a, 0.05 * std::abs(mean_a) + 2) << fa.kind << " " << fa.sample_state;
    if (fa.kind == spot_kind) {
      double peak_a = 0, peak_b = 0;
      const Eigen::Vector2i at_a = Peak(ia, &peak_a), at_b = Peak(ib, &peak_b);
      EXPECT_LE((at_a - at_b).cwiseAbs().maxCoeff(), 1) << "the resumed frame's spot is elsewhere";
      EXPECT_NEAR(peak_b, peak_a, 0.1 * peak_a + 4);  // 4 DN: noise of a 3x3 mean of a faint spot.
    }
  }
}

Image LoadedFrame(const std::string& dir, const Session& session, int index) {
  Image image;
  EXPECT_TRUE(LoadFrame(dir, session, session.frames.at(index), &image).ok());
  return image;
}

// A display-synchronised dot scan killed mid-scan and resumed has the frame list of an
// uninterrupted run (kinds, patterns, dots, exposures, files, statuses; not the timestamps, nor
// the noise: the first frame after the resume needs a settle, so later captures draw other
// noise), each frame showing the same dot, and nothing else in frames/.
TEST_F(CliAcquireTest, DotScanKilledMidScanAndResumedHasTheFramesOfAnUninterruptedRun) {
  const std::string reference = *dir_ / "dots_reference", resumed = *dir_ / "dots_resumed";
  auto args = [](const std::string& out) {
    return "acquire dot-scan --quiet --camera-width-px 64 --camera-height-px 48 --monitor-width-px 64"
           " --monitor-height-px 64 --grid-nx 4 --grid-ny 4 --exposure-steps 2 --sim-realtime --seed 5 " + out;
  };
  constexpr int kPlanned = 2 + 2 + 4 * 4 * 2;
  const RunResult ref = RunThinslab(args(reference));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;

  const int frames_at_kill = RunAndKillAfter(args(resumed), resumed, 8);
  ASSERT_GE(frames_at_kill, 8) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, kPlanned) << "killed too late to test a resume";
  Session killed;
  ASSERT_TRUE(ReadSession(resumed, &killed).ok());
  EXPECT_EQ(killed.acquisition.state, "running");
  EXPECT_LT(killed.frames.size(), static_cast<size_t>(frames_at_kill)) << "the journal was not needed";
  // The session check of the killed capture says to resume before the sample leaves the rig.
  const RunResult check = RunThinslab("check " + resumed);
  EXPECT_EQ(check.exit_code, 3) << check.output;
  EXPECT_NE(check.output.find("retake [incomplete]: the acquisition did not finish"), std::string::npos) << check.output;
  const RunResult again = RunThinslab(args(resumed) + " --resume");
  ASSERT_EQ(again.exit_code, 0) << again.output;

  Session b;
  ExpectTheFramesOfTheUninterruptedRun(reference, resumed, kPlanned, "dot", &b);
  EXPECT_EQ(b.UsableFrames("dot", "contaminated").size(), 32u);
  // The camera was reopened for the resume: its ids restart, then increase again.
  for (size_t i = static_cast<size_t>(frames_at_kill) + 1; i < b.frames.size(); ++i) {
    EXPECT_GT(*b.frames[i].camera_frame_id, *b.frames[i - 1].camera_frame_id) << "frame " << i;
  }
  std::vector<std::string> events;
  for (const auto& e : b.acquisition.events) events.push_back(e.event);
  EXPECT_EQ(events, (std::vector<std::string>{"started", "resumed", "completed"}));
}

// A display gamma session killed mid-scan and resumed: the levels of each repeat are in a seeded
// random order, which the resume plans again from the seed; every frame must show the level of
// the uninterrupted run's frame (its mean within 5 %), so a resume that replanned another order,
// or skipped or repeated a level, fails.
TEST_F(CliAcquireTest, GammaSessionKilledMidScanAndResumedHasTheFramesOfAnUninterruptedRun) {
  const std::string reference = *dir_ / "gamma_reference", resumed = *dir_ / "gamma_resumed";
  auto args = [](const std::string& out) {
    return "acquire gamma --quiet --camera-width-px 64 --camera-height-px 48 --steps 8 --repeats 2"
           " --exposures-us 20000,80000 --dark-frames 1 --sim-realtime --seed 4 " + out;
  };
  constexpr int kPlanned = 2 * 1 + 2 * 9 * 2;  // Darks, then 2 repeats x 9 levels x 2 exposures.
  const RunResult ref = RunThinslab(args(reference));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;

  const int frames_at_kill = RunAndKillAfter(args(resumed), resumed, 14);
  ASSERT_GE(frames_at_kill, 14) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, kPlanned - 4) << "killed too late to test a resume";
  const RunResult again = RunThinslab(args(resumed) + " --resume");
  ASSERT_EQ(again.exit_code, 0) << again.output;

  Session b;
  ExpectTheFramesOfTheUninterruptedRun(reference, resumed, kPlanned, "", &b);
  // Every level was measured (above black, neighbouring levels' means differ by far more than
  // the 5 % the frame check allows).
  std::set<std::string> levels;
  for (const FrameRecord* f : b.UsableFrames("level")) levels.insert(f->light.projector_pattern);
  EXPECT_EQ(levels.size(), 9u);
  std::vector<std::string> events;
  for (const auto& e : b.acquisition.events) events.push_back(e.event);
  EXPECT_EQ(events, (std::vector<std::string>{"started", "resumed", "completed"}));
}

// A laser-lobe session killed while the laser is on (mid contaminated bracket) and resumed:
// the resumed run must switch the laser on again before its first frame, and change the sample
// for the clean bracket, though the steps that did so before the kill are skipped. Every frame
// has the planned light and the brightness of the uninterrupted run's (a lobe frame taken with
// the laser off would be as dark as a dark frame).
TEST_F(CliAcquireTest, LaserSessionKilledWithTheLaserOnAndResumedHasTheFramesOfAnUninterruptedRun) {
  const std::string reference = *dir_ / "laser_reference", resumed = *dir_ / "laser_resumed";
  auto args = [](const std::string& out) {
    return "acquire laser --quiet --camera-width-px 64 --camera-height-px 48 --photons 20000"
           " --exposures-us 20000,40000,80000 --frames-per-exposure 2 --capture-flat false --sim-realtime"
           " --seed 3 " + out;
  };
  constexpr int kPlanned = 3 * 3 * 2;  // Dark, contaminated and clean brackets.
  const RunResult ref = RunThinslab(args(reference));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;

  const int frames_at_kill = RunAndKillAfter(args(resumed), resumed, 8);
  ASSERT_GE(frames_at_kill, 8) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, 12) << "killed after the contaminated bracket: the laser-on resume is not tested";
  const RunResult again = RunThinslab(args(resumed) + " --resume");
  ASSERT_EQ(again.exit_code, 0) << again.output;

  Session b;
  ExpectTheFramesOfTheUninterruptedRun(reference, resumed, kPlanned, "laser", &b);
  // The peak check can tell: the lobe's spot is far brighter than the dark frame of its exposure.
  double lobe_peak = 0, dark_peak = 0;
  Peak(LoadedFrame(resumed, b, 6), &lobe_peak);
  Peak(LoadedFrame(resumed, b, 0), &dark_peak);
  EXPECT_GT(lobe_peak - dark_peak, 3 * (0.1 * lobe_peak + 4)) << "lobe " << lobe_peak << ", dark " << dark_peak;
  std::vector<std::string> events;
  for (const auto& e : b.acquisition.events) events.push_back(e.event);
  EXPECT_EQ(events, (std::vector<std::string>{"started", "resumed", "completed"}));
}

// An exposure bracket (dark then lit, display-synchronised) killed in its lit half and
// resumed, on a simulated camera that exposes whole 37 us steps: the frames are those of the
// uninterrupted run, and every frame records the exposure the camera applied (a multiple of
// 37 us, 1 us off the requested refresh multiple), not the one requested.
TEST_F(CliAcquireTest, BracketKilledMidScanAndResumedHasTheFramesOfAnUninterruptedRun) {
  const std::string reference = *dir_ / "bracket_reference", resumed = *dir_ / "bracket_resumed";
  auto args = [](const std::string& out) {
    return "acquire bracket --quiet --camera-width-px 64 --camera-height-px 48 --frames-per-exposure 2"
           " --sim-exposure-step-us 37 --sim-realtime --seed 6 " + out;
  };
  constexpr int kDark = 5 * 2, kPlanned = 2 * kDark;  // Default bracket: 5 exposures.
  const RunResult ref = RunThinslab(args(reference));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;

  const int frames_at_kill = RunAndKillAfter(args(resumed), resumed, kDark + 2);
  ASSERT_GE(frames_at_kill, kDark + 2) << "the acquisition finished before it could be killed";
  ASSERT_LT(frames_at_kill, kPlanned) << "killed too late to test a resume";
  const RunResult again = RunThinslab(args(resumed) + " --resume");
  ASSERT_EQ(again.exit_code, 0) << again.output;

  Session b;
  ExpectTheFramesOfTheUninterruptedRun(reference, resumed, kPlanned, "", &b);
  EXPECT_EQ(b.UsableFrames("bracket").size(), static_cast<size_t>(kDark));
  EXPECT_EQ(b.UsableFrames("dark").size(), static_cast<size_t>(kDark));
  const double refresh_us = 1e6 / 85;  // The simulated monitor's refresh period.
  for (const FrameRecord& f : b.frames) {
    const double steps = f.exposure_time_us / 37;
    EXPECT_NEAR(steps, std::round(steps), 1e-9) << "frame " << f.index << ": " << f.exposure_time_us << " us";
    const double periods = std::round(f.exposure_time_us / refresh_us);
    EXPECT_GT(std::abs(f.exposure_time_us - periods * refresh_us), 0.1) << "frame " << f.index << " has the request";
    EXPECT_LT(std::abs(f.exposure_time_us - periods * refresh_us), 18.5) << "frame " << f.index;
  }
  const RunResult zero_step = RunThinslab("acquire bracket --sim-exposure-step-us 0 " + *dir_ / "zero_step");
  EXPECT_NE(zero_step.exit_code, 0);
  EXPECT_NE(zero_step.output.find("--sim-exposure-step-us"), std::string::npos) << zero_step.output;
  EXPECT_FALSE(fs::exists(*dir_ / "zero_step"));
}

TEST_F(CliAcquireTest, UnknownKindAndOptionAreRefused) {
  RunResult r = RunThinslab("acquire holograms " + *dir_ / "h");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown session kind 'holograms'"), std::string::npos) << r.output;
  r = RunThinslab("acquire shadow-maps --frobnicate 3 " + *dir_ / "h");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--frobnicate"), std::string::npos) << r.output;
  r = RunThinslab("acquire shadow-maps --camera gopro:1 " + *dir_ / "h");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("gopro:1"), std::string::npos) << r.output;
  // (A bool option takes the next argument as its value when it is one: --resume goes after OUTPUT.)
  r = RunThinslab("acquire dot-scan " + *dir_ / "never_started" + " --resume");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("nothing to resume"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(*dir_ / "h"));
}

// Every kind keeps the display-camera synchronisation options (once dropped from shadow-maps
// by an edit of its exposure option, unnoticed), and the kinds that plan their exposures say so.
TEST_F(CliAcquireTest, EveryKindTakesTheSynchronisationOptions) {
  for (const char* kind : {"shadow-maps", "laser", "dot-scan", "bracket", "gamma"}) {
    const RunResult r = RunThinslab(std::string("acquire ") + kind + " --camera sim --help");
    EXPECT_EQ(r.exit_code, 0) << kind << ": " << r.output;
    for (const char* option : {"--settle-captures", "--max-sync-captures", "--min-change-dn", "--sync-read-noise-dn"}) {
      EXPECT_NE(r.output.find(option), std::string::npos) << kind << " lacks " << option;
    }
  }
  for (const char* kind : {"shadow-maps", "laser", "dot-scan"}) {
    const RunResult r = RunThinslab(std::string("acquire ") + kind + " --camera sim --help");
    EXPECT_NE(r.output.find("auto"), std::string::npos) << kind << ": " << r.output;
  }
}

TEST_F(CliAcquireTest, AbsentUsbLaserIsNamed) {
  ExpectDeviceError("acquire laser --laser hid-relay:dead:beef:1 " + *dir_ / "usb", {"dead:beef"}, *dir_ / "usb");
  ExpectDeviceError("acquire laser --laser hid-relay:zz " + *dir_ / "usb", {"hid-relay:zz"}, *dir_ / "usb");
}

TEST_F(CliAcquireTest, DisplayIndexOutOfRangeIsNamed) {
  // Under a private X server with one screen, so the window code reaches its range check.
  XvfbServer xvfb;
  std::string error;
  ASSERT_TRUE(xvfb.Start(160, 120, &error)) << error;
  const char* old_display = std::getenv("DISPLAY");
  const std::string saved_display = old_display ? old_display : "";
  setenv("DISPLAY", xvfb.display().c_str(), 1);
  ExpectDeviceError("acquire dot-scan --display 99 " + *dir_ / "disp", {"display 99", "out of range: 1 display"},
                    *dir_ / "disp");
  ExpectDeviceError("acquire dot-scan --display -4 " + *dir_ / "disp", {"--display"}, *dir_ / "disp");
  // Without an X server the error still names the display.
  unsetenv("DISPLAY");
  ExpectDeviceError("acquire dot-scan --display 99 " + *dir_ / "disp", {"display 99"}, *dir_ / "disp");
  if (old_display) setenv("DISPLAY", saved_display.c_str(), 1);
}

// `--gamma-table` reaches the real window: under a private Xvfb, while `acquire bracket
// --display 0` shows flat:0.25, the X server's own framebuffer holds the drive level the table
// inverts 0.25 to (a display with light = drive^2.2: 0.25 -> 0.533), not the identity's 0.25.
TEST_F(CliAcquireTest, DisplayWindowDrivesTheLevelTheGammaTableAsksFor) {
  XvfbServer xvfb;
  std::string error;
  ASSERT_TRUE(xvfb.Start(160, 120, &error)) << error;
  const char* old_display = std::getenv("DISPLAY");
  const std::string saved_display = old_display ? old_display : "";
  setenv("DISPLAY", xvfb.display().c_str(), 1);
#ifdef __SANITIZE_ADDRESS__
  setenv("SDL_RENDER_DRIVER", "software", 1);  // No Mesa GL under LeakSanitizer (pattern_window_test).
  setenv("SDL_FRAMEBUFFER_ACCELERATION", "0", 1);
#endif
  GammaTable table;
  for (int i = 0; i <= 32; ++i) table.drive_to_light.push_back({i / 32.0, std::pow(i / 32.0, 2.2)});
  const std::string table_path = *dir_ / "window_gamma.txt";
  ASSERT_TRUE(WriteGammaTable(table_path, table).ok());
  for (const bool with_table : {true, false}) {
    SCOPED_TRACE(with_table ? "with the table" : "identity");
    const std::string out = *dir_ / (with_table ? "window_table" : "window_identity");
    const std::string args = "acquire bracket --quiet --display 0 --pattern flat:0.25 --capture-dark false"
                             " --camera-width-px 32 --camera-height-px 24 --exposures-us 100000,200000,400000"
                             " --sim-realtime " + (with_table ? "--gamma-table " + table_path + " " : "") + out;
    const pid_t pid = SpawnUntil(args, out, 1);  // The pattern is on screen before its first frame.
    ASSERT_GT(pid, 0);
    Image root;
    const Status dump = DumpRootWindow(xvfb.display(), *dir_ / "root.xwd", &root);
    int wstatus = 0;
    ASSERT_EQ(waitpid(pid, &wstatus, 0), pid);
    ASSERT_TRUE(dump.ok()) << dump.message();
    EXPECT_TRUE(WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0) << "acquire bracket failed";
    ASSERT_EQ(CountFrames(out), 3);
    const double expected = with_table ? table.DriveForLight(0.25) : 0.25;
    // 8-bit drive: within half a step of the exact level, plus rounding in the renderer.
    EXPECT_NEAR(root.at(80, 60), 255 * expected, 1.0) << "expected drive " << expected;
    EXPECT_NEAR(root.at(5, 5), root.at(80, 60), 0.5) << "flat pattern not uniform on screen";
  }
  if (saved_display.empty()) {
    unsetenv("DISPLAY");
  } else {
    setenv("DISPLAY", saved_display.c_str(), 1);
  }
}

TEST_F(CliAcquireTest, UnreachableOrAbsentCameraIsNamed) {
  ExpectDeviceError("acquire shadow-maps --camera aravis:127.0.0.2 --camera-timeout-s 0.3 " + *dir_ / "cam",
                    {"aravis:127.0.0.2"}, *dir_ / "cam");
  ExpectDeviceError("acquire bracket --camera v4l2:/dev/video97 " + *dir_ / "cam", {"/dev/video97"}, *dir_ / "cam");
}

// A device that cannot be opened on --resume leaves the interrupted session exactly as it was.
TEST_F(CliAcquireTest, DeviceFailureOnResumeLeavesTheSessionConsistent) {
  const std::string session = *dir_ / "partial";
  const std::string args = "acquire bracket --quiet --camera-width-px 64 --camera-height-px 48 --monitor-width-px 64"
                           " --monitor-height-px 64 --exposure-steps 2 " + session;
  ASSERT_EQ(RunThinslab(args).exit_code, 0);
  std::string before;
  ASSERT_TRUE(ReadFileToString(session + "/session.json", &before).ok());
  const RunResult r = RunThinslab(args + " --resume --laser hid-relay:dead:beef:1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("dead:beef"), std::string::npos) << r.output;
  std::string after;
  ASSERT_TRUE(ReadFileToString(session + "/session.json", &after).ok());
  EXPECT_EQ(before, after);
  const RunResult info = RunThinslab("info " + session);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("Acquisition: complete"), std::string::npos) << info.output;
}

}  // namespace
}  // namespace thinslab
