// SPDX-License-Identifier: Apache-2.0
// Frame files of a capture: PNG/TIFF/EXR frames and variance files read in DN, raw frames
// written as PNG (docs/format.md sections 3-4).
#include "thinslab/core/frame_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/opencv_error.h"
#include "thinslab/core/png_io.h"
#include "thinslab/core/session_format.h"

namespace thinslab {
namespace {

using namespace session_format;  // NOLINT: the format's shared vocabulary.

// libpng prints decode errors ("libpng error: Read Error") on stderr itself before OpenCV
// returns an empty image; thinslab reports the failure once, through Status, naming the file.
class ScopedSilenceStderr {
 public:
  ScopedSilenceStderr() : lock_(Mutex()) {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int null_fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, STDERR_FILENO);
    if (null_fd >= 0) ::close(null_fd);
  }
  ~ScopedSilenceStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
  }

 private:
  static std::mutex& Mutex() {
    static std::mutex mutex;
    return mutex;
  }
  std::lock_guard<std::mutex> lock_;
  int saved_ = -1;
};

// One EXR frame file (the frame or its variance): channel "Y" or its only channel, the camera's
// size, finite values.
Status ReadFrameExr(const std::string& path, const CameraInfo& camera, Image* out) {
  Image exr;
  THINSLAB_RETURN_IF_ERROR(ReadExr(path, &exr));
  int c = exr.ChannelIndex("Y");
  if (c < 0 && exr.num_channels() == 1) c = 0;
  if (c < 0) {
    std::string names;
    for (const auto& n : exr.channel_names()) names += (names.empty() ? "" : ", ") + n;
    return Status::Error(path + ": no channel \"Y\" and more than one channel (" + names +
                         "); frame EXRs hold one linear channel named \"Y\"");
  }
  const int w = camera.width_px, h = camera.height_px;
  if (exr.width() != w || exr.height() != h) {
    return Status::Error(path + ": image is " + std::to_string(exr.width()) + "x" + std::to_string(exr.height()) +
                         " px but camera " + camera.id + " is " + std::to_string(w) + "x" + std::to_string(h) + " px");
  }
  *out = Image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = exr.at(x, y, c);
      if (!std::isfinite(v)) {
        return Status::Error(path + ": non-finite value at pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                             ")");
      }
      out->at(x, y) = v;
    }
  }
  return Status::Ok();
}

}  // namespace

Status LoadFrameVariance(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                         Image* variance) {
  *variance = Image();
  if (frame.variance_file.empty()) return Status::Ok();
  const std::string frame_name = "frame " + std::to_string(frame.index);
  const CameraInfo* camera = session.FindCamera(frame.camera_id);
  if (camera == nullptr) {
    return Status::Error(ManifestPath(session_dir) + ": " + frame_name + ": unknown camera id " +
                         Quote(frame.camera_id));
  }
  std::string path;
  const std::string reason = ResolveFrameFile(session_dir, frame.variance_file, &path);
  if (!reason.empty()) {
    return Status::Error(JoinPath(session_dir, frame.variance_file) + ": " + frame_name + " variance_file: " + reason);
  }
  THINSLAB_RETURN_IF_ERROR(ReadFrameExr(path, *camera, variance));
  for (size_t i = 0; i < variance->data().size(); ++i) {
    if (variance->data()[i] < 0) {
      const int w = camera->width_px;
      return Status::Error(path + ": " + frame_name + " variance_file: negative variance " +
                           Num(variance->data()[i]) + " at pixel (" + std::to_string(i % w) + ", " +
                           std::to_string(i / w) + ")");
    }
  }
  return Status::Ok();
}

Status LoadFrame(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                 Image* image_dn) {
  const std::string manifest = ManifestPath(session_dir);
  const std::string frame_name = "frame " + std::to_string(frame.index);
  if (frame.status == FrameStatus::kFailed) {
    return Status::Error(manifest + ": " + frame_name + " has status failed and no image");
  }
  const CameraInfo* camera = session.FindCamera(frame.camera_id);
  if (camera == nullptr) {
    return Status::Error(manifest + ": " + frame_name + ": unknown camera id " +
                         Quote(frame.camera_id));
  }
  std::string path;
  const std::string reason = ResolveFrameFile(session_dir, frame.file, &path);
  if (!reason.empty()) {
    return Status::Error(JoinPath(session_dir, frame.file) + ": " + frame_name + ": " + reason);
  }

  const int w = camera->width_px, h = camera->height_px;
  auto size_error = [&](int got_w, int got_h) {
    return Status::Error(path + ": image is " + std::to_string(got_w) + "x" +
                         std::to_string(got_h) + " px but camera " + camera->id + " is " +
                         std::to_string(w) + "x" + std::to_string(h) + " px");
  };
  const double black = camera->black_level_dn;
  const std::string ext = Lowercase(fs::path(frame.file).extension().string());

  if (ext == ".exr") {
    THINSLAB_RETURN_IF_ERROR(ReadFrameExr(path, *camera, image_dn));
    for (float& v : image_dn->data()) v = static_cast<float>(static_cast<double>(v) - black);
    return Status::Ok();
  }

  if (ext != ".png" && ext != ".tif" && ext != ".tiff") {
    return Status::Error(path + ": unsupported frame file extension " + Quote(ext) +
                         " (expected .png, .tif, .tiff or .exr)");
  }
  if (!IsIntegerDepth(camera->bit_depth)) {
    return Status::Error(path + ": camera " + camera->id + " has bit_depth " +
                         std::to_string(camera->bit_depth) +
                         " (float frames); its frames must be EXR, not integer images");
  }
  cv::Mat m;
  try {
    ScopedSilenceStderr silence;
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const std::exception& e) {
    return Status::Error(path + ": cannot decode image (corrupt or truncated?): " + OpenCvErrorText(e));
  }
  if (m.empty()) return Status::Error(path + ": cannot decode image (corrupt or truncated?)");
  if (m.channels() != 1) {
    return Status::Error(
        path + ": image has " + std::to_string(m.channels()) +
        " channels; frames must be single-channel (raw or monochrome), not colour");
  }
  if (m.cols != w || m.rows != h) return size_error(m.cols, m.rows);
  const int expected_depth = camera->bit_depth <= 8 ? CV_8U : CV_16U;
  if (m.depth() != expected_depth) {
    const std::string got = m.depth() == CV_8U    ? "8-bit"
                            : m.depth() == CV_16U ? "16-bit"
                                                  : "a non-integer or signed sample type";
    return Status::Error(path + ": image is " + got + " but camera " + camera->id +
                         " has bit_depth " + std::to_string(camera->bit_depth) + ", which needs " +
                         (expected_depth == CV_8U ? "8-bit" : "16-bit") + " samples");
  }
  double max_value = 0;
  cv::minMaxLoc(m, nullptr, &max_value);
  const double max_dn = std::ldexp(1.0, camera->bit_depth) - 1;
  if (max_value > max_dn) {
    return Status::Error(path + ": value " + Num(max_value) + " exceeds the " +
                         std::to_string(camera->bit_depth) + "-bit range of camera " + camera->id +
                         " (max " + Num(max_dn) +
                         "); frames hold DN in the low bits, not shifted to the top");
  }
  Image out(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double v =
          expected_depth == CV_8U ? m.at<std::uint8_t>(y, x) : m.at<std::uint16_t>(y, x);
      out.at(x, y) = static_cast<float>(v - black);
    }
  }
  *image_dn = std::move(out);
  return Status::Ok();
}

Status WriteRawFrame(const std::string& path, const Image& raw_dn, int bit_depth) {
  if (!IsIntegerDepth(bit_depth) ||
      std::find(BitDepths().begin(), BitDepths().end(), bit_depth) == BitDepths().end()) {
    return Status::Error(path + ": bit_depth " + std::to_string(bit_depth) +
                         " cannot be written as an integer PNG (8, 10, 12, 14 or 16; write float "
                         "frames with WriteExr)");
  }
  if (Lowercase(fs::path(path).extension().string()) != ".png") {
    return Status::Error(path + ": WriteRawFrame writes PNG; the file name must end in .png");
  }
  if (raw_dn.empty()) return Status::Error(path + ": refusing to write an empty image");
  if (raw_dn.num_channels() != 1) {
    return Status::Error(path + ": raw frames are single-channel, got " +
                         std::to_string(raw_dn.num_channels()) + " channels");
  }
  const int w = raw_dn.width(), h = raw_dn.height();
  const double max_dn = std::ldexp(1.0, bit_depth) - 1;
  const bool wide = bit_depth > 8;
  cv::Mat m(h, w, wide ? CV_16U : CV_8U);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = raw_dn.at(x, y);
      if (!std::isfinite(v)) {
        return Status::Error(path + ": non-finite value at pixel (" + std::to_string(x) + ", " +
                             std::to_string(y) + "); refusing to write");
      }
      const double dn = std::clamp(std::round(static_cast<double>(v)), 0.0, max_dn);
      if (wide) {
        m.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(dn);
      } else {
        m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(dn);
      }
    }
  }
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !DirectoryExists(parent.string())) {
    THINSLAB_RETURN_IF_ERROR(CreateDirectories(parent.string()));
  }
  return WritePngAtomically(path, m);
}

}  // namespace thinslab
