// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/png_io.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/opencv_error.h"
#include "thinslab/core/version.h"

namespace thinslab {
namespace {

// CRC-32 of the PNG specification (ISO 3309, polynomial 0xEDB88320), over type + data.
uint32_t PngCrc(const std::string& bytes) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

void AppendBigEndian(uint32_t v, std::string* out) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<char>((v >> shift) & 0xFF));
}

}  // namespace

Status WritePngAtomically(const std::string& path, const cv::Mat& image) {
  std::vector<uint8_t> encoded;
  try {
    if (!cv::imencode(".png", image, encoded)) return Status::Error(path + ": PNG encoding failed");
  } catch (const std::exception& e) {
    return Status::Error(path + ": PNG encoding failed: " + OpenCvErrorText(e));
  }
  // Signature (8 bytes) + IHDR chunk (4 length + 4 type + 13 data + 4 CRC): the text chunk
  // goes right after IHDR, where the PNG specification allows it.
  constexpr size_t kAfterIhdr = 8 + 25;
  if (encoded.size() < kAfterIhdr) return Status::Error(path + ": PNG encoding failed (short stream)");
  const std::string body = std::string("tEXt") + "Software" + '\0' + "thinslab " + THINSLAB_VERSION_STRING;
  std::string chunk;
  AppendBigEndian(static_cast<uint32_t>(body.size() - 4), &chunk);
  chunk += body;
  AppendBigEndian(PngCrc(body), &chunk);
  std::string bytes(encoded.begin(), encoded.begin() + kAfterIhdr);
  bytes += chunk;
  bytes.append(encoded.begin() + kAfterIhdr, encoded.end());
  return WriteFileAtomically(path, bytes);
}

double SrgbEncode(double linear) {
  const double x = std::clamp(linear, 0.0, 1.0);
  return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1 / 2.4) - 0.055;
}

cv::Mat LabelledRadianceTile(const Image& radiance, int channel, double white, const std::string& label, int scale) {
  constexpr int kHeader = 28;
  const int s = std::max(1, scale);
  cv::Mat tile(radiance.height() * s + kHeader, radiance.width() * s, CV_8UC3, cv::Scalar(32, 32, 32));
  for (int y = 0; y < radiance.height() * s; ++y) {
    for (int x = 0; x < radiance.width() * s; ++x) {
      const auto v = static_cast<uint8_t>(std::lround(255 * SrgbEncode(radiance.at(x / s, y / s, channel) / white)));
      tile.at<cv::Vec3b>(y + kHeader, x) = cv::Vec3b(v, v, v);
    }
  }
  cv::putText(tile, label, cv::Point(6, 19), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return tile;
}

cv::Mat SideBySide(const std::vector<cv::Mat>& tiles) {
  std::vector<cv::Mat> with_gaps;
  for (size_t k = 0; k < tiles.size(); ++k) {
    if (k) with_gaps.push_back(cv::Mat(tiles[k].rows, 6, CV_8UC3, cv::Scalar(255, 255, 255)));
    with_gaps.push_back(tiles[k]);
  }
  cv::Mat sheet;
  cv::hconcat(with_gaps, sheet);
  return sheet;
}

}  // namespace thinslab
