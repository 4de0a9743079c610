// SPDX-License-Identifier: Apache-2.0
// Issue #29 item 2 through the binary: `mpirun -n N thinslab fit dmf` shares the dot frames
// (HDR merge, Eq. 12), the diffuse separation, the representatives' fits and the interpolation
// out over N processes on this machine and writes the same maps bit for bit as one process, in
// memory and streamed, clustered and not. A frame that one process cannot read ends every
// process with its error (no process left waiting), and commands that do not share their work
// refuse to run under mpirun. Built only with THINSLAB_WITH_MPI; MPI talks over shared memory
// and loopback only.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/same_fit.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/file.h"

namespace thinslab {
namespace {

// mpirun on this machine: shared memory between the processes, its own control traffic on the
// loopback interface; root allowed (CI runs as root).
RunResult RunMpi(int processes, const std::string& args) {
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  // Under AddressSanitizer, no leak check of the processes mpirun starts: Open MPI keeps
  // allocations until exit in plugins it has unloaded by then, which LeakSanitizer can only name
  // (and scripts/lsan.supp suppress) with full-stack unwinding at every malloc, 2.4x the time.
  // Memory errors and undefined behaviour are still checked; thinslab's leaks are checked on the
  // same code run as one process (every other fit dmf test).
  static const bool asan_set = [] {
    if (const char* asan = std::getenv("ASAN_OPTIONS")) {
      setenv("ASAN_OPTIONS", (std::string(asan) + ":detect_leaks=0").c_str(), 1);
    }
    return true;
  }();
  (void)asan_set;
  return RunShell("mpirun -n " + std::to_string(processes) +
                  " --oversubscribe --mca btl self,vader --mca oob_tcp_if_include lo " + ThinslabBinary() + " " + args);
}

TEST(CliDmfMpi, ProcessesWriteTheSameMapsAsOne) {
  TempDir dir;
  const std::string capture = dir / "capture";
  SimulateSmallDotScan(capture);
  const std::string fit = "fit dmf " + capture + " --pitch-mm 2.5 --hold-out true";
  RunThinslabOk(fit + " --threads 2 --out " + (dir / "one"));
  const RunResult two = RunMpi(2, fit + " --threads 1 --out " + (dir / "two"));
  ASSERT_EQ(two.exit_code, 0) << two.output;
  EXPECT_EQ(ReadJsonFile(dir / "two/summary.json")["processes"], 2);
  EXPECT_EQ(ReadJsonFile(dir / "one/summary.json")["processes"], 1);
  ExpectSameFit(dir, "one", "two");
  // Streamed from disk in bands of 4 grid rows: each process its own spill file.
  const RunResult streamed = RunMpi(2, fit + " --threads 1 --stream-band-points 128 --out " + (dir / "two_streamed"));
  ASSERT_EQ(streamed.exit_code, 0) << streamed.output;
  ExpectSameFit(dir, "one", "two_streamed");

  // Every point fitted directly, three processes (uneven shares), streamed.
  const std::string all =
      "fit dmf " + capture + " --pitch-mm 5 --hold-out true --cluster-fraction 0 --split-half false";
  RunThinslabOk(all + " --threads 2 --out " + (dir / "all_one"));
  const RunResult three = RunMpi(3, all + " --threads 1 --stream-band-points 48 --out " + (dir / "all_three"));
  ASSERT_EQ(three.exit_code, 0) << three.output;
  ExpectSameFit(dir, "all_one", "all_three");

  // Nothing but the outputs beside them: no spill file or staging folder of any process.
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    const std::string name = entry.path().filename().string();
    EXPECT_EQ(name.find(".partial"), std::string::npos) << name;
    EXPECT_EQ(name.find("slices"), std::string::npos) << name;
  }
}

TEST(CliDmfMpi, OneProcessesBadFrameStopsEveryProcessWithItsError) {
  TempDir dir;
  const std::string capture = dir / "capture";
  RunThinslabOk("sim dot-scan " + capture +
                " --quiet --grid-nx 6 --grid-ny 6 --photons-k 5 --table-bins 16 --camera-width-px 160 "
                "--camera-height-px 120");
  // The second dot of the scan (row-major: by y, then x) is process 1's in the first round of two.
  const nlohmann::json session = ReadJsonFile(dir / "capture/session.json");
  std::map<std::pair<double, double>, std::string> dot_files;
  for (const auto& f : session["frames"]) {
    if (f["kind"] == "dot" && f["light"].contains("dot_px")) {
      dot_files.emplace(std::make_pair(f["light"]["dot_px"][1].get<double>(), f["light"]["dot_px"][0].get<double>()),
                        f["file"].get<std::string>());
    }
  }
  ASSERT_GE(dot_files.size(), 2u);
  const std::string second_dot = std::next(dot_files.begin())->second;
  ASSERT_FALSE(second_dot.empty());
  ASSERT_TRUE(WriteFileAtomically(dir / ("capture/" + second_dot), "not a png").ok());
  const RunResult bad = RunMpi(2, "fit dmf " + capture + " --pitch-mm 4 --threads 1 --out " + (dir / "fit"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("error: process 1 of 2: dot ("), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find(second_dot + ": cannot decode image"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "fit"));

  const RunResult info = RunMpi(2, "info " + capture);
  EXPECT_NE(info.exit_code, 0);
  EXPECT_NE(info.output.find("thinslab info runs as one process; under mpirun only `thinslab fit dmf`"),
            std::string::npos)
      << info.output;
}

}  // namespace
}  // namespace thinslab
