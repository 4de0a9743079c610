// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/blender_render.h"

#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <thread>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/process.h"

namespace thinslab {

namespace {

// Samples rendered so far, read from Cycles' log: passes finished ("Saved: '...'" lines) times
// `samples`, plus the last "Sample N/M" of the pass under way.
int64_t RenderedSamples(const std::string& log_text, int samples) {
  int64_t done = 0;
  size_t pass_start = 0;
  for (size_t at = log_text.find("Saved: '"); at != std::string::npos; at = log_text.find("Saved: '", at + 1)) {
    done += samples;
    pass_start = at;
  }
  const size_t sample = log_text.rfind("| Sample ");
  if (sample != std::string::npos && sample > pass_start) done += std::atoi(log_text.c_str() + sample + 9);
  return done;
}

// Waits for Blender, reporting its samples every half second; a cancel stops it (SIGTERM).
Status WaitForRender(pid_t blender, const std::string& log_path, int passes, int samples, const std::string& label,
                     const ProgressCallback& progress, int* exit_code) {
  ProgressTracker tracker(progress, label + " (" + std::to_string(passes) + " passes)",
                          static_cast<int64_t>(passes) * samples);
  for (;;) {
    bool ended = false;
    THINSLAB_RETURN_IF_ERROR(PollProgram(blender, &ended, exit_code));
    std::string text;
    if (progress && ReadFileToString(log_path, &text).ok() && !tracker.Report(RenderedSamples(text, samples))) {
      if (!ended) {
        kill(blender, SIGTERM);
        THINSLAB_RETURN_IF_ERROR(WaitProgram(blender, nullptr, exit_code));
      }
      return Status::Error("RenderRoundTrip: cancelled");
    }
    if (ended) return Status::Ok();
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

}  // namespace

Status RenderBlenderPasses(const std::string& blender, const std::string& scene_dir, const std::string& prefix,
                           int passes, int samples, const std::string& progress_label,
                           const ProgressCallback& progress) {
  const std::string blender_log = JoinPath(scene_dir, "blender.log");
  const std::string script = JoinPath(scene_dir, "scene.py");
  int exit_code = 0;
  pid_t process = 0;
  const Status started = StartProgram({blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                                       script, "--", "--passes", prefix, "--samples", std::to_string(samples)},
                                      blender_log, &process);
  if (!started.ok()) {
    return Status::Error("--blender: " + started.message() + " (install Debian's blender package, or give its path)");
  }
  THINSLAB_RETURN_IF_ERROR(WaitForRender(process, blender_log, passes, samples, progress_label, progress, &exit_code));
  if (exit_code != 0) {
    std::string tail;
    if (!ReadFileToString(blender_log, &tail).ok()) tail = "(unreadable)";
    if (tail.size() > 2000) tail = "..." + tail.substr(tail.size() - 2000);
    return Status::Error("--blender: '" + blender + "' exited with " + std::to_string(exit_code) + " rendering " +
                         script + "; its log ends:\n" + tail);
  }
  return Status::Ok();
}

Status ReadBlenderRender(const std::string& path, int width, int height, const std::string& channel_prefix,
                         Image* out) {
  Image render;
  THINSLAB_RETURN_IF_ERROR(ReadExr(path, &render));
  int r = 0, g = 0, b = 0;
  THINSLAB_RETURN_IF_ERROR(RequireChannel(render, path, channel_prefix + "R", &r));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(render, path, channel_prefix + "G", &g));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(render, path, channel_prefix + "B", &b));
  if (render.width() != width || render.height() != height) {
    return Status::Error(path + ": Blender rendered " + std::to_string(render.width()) + "x" +
                         std::to_string(render.height()) + " px, the scene asks for " + std::to_string(width) + "x" +
                         std::to_string(height));
  }
  *out = Image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double v = (render.at(x, y, r) + render.at(x, y, g) + render.at(x, y, b)) / 3;
      if (!std::isfinite(v) || v < 0)
        return Status::Error(path + ": " + channel_prefix + "pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                             ") is not a finite radiance");
      out->at(x, y) = static_cast<float>(v);
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
