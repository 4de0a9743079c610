// SPDX-License-Identifier: Apache-2.0
// Cost of the per-frame bookkeeping of an acquisition (docs/benchmarks.md): one rewrite of the
// manifest as a function of the frames in it, and a whole 40 x 40 x 2 dot scan through
// SessionWriter (journal line per frame, manifest at bounded intervals). Frames here are tiny
// (8 x 6 px), so the figures are the bookkeeping's share; compare with writing a real frame
// (a 1600 x 1200 16-bit PNG).
#include <benchmark/benchmark.h>

#include <sys/stat.h>

#include <filesystem>
#include <string>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

Session Header() {
  Session header = TinySessionHeader("dot_scan", TinyCamera("bench"));
  header.acquisition.present = true;
  header.acquisition.state = "running";
  return header;
}

// As RunAcquisition (`thinslab acquire`) opens its writer.
Status OpenForAcquisition(SessionWriter* writer, const std::string& dir, const Session& header) {
  SessionWriterOptions options;
  options.journal = true;
  return writer->Open(dir, header, options);
}

FrameRecord DotFrame(int k) {
  FrameRecord r;
  r.camera_id = "cam0";
  r.kind = "dot";
  r.sample_state = "contaminated";
  r.exposure_time_us = 23529.41;
  r.light.projector_pattern = "dot:" + std::to_string(k) + ".5,100.5";
  r.light.dot_px = Eigen::Vector2d(k + 0.5, 100.5);
  r.timestamp_utc = "2026-11-23T00:00:00.000Z";
  return r;
}

// One atomic rewrite of session.json (encode, write, fsync, rename). Arg: frames in the session
// (4806 = a 40 x 40 dot scan with a 3-exposure bracket, plus all-dots and dark brackets).
void BM_SaveManifestOfSession(benchmark::State& state) {
  const std::string dir = (std::filesystem::temp_directory_path() / "thinslab_acquire_bench").string();
  std::filesystem::remove_all(dir);
  SessionWriter writer;
  if (!writer.Open(dir, Header()).ok()) state.SkipWithError("cannot open session");
  Session* s = writer.mutable_session();
  for (int k = 0; k < state.range(0); ++k) {
    FrameRecord r = DotFrame(k);
    r.index = k;
    r.file = "frames/cam0/dot/x.png";
    s->frames.push_back(r);
  }
  for (auto _ : state) {
    if (!writer.Save().ok()) state.SkipWithError("Save failed");
  }
  const std::filesystem::path manifest = std::filesystem::path(dir) / "session.json";
  state.counters["manifest_bytes"] = static_cast<double>(std::filesystem::file_size(manifest));
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_SaveManifestOfSession)->Arg(10)->Arg(1000)->Arg(4806)->Unit(benchmark::kMillisecond);

// A whole 40 x 40 dot scan with a 2-exposure bracket (2 all-dots + 2 dark + 3200 dot frames,
// issue #7's example) through one SessionWriter, as `thinslab acquire dot-scan` writes it.
// Counters: bytes written to session.json over the scan (each rewrite is a new file, seen as a
// new inode), manifest rewrites, journal bytes, and wall time per frame.
void BM_DotScan40x40x2(benchmark::State& state) {
  const std::string dir = (std::filesystem::temp_directory_path() / "thinslab_acquire_bench_scan").string();
  const std::filesystem::path manifest = std::filesystem::path(dir) / "session.json";
  constexpr int kFrames = 2 + 2 + 40 * 40 * 2;
  const Image frame(8, 6, 100.0f);
  double manifest_bytes = 0, rewrites = 0, journal_bytes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    std::filesystem::remove_all(dir);
    state.ResumeTiming();
    SessionWriter writer;
    if (!OpenForAcquisition(&writer, dir, Header()).ok()) state.SkipWithError("cannot open session");
    ino_t last_inode = 0;
    manifest_bytes = rewrites = 0;
    auto count_rewrite = [&]() {
      struct stat st {};
      if (::stat(manifest.c_str(), &st) == 0 && st.st_ino != last_inode) {
        last_inode = st.st_ino;
        manifest_bytes += static_cast<double>(st.st_size);
        ++rewrites;
      }
    };
    count_rewrite();
    for (int k = 0; k < kFrames; ++k) {
      if (!writer.AddFrame(DotFrame(k % 40), frame).ok()) state.SkipWithError("AddFrame failed");
      count_rewrite();
    }
    if (!writer.Save().ok()) state.SkipWithError("Save failed");
    count_rewrite();
    std::error_code ec;
    const auto journal = std::filesystem::file_size(std::filesystem::path(dir) / "journal.log", ec);
    journal_bytes = ec ? 0.0 : static_cast<double>(journal);
  }
  state.counters["manifest_MB_written"] = manifest_bytes / 1e6;
  state.counters["manifest_rewrites"] = rewrites;
  state.counters["journal_MB"] = journal_bytes / 1e6;
  state.counters["final_manifest_MB"] = static_cast<double>(std::filesystem::file_size(manifest)) / 1e6;
  state.counters["ms_per_frame"] =
      benchmark::Counter(kFrames * 1e-3, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_DotScan40x40x2)->Iterations(1)->UseRealTime()->Unit(benchmark::kSecond);

}  // namespace
}  // namespace thinslab
BENCHMARK_MAIN();
