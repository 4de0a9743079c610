// SPDX-License-Identifier: Apache-2.0
// The pixels an X server would scan out, read with `xwd -root` (package x11-apps): how the
// tests of the SDL2 pattern window and of `thinslab acquire --display` see what the screen
// shows, independently of the renderer's own read-back.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <string>
#include <utility>

#include "thinslab/core/file.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

inline uint32_t BigEndian32(const std::string& b, size_t offset) {
  return (uint32_t(uint8_t(b[offset])) << 24) | (uint32_t(uint8_t(b[offset + 1])) << 16) |
         (uint32_t(uint8_t(b[offset + 2])) << 8) | uint32_t(uint8_t(b[offset + 3]));
}

// Reads the X server's root window with `xwd -root` (the pixels the server would scan out) as
// the mean of R, G and B. Supports the 24/32-bit TrueColor ZPixmap that Xvfb -screen WxHx24 uses.
inline Status DumpRootWindow(const std::string& display, const std::string& path, Image* image) {
  const std::string command = "xwd -root -silent -display " + display + " -out " + path;
  if (std::system(command.c_str()) != 0) return Status::Error("`" + command + "` failed");
  std::string b;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &b));
  if (b.size() < 100) return Status::Error(path + ": truncated XWD header");
  // XWDFileHeader: 25 big-endian CARD32 fields.
  auto field = [&](int i) { return BigEndian32(b, 4 * i); };
  const uint32_t header_size = field(0), width = field(4), height = field(5);
  const uint32_t byte_order = field(7), bits_per_pixel = field(11), bytes_per_line = field(12);
  const uint32_t red_mask = field(14), green_mask = field(15), blue_mask = field(16);
  const uint32_t ncolors = field(19);
  if (bits_per_pixel != 32) return Status::Error(path + ": expected 32 bits per pixel");
  const size_t data = header_size + 12 * ncolors;
  if (b.size() < data + size_t(bytes_per_line) * height) {
    return Status::Error(path + ": truncated XWD pixels");
  }
  auto channel = [](uint32_t p, uint32_t mask) {
    int shift = 0;
    while (mask != 0 && (mask & 1u) == 0) {
      mask >>= 1;
      ++shift;
    }
    return double((p >> shift) & mask);
  };
  Image out(int(width), int(height), 0.0f);
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const size_t o = data + size_t(y) * bytes_per_line + 4 * x;
      const uint8_t* q = reinterpret_cast<const uint8_t*>(b.data() + o);
      const uint32_t p = byte_order == 0 ? (q[0] | (q[1] << 8) | (q[2] << 16) | (uint32_t(q[3]) << 24))
                                         : ((uint32_t(q[0]) << 24) | (q[1] << 16) | (q[2] << 8) | q[3]);
      out.at(int(x), int(y)) = float(
          (channel(p, red_mask) + channel(p, green_mask) + channel(p, blue_mask)) / 3.0);
    }
  }
  *image = std::move(out);
  return Status::Ok();
}

}  // namespace thinslab
