// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/exr_io.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfIntAttribute.h>
#include <ImfMatrixAttribute.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <map>
#include <nlohmann/json.hpp>
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

// One channel as it goes into the file.
struct FileChannel {
  int source = 0;  // Channel index in the image.
  std::string name;
  Imf::PixelType type = Imf::FLOAT;
};

// A file channel's pixels in its own pixel type, as a contiguous plane.
struct Plane {
  std::vector<float> f;
  std::vector<half> h;
  std::vector<uint32_t> u;
};

std::string PixelName(const std::string& path, const std::string& channel, size_t pixel, int width) {
  std::ostringstream msg;
  msg << path << ": channel '" << channel << "' at pixel (" << pixel % width << ", " << pixel / width << ")";
  return msg.str();
}

Status FillPlane(const std::string& path, const Image& image, const FileChannel& fc, Plane* plane) {
  const size_t n = image.num_pixels();
  const int nc = image.num_channels();
  const std::vector<float>& data = image.data();
  for (size_t i = 0; i < n; ++i) {
    const float v = data[i * nc + fc.source];
    if (!std::isfinite(v)) {
      return Status::Error(PixelName(path, image.channel_names()[fc.source], i, image.width()) +
                           " has a non-finite value; refusing to write");
    }
  }
  if (fc.type == Imf::FLOAT) {
    plane->f.resize(n);
    for (size_t i = 0; i < n; ++i) plane->f[i] = data[i * nc + fc.source];
  } else if (fc.type == Imf::HALF) {
    plane->h.resize(n);
    for (size_t i = 0; i < n; ++i) {
      plane->h[i] = half(data[i * nc + fc.source]);
      if (!plane->h[i].isFinite()) {
        std::ostringstream msg;
        msg << PixelName(path, image.channel_names()[fc.source], i, image.width()) << " value "
            << data[i * nc + fc.source] << " overflows half precision; refusing to write";
        return Status::Error(msg.str());
      }
    }
  } else {
    plane->u.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const float v = data[i * nc + fc.source];
      if (v < 0 || v > 4294967295.0f || v != std::floor(v)) {
        std::ostringstream msg;
        msg << PixelName(path, image.channel_names()[fc.source], i, image.width()) << " value " << v
            << " is not an unsigned integer (an integer channel); refusing to write";
        return Status::Error(msg.str());
      }
      plane->u[i] = static_cast<uint32_t>(v);
    }
  }
  return Status::Ok();
}

void InsertNumericAttribute(const std::string& key, const std::vector<double>& v, Imf::Header* header) {
  if (v.size() == 1) {
    header->insert(key, Imf::DoubleAttribute(v[0]));
  } else if (v.size() == 2) {
    header->insert(key, Imf::V2dAttribute(Imath::V2d(v[0], v[1])));
  } else if (v.size() == 3) {
    header->insert(key, Imf::V3dAttribute(Imath::V3d(v[0], v[1], v[2])));
  } else if (v.size() == 16 && (key == "worldToCamera" || key == "worldToNDC")) {
    // OpenEXR's standard attributes of these names are M44f.
    Imath::M44f m;
    for (int i = 0; i < 16; ++i) m[i / 4][i % 4] = static_cast<float>(v[i]);
    header->insert(key, Imf::M44fAttribute(m));
  } else if (v.size() == 16) {
    Imath::M44d m;
    for (int i = 0; i < 16; ++i) m[i / 4][i % 4] = v[i];
    header->insert(key, Imf::M44dAttribute(m));
  } else {
    header->insert(key, Imf::FloatVectorAttribute(std::vector<float>(v.begin(), v.end())));
  }
}

using StringAttributes = std::map<std::string, std::string>;

Status WriteChannels(const std::string& path, const Image& image, const std::vector<FileChannel>& channels,
                     const StringAttributes& strings) {
  if (image.empty()) return Status::Error(path + ": refusing to write an empty image");
  const int w = image.width(), h = image.height();
  std::vector<Plane> planes(channels.size());
  for (size_t c = 0; c < channels.size(); ++c) {
    THINSLAB_RETURN_IF_ERROR(FillPlane(path, image, channels[c], &planes[c]));
  }
  try {
    Imf::Header header(w, h);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const FileChannel& fc : channels) header.channels().insert(fc.name, Imf::Channel(fc.type));
    for (const auto& [key, value] : strings) header.insert(key, Imf::StringAttribute(value));
    for (const auto& [key, value] : image.numeric_attributes()) InsertNumericAttribute(key, value, &header);
    // The mark by which core/output_guard.h knows the file as thinslab's own.
    if (strings.count("thinslab_version") == 0) {
      header.insert("thinslab_version", Imf::StringAttribute(THINSLAB_VERSION_STRING));
    }
    // OpenEXR converts pixel types when reading but not when writing: each slice has the
    // file channel's type.
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < channels.size(); ++c) {
      const Imf::PixelType type = channels[c].type;
      char* base = type == Imf::FLOAT  ? reinterpret_cast<char*>(planes[c].f.data())
                   : type == Imf::HALF ? reinterpret_cast<char*>(planes[c].h.data())
                                       : reinterpret_cast<char*>(planes[c].u.data());
      const size_t xstride = type == Imf::HALF ? sizeof(half) : 4;
      fb.insert(channels[c].name, Imf::Slice(type, base, xstride, xstride * w));
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

// Format 1.0 outputs (tau.exr, maps.exr, calib/hdr) named channels and attributes differently.
void TranslateFormat1(Image* image) {
  static const std::map<std::string, std::string> kRenamed = {
      {"tau_plain", "tau_eq7"}, {"alpha", "top_face_weight"}, {"residual", "log_rms_residual"}};
  std::vector<std::string> names = image->channel_names();
  bool renamed = false;
  for (std::string& name : names) {
    const auto it = kRenamed.find(name);
    if (it != kRenamed.end()) name = it->second, renamed = true;
  }
  if (renamed) {
    Image out(image->width(), image->height(), names);
    out.data() = std::move(image->data());
    out.attributes() = std::move(image->attributes());
    out.numeric_attributes() = std::move(image->numeric_attributes());
    *image = std::move(out);
  }
  for (const char* key : {"pixel_pitch_m", "grid_min_m", "eta", "region_min_m", "region_max_m", "ndf_resolution",
                          "atlas_stride"}) {
    const auto it = image->attributes().find(key);
    if (it == image->attributes().end()) continue;
    const nlohmann::json j = nlohmann::json::parse(it->second, nullptr, false);
    std::vector<double> values;
    if (j.is_number()) values.push_back(j.get<double>());
    if (j.is_array()) {
      for (const auto& v : j) {
        if (v.is_number()) values.push_back(v.get<double>());
      }
      if (values.size() != j.size()) values.clear();
    }
    if (values.empty()) continue;
    image->numeric_attributes()[key] = values;
    image->attributes().erase(it);
  }
}

// Format 2.0 maps: "name.Y" reads as "name"; the default-layer "Y" repeats the primary.
void TranslateLayers(Image* image) {
  const auto primary = image->attributes().find("primary_channel");
  if (primary == image->attributes().end()) return;
  const int repeated = image->ChannelIndex(primary->second + ".Y") >= 0 ? image->ChannelIndex("Y") : -1;
  std::vector<std::string> names;
  std::vector<int> kept;
  for (int c = 0; c < image->num_channels(); ++c) {
    if (c == repeated) continue;
    std::string name = image->channel_names()[c];
    if (name.size() > 2 && name.compare(name.size() - 2, 2, ".Y") == 0) name.resize(name.size() - 2);
    names.push_back(name);
    kept.push_back(c);
  }
  Image out(image->width(), image->height(), names);
  for (size_t p = 0; p < image->num_pixels(); ++p) {
    for (size_t k = 0; k < kept.size(); ++k) {
      out.data()[p * kept.size() + k] = image->data()[p * image->num_channels() + kept[k]];
    }
  }
  out.attributes() = std::move(image->attributes());
  out.numeric_attributes() = std::move(image->numeric_attributes());
  *image = std::move(out);
}

void ReadNumericAttribute(const std::string& key, const Imf::Attribute& a, Image* image) {
  std::vector<double> v;
  if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&a)) {
    v = {d->value()};
  } else if (const auto* f = dynamic_cast<const Imf::FloatAttribute*>(&a)) {
    v = {f->value()};
  } else if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&a)) {
    v = {static_cast<double>(i->value())};
  } else if (const auto* v2 = dynamic_cast<const Imf::V2dAttribute*>(&a)) {
    v = {v2->value().x, v2->value().y};
  } else if (const auto* v3 = dynamic_cast<const Imf::V3dAttribute*>(&a)) {
    v = {v3->value().x, v3->value().y, v3->value().z};
  } else if (const auto* md = dynamic_cast<const Imf::M44dAttribute*>(&a)) {
    for (int k = 0; k < 16; ++k) v.push_back(md->value()[k / 4][k % 4]);
  } else if (const auto* mf = dynamic_cast<const Imf::M44fAttribute*>(&a)) {
    for (int k = 0; k < 16; ++k) v.push_back(mf->value()[k / 4][k % 4]);
  } else if (const auto* fv = dynamic_cast<const Imf::FloatVectorAttribute*>(&a)) {
    v.assign(fv->value().begin(), fv->value().end());
  } else {
    return;
  }
  image->numeric_attributes()[key] = v;
}

}  // namespace

Status WriteExr(const std::string& path, const Image& image, ExrPixelType pixel_type) {
  std::vector<FileChannel> channels;
  for (int c = 0; c < image.num_channels(); ++c) {
    channels.push_back({c, image.channel_names()[c], pixel_type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT});
  }
  return WriteChannels(path, image, channels, image.attributes());
}

Status WriteMapExr(const std::string& path, const Image& map, const MapExrLayout& layout,
                   const Provenance& provenance) {
  const int primary = map.ChannelIndex(layout.primary);
  if (primary < 0) return Status::Error(path + ": the map has no primary channel '" + layout.primary + "'");
  std::vector<FileChannel> channels = {{primary, "Y", Imf::FLOAT}};
  for (int c = 0; c < map.num_channels(); ++c) {
    const std::string& name = map.channel_names()[c];
    const bool integer =
        std::find(layout.integer_channels.begin(), layout.integer_channels.end(), name) != layout.integer_channels.end();
    channels.push_back({c, name + ".Y", integer ? Imf::UINT : Imf::FLOAT});
  }
  Image stamp(1, 1);  // Carries the header attributes only.
  stamp.attributes() = map.attributes();
  StampProvenance(provenance, &stamp);
  stamp.attributes()["primary_channel"] = layout.primary;
  return WriteChannels(path, map, channels, stamp.attributes());
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
      const std::string key = it.name();
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
        out.attributes()[key] = s->value();
      } else if (key != "pixelAspectRatio" && key != "screenWindowCenter" && key != "screenWindowWidth") {
        ReadNumericAttribute(key, it.attribute(), &out);  // OpenEXR's required attributes left out.
      }
    }
    // thinslab's own outputs come back under their plain names whatever the format version.
    const auto version = out.attributes().find("format_version");
    if (out.attributes().count("thinslab_version") > 0) {
      if (version == out.attributes().end() || version->second.rfind("1.", 0) == 0) {
        TranslateFormat1(&out);
      } else {
        TranslateLayers(&out);
      }
    }
    *image = std::move(out);
    return Status::Ok();
  } catch (const std::exception& e) {
    return Status::Error(path + ": not a readable OpenEXR file (" + e.what() + ")");
  }
}

Status RequireChannel(const Image& image, const std::string& file, const std::string& name, int* index) {
  *index = image.ChannelIndex(name);
  if (*index < 0) return Status::Error(file + ": channel '" + name + "' is missing");
  return Status::Ok();
}

Status RequireNumericAttribute(const Image& image, const std::string& file, const std::string& key, size_t count,
                               std::vector<double>* values, const std::string& hint) {
  const std::vector<double>* found = image.NumericAttribute(key, count);
  if (found == nullptr) {
    return Status::Error(file + ": numeric attribute '" + key + "' with " + std::to_string(count) + " value(s) is missing" +
                         (hint.empty() ? "" : " (" + hint + ")"));
  }
  for (double v : *found) {
    if (!std::isfinite(v)) return Status::Error(file + ": attribute '" + key + "' is not finite");
  }
  *values = *found;
  return Status::Ok();
}

}  // namespace thinslab
