// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/pattern_window.h"

#include <SDL.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/drivers/sdl_handles.h"

namespace thinslab {

using sdl::AsRenderer;
using sdl::AsTexture;
using sdl::AsWindow;

double ExposureAsRefreshMultiple(double requested_s, double refresh_period_s) {
  if (!(refresh_period_s > 0) || !std::isfinite(refresh_period_s)) return requested_s;
  const double n = std::max(1.0, std::round(requested_s / refresh_period_s));
  return n * refresh_period_s;
}

PatternWindow::~PatternWindow() {
  if (texture_ != nullptr) SDL_DestroyTexture(AsTexture(texture_));
  if (renderer_ != nullptr) SDL_DestroyRenderer(AsRenderer(renderer_));
  if (window_ != nullptr) SDL_DestroyWindow(AsWindow(window_));
  if (owns_sdl_video_) SDL_QuitSubSystem(SDL_INIT_VIDEO);
}

Status PatternWindow::Present() {
  SDL_Event event;
  while (SDL_PollEvent(&event) != 0) {
    if (event.type == SDL_QUIT ||
        (event.type == SDL_WINDOWEVENT && event.window.event == SDL_WINDOWEVENT_CLOSE)) {
      return Status::Error("pattern window on display " + std::to_string(options_.display_index) +
                           " was closed");
    }
  }
  SDL_Renderer* renderer = AsRenderer(renderer_);
  if (SDL_RenderClear(renderer) != 0 ||
      SDL_RenderCopy(renderer, AsTexture(texture_), nullptr, nullptr) != 0) {
    return Status::Error("pattern window on display " + std::to_string(options_.display_index) +
                         ": rendering failed: " + sdl::Error());
  }
  SDL_RenderPresent(renderer);
  return Status::Ok();
}

Status PatternWindow::ShowPattern(const std::string& pattern) {
  PatternSpec spec;
  THINSLAB_RETURN_IF_ERROR(ParsePatternId(pattern, &spec));
  Image linear;
  THINSLAB_RETURN_IF_ERROR(
      RasterizePattern(spec, width_, height_, options_.dot_radius_px, &linear));
  // Inverse gamma through a 4096-entry lookup table of drive levels (linear light is smooth, so
  // 4096 steps is far below the 8-bit output step).
  constexpr int kLut = 4096;
  std::vector<uint8_t> lut(kLut + 1);
  for (int i = 0; i <= kLut; ++i) {
    lut[i] = static_cast<uint8_t>(std::lround(255 * gamma_.DriveForLight(double(i) / kLut)));
  }
  last_drive_.resize(linear.num_pixels());
  std::vector<uint32_t> argb(linear.num_pixels());
  const std::vector<float>& v = linear.data();
  for (size_t i = 0; i < v.size(); ++i) {
    const uint8_t d = lut[std::lround(std::clamp(v[i], 0.0f, 1.0f) * kLut)];
    last_drive_[i] = d;
    argb[i] = 0xff000000u | (uint32_t{d} << 16) | (uint32_t{d} << 8) | d;
  }
  if (SDL_UpdateTexture(AsTexture(texture_), nullptr, argb.data(), width_ * 4) != 0) {
    return Status::Error("pattern window: texture upload failed: " + sdl::Error());
  }
  // With vsync each present blocks until the next vertical blank: the first puts the pattern in
  // the queue, the following ones guarantee it has been scanned out at least once completely.
  for (int i = 0; i <= options_.settle_presents; ++i) THINSLAB_RETURN_IF_ERROR(Present());
  if (options_.settle_s > 0) SDL_Delay(static_cast<Uint32>(std::lround(options_.settle_s * 1e3)));
  return Status::Ok();
}

Status PatternWindow::ReadBackFramebuffer(Image* image) {
  SDL_Renderer* renderer = AsRenderer(renderer_);
  // The back buffer is undefined after a present: draw the current texture again, read, present.
  if (SDL_RenderClear(renderer) != 0 ||
      SDL_RenderCopy(renderer, AsTexture(texture_), nullptr, nullptr) != 0) {
    return Status::Error("pattern window: rendering failed: " + sdl::Error());
  }
  std::vector<uint32_t> argb(static_cast<size_t>(width_) * height_);
  if (SDL_RenderReadPixels(renderer, nullptr, SDL_PIXELFORMAT_ARGB8888, argb.data(), width_ * 4) !=
      0) {
    return Status::Error("pattern window: SDL_RenderReadPixels failed: " + sdl::Error());
  }
  SDL_RenderPresent(renderer);
  Image out(width_, height_, 0.0f);
  for (size_t i = 0; i < argb.size(); ++i) {
    const uint32_t p = argb[i];
    out.data()[i] = static_cast<float>(((p >> 16) & 0xff) + ((p >> 8) & 0xff) + (p & 0xff)) / 3.0f;
  }
  *image = std::move(out);
  return Status::Ok();
}

Status OpenPatternWindow(const PatternWindowOptions& options, std::unique_ptr<PatternWindow>* out) {
  const std::string name = "display " + std::to_string(options.display_index);
  if (!(options.dot_radius_px > 0) || !(options.settle_s >= 0) || options.settle_presents < 0 ||
      options.width_px < 0 || options.height_px < 0) {
    return Status::Error(name +
                         ": PatternWindowOptions need dot_radius_px > 0, settle_s >= 0, "
                         "settle_presents >= 0 and non-negative width/height");
  }
  std::unique_ptr<PatternWindow> w(new PatternWindow());
  w->options_ = options;
  w->gamma_ = IdentityGammaTable();
  if (!options.gamma_table_path.empty()) {
    THINSLAB_RETURN_IF_ERROR(ReadGammaTable(options.gamma_table_path, &w->gamma_));
  }
  // A fullscreen pattern window must stay up when the operator clicks on another monitor.
  SDL_SetHint(SDL_HINT_VIDEO_MINIMIZE_ON_FOCUS_LOSS, "0");
  // One texel per screen pixel: any filtering would move sub-pixel dots.
  SDL_SetHint(SDL_HINT_RENDER_SCALE_QUALITY, "nearest");
  if (SDL_InitSubSystem(SDL_INIT_VIDEO) != 0) {
    const char* display = std::getenv("DISPLAY");
    return Status::Error(name + ": SDL video initialisation failed (DISPLAY=" +
                         (display != nullptr ? display : "<unset>") + "): " + sdl::Error());
  }
  w->owns_sdl_video_ = true;
  const int count = SDL_GetNumVideoDisplays();
  if (count < 1) {
    return Status::Error(name + ": SDL finds no displays: " + sdl::Error());
  }
  if (options.display_index < 0 || options.display_index >= count) {
    return Status::Error("display index " + std::to_string(options.display_index) +
                         " is out of range: " + std::to_string(count) +
                         " display(s) available (indices 0.." + std::to_string(count - 1) + ")");
  }
  SDL_DisplayMode mode;
  if (SDL_GetCurrentDisplayMode(options.display_index, &mode) != 0) {
    return Status::Error(name + ": SDL_GetCurrentDisplayMode failed: " + sdl::Error());
  }
  // SDL reports 0 Hz when the driver does not know (e.g. Xvfb without RandR rates).
  w->refresh_period_s_ = mode.refresh_rate > 0 ? 1.0 / mode.refresh_rate : 0;
  int width = options.width_px > 0 ? options.width_px : mode.w;
  int height = options.height_px > 0 ? options.height_px : mode.h;
  Uint32 flags = SDL_WINDOW_SHOWN | SDL_WINDOW_BORDERLESS;
  if (options.fullscreen) {
    // Desktop fullscreen keeps the display's native mode, so pattern pixels are screen pixels.
    if ((options.width_px > 0 && options.width_px != mode.w) ||
        (options.height_px > 0 && options.height_px != mode.h)) {
      return Status::Error(name + ": fullscreen uses the display's mode " + std::to_string(mode.w) +
                           "x" + std::to_string(mode.h) + ", not the requested " +
                           std::to_string(options.width_px) + "x" +
                           std::to_string(options.height_px));
    }
    width = mode.w;
    height = mode.h;
    flags |= SDL_WINDOW_FULLSCREEN_DESKTOP;
  }
  SDL_Window* window = SDL_CreateWindow(
      "thinslab pattern", SDL_WINDOWPOS_UNDEFINED_DISPLAY(options.display_index),
      SDL_WINDOWPOS_UNDEFINED_DISPLAY(options.display_index), width, height, flags);
  if (window == nullptr) {
    return Status::Error(name + ": SDL_CreateWindow failed: " + sdl::Error());
  }
  w->window_ = window;
  SDL_Renderer* renderer =
      SDL_CreateRenderer(window, -1, SDL_RENDERER_ACCELERATED | SDL_RENDERER_PRESENTVSYNC);
  if (renderer == nullptr) {
    // No GPU (e.g. Xvfb): the software renderer still places every pixel exactly.
    renderer = SDL_CreateRenderer(window, -1, SDL_RENDERER_SOFTWARE);
  }
  if (renderer == nullptr) {
    return Status::Error(name + ": SDL_CreateRenderer failed: " + sdl::Error());
  }
  w->renderer_ = renderer;
  SDL_RendererInfo renderer_info;
  if (SDL_GetRendererInfo(renderer, &renderer_info) == 0 && renderer_info.name != nullptr) {
    w->renderer_name_ = renderer_info.name;
  }
  SDL_SetRenderDrawColor(renderer, 0, 0, 0, 255);
  // The window manager may resize the fullscreen window asynchronously: let it settle, then use
  // the renderer's actual output size (pixels, also on HiDPI).
  SDL_PumpEvents();
  if (SDL_GetRendererOutputSize(renderer, &w->width_, &w->height_) != 0 || w->width_ <= 0 ||
      w->height_ <= 0) {
    return Status::Error(name + ": SDL_GetRendererOutputSize failed: " + sdl::Error());
  }
  SDL_Texture* texture = SDL_CreateTexture(renderer, SDL_PIXELFORMAT_ARGB8888,
                                           SDL_TEXTUREACCESS_STREAMING, w->width_, w->height_);
  if (texture == nullptr) {
    return Status::Error(name + ": SDL_CreateTexture failed: " + sdl::Error());
  }
  w->texture_ = texture;
  SDL_ShowCursor(SDL_DISABLE);
  THINSLAB_RETURN_IF_ERROR(w->ShowPattern(""));
  *out = std::move(w);
  return Status::Ok();
}

}  // namespace thinslab
