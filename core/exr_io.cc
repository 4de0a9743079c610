// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/exr_io.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>

#include <cmath>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/memory.h"
#include "thinslab/core/version.h"

namespace thinslab {
namespace {

// In-memory output stream, so the file on disk is written in one atomic step.
class MemoryOStream : public Imf::OStream {
 public:
  MemoryOStream() : Imf::OStream("memory") {}
  void write(const char c[], int n) override {
    if (pos_ + n > buffer_.size()) buffer_.resize(pos_ + n);
    std::copy(c, c + n, buffer_.begin() + static_cast<std::ptrdiff_t>(pos_));
    pos_ += static_cast<size_t>(n);
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = pos; }
  const std::string& buffer() const { return buffer_; }

 private:
  std::string buffer_;
  size_t pos_ = 0;
};

}  // namespace

Status WriteExr(const std::string& path, const Image& image, ExrPixelType pixel_type) {
  if (image.empty()) return Status::Error(path + ": refusing to write an empty image");
  const int w = image.width(), h = image.height(), nc = image.num_channels();
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < nc; ++c) {
        if (!std::isfinite(image.at(x, y, c))) {
          std::ostringstream msg;
          msg << path << ": channel '" << image.channel_names()[c] << "' has a non-finite value at pixel ("
              << x << ", " << y << "); refusing to write";
          return Status::Error(msg.str());
        }
      }
    }
  }
  try {
    Imf::Header header(w, h);
    header.compression() = Imf::ZIP_COMPRESSION;
    const Imf::PixelType type = pixel_type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT;
    for (const auto& name : image.channel_names()) header.channels().insert(name, Imf::Channel(type));
    for (const auto& [key, value] : image.attributes()) {
      header.insert(key, Imf::StringAttribute(value));
    }
    // The mark by which core/output_guard.h knows the file as thinslab's own.
    if (image.attributes().count("thinslab_version") == 0) {
      header.insert("thinslab_version", Imf::StringAttribute(THINSLAB_VERSION_STRING));
    }
    // OpenEXR converts pixel types when reading but not when writing: a HALF file channel
    // needs a HALF slice.
    Imf::FrameBuffer fb;
    std::vector<half> half_pixels;
    if (pixel_type == ExrPixelType::kHalf) {
      half_pixels.resize(image.data().size());
      for (size_t i = 0; i < half_pixels.size(); ++i) {
        half_pixels[i] = half(image.data()[i]);
        if (!half_pixels[i].isFinite()) {
          const size_t pixel = i / nc;
          std::ostringstream msg;
          msg << path << ": channel '" << image.channel_names()[i % nc] << "' value "
              << image.data()[i] << " at pixel (" << pixel % w << ", " << pixel / w
              << ") overflows half precision; refusing to write";
          return Status::Error(msg.str());
        }
      }
      const size_t xstride = sizeof(half) * nc;
      const size_t ystride = xstride * w;
      char* base = reinterpret_cast<char*>(half_pixels.data());
      for (int c = 0; c < nc; ++c) {
        fb.insert(image.channel_names()[c],
                  Imf::Slice(Imf::HALF, base + c * sizeof(half), xstride, ystride));
      }
    } else {
      const size_t xstride = sizeof(float) * nc;
      const size_t ystride = xstride * w;
      char* base = reinterpret_cast<char*>(const_cast<float*>(image.data().data()));
      for (int c = 0; c < nc; ++c) {
        fb.insert(image.channel_names()[c],
                  Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xstride, ystride));
      }
    }
    MemoryOStream stream;
    {
      Imf::OutputFile file(stream, header);
      file.setFrameBuffer(fb);
      file.writePixels(h);
    }
    return WriteFileAtomically(path, stream.buffer());
  } catch (const std::exception& e) {
    return Status::Error(path + ": OpenEXR write failed: " + e.what());
  }
}

Status ReadExr(const std::string& path, Image* image) {
  const std::string unreadable = UnreadableFileReason(path);
  if (unreadable == "does not exist") return Status::Error(path + ": file not found");
  if (!unreadable.empty()) return Status::Error(path + ": " + unreadable);
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const int64_t w64 = int64_t{dw.max.x} - dw.min.x + 1, h64 = int64_t{dw.max.y} - dw.min.y + 1;
    if (w64 <= 0 || h64 <= 0) return Status::Error(path + ": empty data window");
    if (w64 > (1 << 24) || h64 > (1 << 24)) {
      return Status::Error(path + ": data window " + std::to_string(w64) + "x" + std::to_string(h64) +
                           " px is larger than any image thinslab reads (16777216 px a side)");
    }
    const int w = static_cast<int>(w64), h = static_cast<int>(h64);
    std::vector<std::string> names;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
      names.push_back(it.name());
    }
    if (names.empty()) return Status::Error(path + ": no channels");
    // A header can declare any data window: refuse one the machine cannot hold before allocating.
    THINSLAB_RETURN_IF_ERROR(CheckMemoryNeed(sizeof(float) * static_cast<double>(w) * h * names.size(),
                                             path + ": its " + std::to_string(w) + "x" + std::to_string(h) + " px data window"));
    Image out(w, h, names);
    Imf::FrameBuffer fb;
    const size_t xstride = sizeof(float) * names.size();
    const size_t ystride = xstride * w;
    char* base = reinterpret_cast<char*>(out.data().data()) -
                 (static_cast<std::ptrdiff_t>(dw.min.x) * xstride + static_cast<std::ptrdiff_t>(dw.min.y) * ystride);
    for (size_t c = 0; c < names.size(); ++c) {
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xstride, ystride));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    for (auto it = file.header().begin(); it != file.header().end(); ++it) {
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
        out.attributes()[it.name()] = s->value();
      }
    }
    *image = std::move(out);
    return Status::Ok();
  } catch (const std::exception& e) {
    return Status::Error(path + ": not a readable OpenEXR file (" + e.what() + ")");
  }
}

}  // namespace thinslab
