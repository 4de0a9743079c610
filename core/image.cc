// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/image.h"

#include <algorithm>
#include <cmath>

namespace thinslab {

Image::Image(int width, int height, std::vector<std::string> channel_names, float fill)
    : width_(width), height_(height), channel_names_(std::move(channel_names)) {
  CHECK_GE(width, 0);
  CHECK_GE(height, 0);
  CHECK(!channel_names_.empty());
  data_.assign(static_cast<size_t>(width) * height * channel_names_.size(), fill);
}

int Image::ChannelIndex(const std::string& name) const {
  for (int c = 0; c < num_channels(); ++c) {
    if (channel_names_[c] == name) return c;
  }
  return -1;
}

Image Image::Channel(int c) const {
  CHECK(c >= 0 && c < num_channels());
  Image out(width_, height_, {channel_names_[c]});
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) out.at(x, y) = at(x, y, c);
  }
  out.attributes_ = attributes_;
  out.numeric_attributes_ = numeric_attributes_;
  return out;
}

const std::vector<double>* Image::NumericAttribute(const std::string& key, size_t count) const {
  const auto it = numeric_attributes_.find(key);
  return it != numeric_attributes_.end() && it->second.size() == count ? &it->second : nullptr;
}

float Image::Bilinear(double x, double y, int c) const {
  const double fx = x - 0.5, fy = y - 0.5;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const double tx = fx - x0, ty = fy - y0;
  auto pix = [&](int xi, int yi) {
    xi = std::clamp(xi, 0, width_ - 1);
    yi = std::clamp(yi, 0, height_ - 1);
    return static_cast<double>(at(xi, yi, c));
  };
  return static_cast<float>((1 - ty) * ((1 - tx) * pix(x0, y0) + tx * pix(x0 + 1, y0)) +
                            ty * ((1 - tx) * pix(x0, y0 + 1) + tx * pix(x0 + 1, y0 + 1)));
}

Image StackChannels(const std::vector<const Image*>& images, const std::vector<std::string>& names) {
  CHECK_EQ(images.size(), names.size());
  CHECK(!images.empty());
  Image out(images[0]->width(), images[0]->height(), names);
  for (size_t c = 0; c < images.size(); ++c) {
    CHECK_EQ(images[c]->width(), out.width());
    CHECK_EQ(images[c]->height(), out.height());
    CHECK_EQ(images[c]->num_channels(), 1);
    for (int y = 0; y < out.height(); ++y) {
      for (int x = 0; x < out.width(); ++x) out.at(x, y, static_cast<int>(c)) = images[c]->at(x, y);
    }
  }
  return out;
}

}  // namespace thinslab
