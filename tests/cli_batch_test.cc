// SPDX-License-Identifier: Apache-2.0
// Issue #29 item 2, through the binary: `thinslab batch ROOT` refits every capture under ROOT with
// the fit its kind takes, skips fits that are complete and current (the batch's options and the
// digest of the options.ini the fit wrote), refits when either changes or the capture changed
// (its manifest, calibration files, frames), keeps going past a
// broken capture (and exits 1 naming it), splits a folder into shards, and resumes after a kill.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/file.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSmallShadow = " --camera-width-px 96 --camera-height-px 72 --photons 2000 --frames 1";
constexpr const char* kSmallLaser =
    " --camera-width-px 160 --camera-height-px 120 --capture-clean false --photons 20000";

std::string Status(const nlohmann::json& state, const std::string& capture) {
  if (!state["captures"].contains(capture)) return "(absent)";
  return state["captures"][capture]["status"];
}

fs::file_time_type Modified(const std::string& path) {
  std::error_code ec;
  return fs::last_write_time(path, ec);
}

TEST(CliBatch, FitsEveryCaptureSkipsCurrentOnesAndRefitsWhenOptionsChange) {
  TempDir dir;
  const std::string root = dir / "captures";
  RunThinslabOk("sim shadow-maps " + root + "/a" + kSmallShadow + " --seed 1");
  RunThinslabOk("sim shadow-maps " + root + "/b" + kSmallShadow + " --seed 2");
  RunThinslabOk("sim laser " + root + "/c" + kSmallLaser);
  fs::copy(root + "/a", root + "/d", fs::copy_options::recursive);
  ASSERT_TRUE(WriteFileAtomically(root + "/d/session.json", "{\"format\": \"thinslab-session\", ").ok());
  fs::create_directories(root + "/notes");  // No session.json: not a capture.

  RunResult r = RunThinslab("batch " + root + " --jobs 2");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("1 capture failed"), std::string::npos) << r.output;
  nlohmann::json state = ReadJsonFile(root + "/thinslab_batch.json");
  EXPECT_EQ(state["format"], "thinslab-batch-state");
  EXPECT_EQ(Status(state, "a"), "fitted");
  EXPECT_EQ(Status(state, "b"), "fitted");
  EXPECT_EQ(Status(state, "c"), "fitted");
  EXPECT_EQ(Status(state, "d"), "failed");
  EXPECT_EQ(Status(state, "notes"), "(absent)");
  EXPECT_NE(state["captures"]["d"]["note"].get<std::string>().find("session.json"), std::string::npos) << state.dump();
  EXPECT_TRUE(FileExists(root + "/a/fit/tau/tau.exr"));
  EXPECT_TRUE(FileExists(root + "/c/fit/phase/summary.json"));
  std::string table;
  ASSERT_TRUE(ReadFileToString(root + "/thinslab_batch.csv", &table).ok());
  EXPECT_EQ(table.rfind("# thinslab batch table\ncapture,kind,fit,status,seconds,note\n", 0), 0u) << table;
  EXPECT_NE(table.find("\na,shadow_map,tau,fitted,"), std::string::npos) << table;
  EXPECT_NE(table.find("\nc,laser_lobe,phase,fitted,"), std::string::npos) << table;

  // Again: nothing is current that was not fitted; the fits are untouched.
  const fs::file_time_type a_fitted = Modified(root + "/a/fit/tau/summary.json");
  r = RunThinslab("batch " + root);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  state = ReadJsonFile(root + "/thinslab_batch.json");
  for (const char* capture : {"a", "b", "c"}) EXPECT_EQ(Status(state, capture), "current") << capture;
  EXPECT_EQ(Status(state, "d"), "failed");
  EXPECT_EQ(Modified(root + "/a/fit/tau/summary.json"), a_fitted);

  // Other options for the tau fits: those two are refitted, the lobe stays current.
  r = RunThinslab("batch " + root + " --tau-options '--g 0.7'");
  state = ReadJsonFile(root + "/thinslab_batch.json");
  EXPECT_EQ(Status(state, "a"), "fitted");
  EXPECT_EQ(Status(state, "b"), "fitted");
  EXPECT_EQ(Status(state, "c"), "current");
  std::string ini;
  ASSERT_TRUE(ReadFileToString(root + "/a/fit/tau/options.ini", &ini).ok());
  EXPECT_NE(ini.find("g = 0.7"), std::string::npos) << ini;

  // A fit redone by hand (its options.ini changed) is not current.
  ASSERT_TRUE(ReadFileToString(root + "/c/fit/phase/options.ini", &ini).ok());
  ASSERT_TRUE(WriteFileAtomically(root + "/c/fit/phase/options.ini", ini + "# by hand\n").ok());
  r = RunThinslab("batch " + root + " --tau-options '--g 0.7'");
  state = ReadJsonFile(root + "/thinslab_batch.json");
  EXPECT_EQ(Status(state, "a"), "current");
  EXPECT_EQ(Status(state, "c"), "fitted");

  // A capture that changed after its fit (a frame re-taken: rewritten with a new time) is
  // refitted, with a note that says why; the others stay current.
  const nlohmann::json b_session = ReadJsonFile(root + "/b/session.json");
  const std::string frame = root + "/b/" + b_session["frames"][1]["file"].get<std::string>();
  std::string bytes;
  ASSERT_TRUE(ReadFileToString(frame, &bytes).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_TRUE(WriteFileAtomically(frame, bytes).ok());
  r = RunThinslab("batch " + root + " --tau-options '--g 0.7'");
  state = ReadJsonFile(root + "/thinslab_batch.json");
  EXPECT_EQ(Status(state, "a"), "current");
  EXPECT_EQ(Status(state, "b"), "fitted");
  EXPECT_EQ(Status(state, "c"), "current");
  EXPECT_NE(state["captures"]["b"]["note"].get<std::string>().find("the capture changed since its fit"),
            std::string::npos)
      << state.dump();

  // Shard 1 of 2 of the sorted captures a, b, c, d: b and d, in a state file of its own.
  r = RunThinslab("batch " + root + " --shard 1/2 --tau-options '--g 0.7'");
  const nlohmann::json shard = ReadJsonFile(root + "/thinslab_batch_1of2.json");
  EXPECT_EQ(Status(shard, "b"), "fitted");  // A new state file: nothing recorded as current yet.
  EXPECT_EQ(Status(shard, "d"), "failed");
  EXPECT_EQ(Status(shard, "a"), "(absent)");
  EXPECT_EQ(Status(shard, "c"), "(absent)");

  // Refusals by name.
  r = RunThinslab("batch " + root + " --shard 2/2");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--shard"), std::string::npos) << r.output;
  r = RunThinslab("batch " + (dir / "none"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("ROOT"), std::string::npos) << r.output;
  r = RunThinslab("batch " + root + " --tau-options '--out x'");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--tau-options"), std::string::npos) << r.output;
  ASSERT_TRUE(WriteFileAtomically(dir / "users.json", "{}").ok());
  r = RunThinslab("batch " + root + " --state " + (dir / "users.json"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("users.json"), std::string::npos) << r.output;
}

TEST(CliBatch, ResumesAfterAKill) {
  TempDir dir;
  const std::string root = dir / "captures";
  for (const char* name : {"a", "b", "c", "d"}) {
    RunThinslabOk("sim shadow-maps " + root + "/" + name + kSmallShadow + " --seed 5");
  }
  // The batch in the background, killed (with its fit) once the first fit is recorded. ("[f]it":
  // the pattern does not match the shell that runs pkill.)
  const std::string pid_file = dir / "batch.pid";
  ASSERT_EQ(
      std::system((ThinslabBinary() + " batch " + root + " > " + (dir / "batch.log") + " 2>&1 & echo $! > " + pid_file)
                      .c_str()),
      0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  bool first_recorded = false;
  while (!first_recorded && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::string text;
    if (!ReadFileToString(root + "/thinslab_batch.json", &text).ok()) continue;
    const nlohmann::json state = nlohmann::json::parse(text, nullptr, false);
    first_recorded = !state.is_discarded() && state["captures"].size() >= 1;
  }
  ASSERT_TRUE(first_recorded) << "the batch recorded no fit within 300 s";
  ASSERT_EQ(std::system(("kill -9 $(cat " + pid_file + ") ; pkill -9 -f '[f]it tau " + root + "/' ; true").c_str()), 0);
  const nlohmann::json killed = ReadJsonFile(root + "/thinslab_batch.json");
  ASSERT_LT(killed["captures"].size(), 4u) << "the batch finished before the kill: " << killed.dump();

  // Run again: what was recorded is current, the rest is fitted, nothing of the killed run is left.
  const RunResult r = RunThinslabOk("batch " + root);
  const nlohmann::json state = ReadJsonFile(root + "/thinslab_batch.json");
  int current = 0, fitted = 0;
  for (const char* name : {"a", "b", "c", "d"}) {
    const std::string s = Status(state, name);
    current += s == "current";
    fitted += s == "fitted";
    EXPECT_TRUE(FileExists(root + "/" + name + "/fit/tau/tau.exr")) << name;
    for (const fs::directory_entry& e : fs::directory_iterator(root + "/" + name + "/fit")) {
      EXPECT_EQ(e.path().filename().string(), "tau") << "left in " << name << "/fit: " << e.path();
    }
  }
  EXPECT_EQ(current, static_cast<int>(killed["captures"].size())) << r.output;
  EXPECT_EQ(current + fitted, 4) << r.output;
}

}  // namespace
}  // namespace thinslab
