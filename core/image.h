// SPDX-License-Identifier: Apache-2.0
// A float image with named channels, stored interleaved, row-major, origin top-left.
// Pixel (x, y) covers [x, x+1) x [y, y+1); its centre is at (x + 0.5, y + 0.5)
// (docs/conventions.md).
#pragma once

#include <glog/logging.h>

#include <map>
#include <string>
#include <vector>

namespace thinslab {

class Image {
 public:
  Image() = default;
  Image(int width, int height, std::vector<std::string> channel_names, float fill = 0.0f);
  // Single-channel image named "Y".
  Image(int width, int height, float fill = 0.0f) : Image(width, height, {"Y"}, fill) {}

  int width() const { return width_; }
  int height() const { return height_; }
  int num_channels() const { return static_cast<int>(channel_names_.size()); }
  size_t num_pixels() const { return static_cast<size_t>(width_) * height_; }
  bool empty() const { return data_.empty(); }
  const std::vector<std::string>& channel_names() const { return channel_names_; }
  // Index of a channel, or -1.
  int ChannelIndex(const std::string& name) const;

  float& at(int x, int y, int c = 0) {
    DCHECK(x >= 0 && x < width_ && y >= 0 && y < height_ && c >= 0 && c < num_channels());
    return data_[(static_cast<size_t>(y) * width_ + x) * channel_names_.size() + c];
  }
  float at(int x, int y, int c = 0) const {
    DCHECK(x >= 0 && x < width_ && y >= 0 && y < height_ && c >= 0 && c < num_channels());
    return data_[(static_cast<size_t>(y) * width_ + x) * channel_names_.size() + c];
  }
  std::vector<float>& data() { return data_; }
  const std::vector<float>& data() const { return data_; }

  // One channel as a single-channel image.
  Image Channel(int c) const;
  // Bilinear sample at continuous coordinates (pixel centres at +0.5); clamps at borders.
  float Bilinear(double x, double y, int c = 0) const;

  // Free-form string attributes written to / read from the EXR header.
  std::map<std::string, std::string>& attributes() { return attributes_; }
  const std::map<std::string, std::string>& attributes() const { return attributes_; }
  // Numeric header attributes, stored with OpenEXR's typed attributes so that other tools read
  // numbers, not text: 1 value as double, 2 as V2d, 3 as V3d, 16 as M44d (row-major), any other
  // count as a float vector (core/exr_io.h).
  std::map<std::string, std::vector<double>>& numeric_attributes() { return numeric_attributes_; }
  const std::map<std::string, std::vector<double>>& numeric_attributes() const { return numeric_attributes_; }
  // The numeric attribute `key` with exactly `count` values, or nullptr.
  const std::vector<double>* NumericAttribute(const std::string& key, size_t count) const;

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<std::string> channel_names_;
  std::vector<float> data_;
  std::map<std::string, std::string> attributes_;
  std::map<std::string, std::vector<double>> numeric_attributes_;
};

// Stacks single-channel images of equal size as the channels of one image.
Image StackChannels(const std::vector<const Image*>& images, const std::vector<std::string>& names);

}  // namespace thinslab
