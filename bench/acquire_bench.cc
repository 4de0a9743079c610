// SPDX-License-Identifier: Apache-2.0
// Cost of the per-frame bookkeeping of an acquisition: SessionWriter::AddFrame rewrites the
// whole manifest atomically after every frame, so its cost grows with the frames already in
// the session. Frames here are tiny (8 x 6 px), so the figure is the manifest's share; compare
// with writing a real frame (a 1600 x 1200 16-bit PNG).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "acquire/session_writer.h"
#include "core/session_io.h"

namespace thinslab {
namespace {

Session Header() {
  Session header;
  header.name = "bench";
  header.kind = "dot_scan";
  CameraInfo c;
  c.id = "cam0";
  c.model = "bench";
  c.width_px = 8;
  c.height_px = 6;
  c.fx_px = c.fy_px = 10;
  c.bit_depth = 12;
  c.saturation_dn = 4095;
  header.rig.cameras = {c};
  header.rig.sample.region_min_m = Eigen::Vector2d(-1, -1);
  header.rig.sample.region_max_m = Eigen::Vector2d(1, 1);
  header.rig.sample.pixel_pitch_m = 1e-3;
  header.acquisition.present = true;
  header.acquisition.state = "running";
  return header;
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

// Arg: frames already in the session (4806 = a 40 x 40 dot scan with a 3-exposure bracket,
// plus all-dots and dark brackets).
void BM_AddFrameToSessionOf(benchmark::State& state) {
  const std::string dir = (std::filesystem::temp_directory_path() / "thinslab_acquire_bench").string();
  std::filesystem::remove_all(dir);
  SessionWriter writer;
  if (!writer.Open(dir, Header()).ok()) state.SkipWithError("cannot open session");
  const Image frame(8, 6, 100.0f);
  Session* s = writer.mutable_session();
  for (int k = 0; k < state.range(0); ++k) {
    FrameRecord r = DotFrame(k);
    r.index = k;
    r.file = "frames/cam0/dot/x.png";
    s->frames.push_back(r);
  }
  for (auto _ : state) {
    if (!writer.AddFrame(DotFrame(0), frame).ok()) state.SkipWithError("AddFrame failed");
    state.PauseTiming();
    s->frames.pop_back();
    state.ResumeTiming();
  }
  std::string text;
  const std::filesystem::path manifest = std::filesystem::path(dir) / "session.json";
  state.counters["manifest_bytes"] = static_cast<double>(std::filesystem::file_size(manifest));
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_AddFrameToSessionOf)->Arg(10)->Arg(1000)->Arg(4806)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace thinslab
BENCHMARK_MAIN();
