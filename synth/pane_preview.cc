// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/pane_preview.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"
#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass_layer.h"
#include "thinslab/synth/layer_synthesis.h"

namespace thinslab {
namespace {

Eigen::Vector3d FromAngles(double theta_deg, double phi_deg, bool outside) {
  // theta from the pane normal, phi in the pane plane from +x towards +y ("down").
  const double t = theta_deg * kPi / 180, p = phi_deg * kPi / 180;
  return Eigen::Vector3d(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), outside ? std::cos(t) : -std::cos(t));
}

double Percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// Box-filters the layer by an integer factor: tau averaged, g/albedo/n2 averaged with the
// coverage weights 1 - e^{-tau} (as the synthesis blends them).
Image DownsampleLayer(const Image& layer, int max_size) {
  // Always rebuilds the channels in the order tau, g, albedo, n2 (EXR readers sort them).
  const int f = std::max(1, (std::max(layer.width(), layer.height()) + max_size - 1) / max_size);
  const int w = (layer.width() + f - 1) / f, h = (layer.height() + f - 1) / f;
  const int ct = layer.ChannelIndex("tau"), cg = layer.ChannelIndex("g"), ca = layer.ChannelIndex("albedo"),
            cn = layer.ChannelIndex("n2");
  Image out(w, h, {"tau", "g", "albedo", "n2"});
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double tau = 0, wsum = 0, g = 0, a = 0, n2 = 0;
      int count = 0;
      for (int yy = y * f; yy < std::min(layer.height(), (y + 1) * f); ++yy) {
        for (int xx = x * f; xx < std::min(layer.width(), (x + 1) * f); ++xx) {
          const double t = layer.at(xx, yy, ct), alpha = -std::expm1(-t);
          tau += t;
          wsum += alpha;
          g += alpha * layer.at(xx, yy, cg);
          a += alpha * layer.at(xx, yy, ca);
          n2 += alpha * layer.at(xx, yy, cn);
          ++count;
        }
      }
      out.at(x, y, 0) = static_cast<float>(tau / count);
      out.at(x, y, 1) = wsum > 0 ? static_cast<float>(g / wsum) : 0.0f;
      out.at(x, y, 2) = wsum > 0 ? static_cast<float>(a / wsum) : 0.0f;
      out.at(x, y, 3) = wsum > 0 ? static_cast<float>(n2 / wsum) : 1.0f;
    }
  }
  return out;
}

Image ResampleTo(const Image& image, int w, int h) {
  cv::Mat src(image.height(), image.width(), CV_32F);
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) src.at<float>(y, x) = image.at(x, y, 0);
  }
  cv::Mat dst;
  cv::resize(src, dst, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  Image out(w, h, {"Y"});
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) out.at(x, y) = std::max(0.0f, dst.at<float>(y, x));
  }
  return out;
}

}  // namespace

std::vector<PaneScene> CanonicalPaneScenes() {
  std::vector<PaneScene> scenes(3);
  // Fig. 8 row 1, "View of Window in Daytime": dark room, bright sky behind the pane. The sky
  // also lights the layer from outside and above: three directions, 30-70 deg off the normal,
  // sharing the surface irradiance pi/2 of a unit-radiance sky filling the upper half of the
  // outside hemisphere (the integral of L cos(theta) over that quarter sphere).
  scenes[0].name = "daylight_window";
  scenes[0].background_scale = 1.0;
  scenes[0].room_radiance = 0.02;
  for (double theta : {30.0, 50.0, 70.0}) {
    scenes[0].lights.push_back({FromAngles(theta, -90, true), kPi / 2 / 3 / std::cos(theta * kPi / 180)});
  }
  // Fig. 8 row 2, "View of Window in Nighttime": dark outside, lit room; a lamp on the viewer's
  // side, above, and the bright room mirrored in the pane.
  scenes[1].name = "night_window";
  scenes[1].background_scale = 0.01;
  scenes[1].room_radiance = 0.1;
  scenes[1].lights.push_back({FromAngles(40, -75, false), 10.0});
  // Fig. 8 row 5, "Collimated Beam from the Side": sunlight striking the pane at 60 deg from
  // outside; clean glass sends none of it to the camera.
  scenes[2].name = "side_light";
  scenes[2].background_scale = 0.05;
  scenes[2].room_radiance = 0.02;
  scenes[2].lights.push_back({FromAngles(60, 0, true), 20.0});
  return scenes;
}

Image ProceduralBackground(int width, int height) {
  Image bg(width, height, {"Y"});
  const double horizon = 0.55 * height;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double u = (x + 0.5) / width, v = (y + 0.5) / height;
      double value;
      if (y + 0.5 < horizon) {
        value = 1.0 - 0.25 * v;  // Sky, slightly darker towards the horizon.
        // Buildings rising into the sky on the right third.
        const double roof = 0.55 - 0.12 * (0.5 + 0.5 * std::sin(u * 23.0)) * (u > 0.66);
        if (v > roof) value = 0.06;
      } else {
        value = 0.05 + 0.04 * (0.5 + 0.5 * std::sin(u * 40.0 + v * 7.0));  // Ground.
      }
      bg.at(x, y) = static_cast<float>(value);
    }
  }
  return bg;
}

Status RenderPaneView(const Image& layer_in, const Image& background, const PaneScene& scene,
                      const PanePreviewOptions& options, Image* radiance, Image* clean) {
  THINSLAB_RETURN_IF_ERROR(CheckContaminationLayer(layer_in, "pane preview layer"));
  if (!(options.glass_index > 1 && options.glass_index < 3)) {
    return Status::Error("PanePreviewOptions::glass_index must be in (1, 3)");
  }
  if (options.max_size_px < 8) return Status::Error("PanePreviewOptions::max_size_px must be >= 8");
  if (background.empty()) return Status::Error("pane preview: empty background image");
  const Image layer = DownsampleLayer(layer_in, options.max_size_px);
  const int w = layer.width(), h = layer.height();
  const Image bg = (background.width() == w && background.height() == h) ? background : ResampleTo(background, w, h);
  *radiance = Image(w, h, {"Y"});
  if (clean) *clean = Image(w, h, {"Y"});
  const Eigen::Vector3d wo(0, 0, -1), up(0, 0, 1), down(0, 0, -1);
  auto shade = [&](double tau, double g, double albedo, double n2, double b) {
    DirtyGlassLayer<double> pane;
    pane.tau = tau;
    pane.g = g;
    pane.albedo = albedo;
    pane.n1 = 1.0;
    pane.n2 = n2;
    pane.n3 = options.glass_index;
    pane.thin_slab = true;
    // Eq. 5 + Appendix (thin slab): the scene behind, unscattered.
    double l = pane.Specular(up).transmittance * b * scene.background_scale;
    // Eqs. 1, 2 + Appendix: the room mirrored by the pane and the layer.
    l += pane.Specular(down).reflectance * scene.room_radiance;
    // Eqs. 3, 4 (lights on the room side) and 6 (outside): single scattering to the camera.
    for (const auto& light : scene.lights) {
      l += pane.Bsdf(light.dir_to_light, wo) * light.irradiance * std::abs(light.dir_to_light.z());
    }
    return l;
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double b = bg.at(x, y, 0);
      radiance->at(x, y) =
          static_cast<float>(shade(layer.at(x, y, 0), layer.at(x, y, 1), layer.at(x, y, 2), layer.at(x, y, 3), b));
      if (clean) clean->at(x, y) = static_cast<float>(shade(0.0, 0.0, 0.0, 1.0, b));
    }
  }
  radiance->attributes()["scene"] = scene.name;
  return Status::Ok();
}

Status WritePanePreview(const std::string& png_path, const Image& layer, const Image& background_in,
                        const PanePreviewOptions& options, std::vector<PanePreviewPanel>* panels) {
  THINSLAB_RETURN_IF_ERROR(CheckContaminationLayer(layer, png_path + " (layer)"));
  const Image background = background_in.empty() ? ProceduralBackground(layer.width(), layer.height()) : background_in;
  const std::vector<PaneScene> scenes = CanonicalPaneScenes();
  std::vector<cv::Mat> tiles;
  panels->clear();
  for (const auto& scene : scenes) {
    Image lit, clean;
    THINSLAB_RETURN_IF_ERROR(RenderPaneView(layer, background, scene, options, &lit, &clean));
    const Image small = DownsampleLayer(layer, options.max_size_px);
    const Image bg = ResampleTo(background, lit.width(), lit.height());
    const double median_bg = Percentile(bg.data(), 0.5);
    PanePreviewPanel panel;
    panel.scene = scene.name;
    double sum_bright = 0, sum_dark = 0;
    int64_t n_bright = 0, n_dark = 0;
    for (int y = 0; y < lit.height(); ++y) {
      for (int x = 0; x < lit.width(); ++x) {
        if (small.at(x, y, 0) <= 0.05 || clean.at(x, y) <= 0) continue;
        const double ratio = lit.at(x, y) / clean.at(x, y);
        if (bg.at(x, y) > median_bg) {
          sum_bright += ratio;
          ++n_bright;
        } else {
          sum_dark += ratio;
          ++n_dark;
        }
      }
    }
    if (n_bright) panel.contrast_bright_background = sum_bright / n_bright;
    if (n_dark) panel.contrast_dark_background = sum_dark / n_dark;
    panels->push_back(panel);
    // White at the 99th percentile of the rendering, so neither bright specks (night, side
    // light) nor the sky (daylight) saturate everything.
    const double white = std::max(1e-12, Percentile(lit.data(), 0.99));
    tiles.push_back(LabelledRadianceTile(lit, 0, white, scene.name));
  }
  return WritePngAtomically(png_path, SideBySide(tiles));
}

Status ReadBackgroundImage(const std::string& path, Image* background) {
  const std::string lower = [&] {
    std::string s = path;
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
    return s;
  }();
  if (lower.size() > 4 && lower.substr(lower.size() - 4) == ".exr") {
    Image image;
    THINSLAB_RETURN_IF_ERROR(ReadExr(path, &image));
    *background = Image(image.width(), image.height(), {"Y"});
    const int cy = image.ChannelIndex("Y"), cr = image.ChannelIndex("R"), cg = image.ChannelIndex("G"),
              cb = image.ChannelIndex("B");
    if (cy < 0 && (cr < 0 || cg < 0 || cb < 0) && image.num_channels() != 1) {
      return Status::Error(path + ": background EXR needs channel Y, or R, G and B");
    }
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x) {
        float v = cy >= 0 ? image.at(x, y, cy)
                  : (cr >= 0 && cg >= 0 && cb >= 0)
                      ? 0.2126f * image.at(x, y, cr) + 0.7152f * image.at(x, y, cg) + 0.0722f * image.at(x, y, cb)
                      : image.at(x, y, 0);
        if (!std::isfinite(v) || v < 0) {
          return Status::Error(path + ": pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                               ") is negative or not finite");
        }
        background->at(x, y) = v;
      }
    }
    return Status::Ok();
  }
  if (!FileExists(path)) return Status::Error(path + ": background image does not exist");
  cv::Mat image = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
  if (image.empty()) return Status::Error(path + ": cannot decode background image (PNG/JPEG/TIFF or EXR expected)");
  const double max_value = image.depth() == CV_16U ? 65535.0 : 255.0;
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    return Status::Error(path + ": background must be 8- or 16-bit");
  cv::Mat f;
  image.convertTo(f, CV_32FC3, 1.0 / max_value);
  *background = Image(f.cols, f.rows, {"Y"});
  auto decode = [](double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); };
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x < f.cols; ++x) {
      const cv::Vec3f bgr = f.at<cv::Vec3f>(y, x);
      background->at(x, y) =
          static_cast<float>(0.0722 * decode(bgr[0]) + 0.7152 * decode(bgr[1]) + 0.2126 * decode(bgr[2]));
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
