// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/preview_window.h"

#include <SDL.h>

#include "thinslab/drivers/sdl_handles.h"

namespace thinslab {

using sdl::AsRenderer;
using sdl::AsTexture;
using sdl::AsWindow;

PreviewWindow::~PreviewWindow() {
  if (texture_ != nullptr) SDL_DestroyTexture(AsTexture(texture_));
  if (renderer_ != nullptr) SDL_DestroyRenderer(AsRenderer(renderer_));
  if (window_ != nullptr) SDL_DestroyWindow(AsWindow(window_));
  if (owns_sdl_video_) SDL_QuitSubSystem(SDL_INIT_VIDEO);
}

Status PreviewWindow::Render() {
  SDL_Renderer* renderer = AsRenderer(renderer_);
  if (SDL_RenderClear(renderer) != 0 || SDL_RenderCopy(renderer, AsTexture(texture_), nullptr, nullptr) != 0) {
    return Status::Error("preview window: SDL_RenderCopy failed: " + sdl::Error());
  }
  return Status::Ok();
}

Status PreviewWindow::Show(const std::vector<uint8_t>& rgb) {
  if (rgb.size() != static_cast<size_t>(width_) * height_ * 3) {
    return Status::Error("preview window: picture of " + std::to_string(rgb.size()) + " bytes for a " +
                         std::to_string(width_) + " x " + std::to_string(height_) + " window");
  }
  if (SDL_UpdateTexture(AsTexture(texture_), nullptr, rgb.data(), width_ * 3) != 0) {
    return Status::Error("preview window: SDL_UpdateTexture failed: " + sdl::Error());
  }
  THINSLAB_RETURN_IF_ERROR(Render());
  SDL_RenderPresent(AsRenderer(renderer_));
  return Status::Ok();
}

bool PreviewWindow::CloseRequested() {
  SDL_Event event;
  while (SDL_PollEvent(&event) != 0) {
    if (event.type == SDL_QUIT || (event.type == SDL_WINDOWEVENT && event.window.event == SDL_WINDOWEVENT_CLOSE) ||
        (event.type == SDL_KEYDOWN && (event.key.keysym.sym == SDLK_q || event.key.keysym.sym == SDLK_ESCAPE))) {
      close_requested_ = true;
    }
  }
  return close_requested_;
}

Status PreviewWindow::ReadBack(std::vector<uint8_t>* rgb) {
  THINSLAB_RETURN_IF_ERROR(Render());
  rgb->assign(static_cast<size_t>(width_) * height_ * 3, 0);
  if (SDL_RenderReadPixels(AsRenderer(renderer_), nullptr, SDL_PIXELFORMAT_RGB24, rgb->data(), width_ * 3) != 0) {
    return Status::Error("preview window: SDL_RenderReadPixels failed: " + sdl::Error());
  }
  SDL_RenderPresent(AsRenderer(renderer_));
  return Status::Ok();
}

Status OpenPreviewWindow(int width, int height, const std::string& title, std::unique_ptr<PreviewWindow>* window) {
  if (width < 1 || height < 1 || width > 16384 || height > 16384) {
    return Status::Error("preview window: size " + std::to_string(width) + " x " + std::to_string(height) +
                         " is out of range");
  }
  std::unique_ptr<PreviewWindow> w(new PreviewWindow());
  if (SDL_InitSubSystem(SDL_INIT_VIDEO) != 0) {
    return Status::Error("preview window: SDL_InitSubSystem(VIDEO) failed (is DISPLAY set?): " + sdl::Error());
  }
  w->owns_sdl_video_ = true;
  SDL_Window* sdl_window = SDL_CreateWindow(title.c_str(), SDL_WINDOWPOS_UNDEFINED, SDL_WINDOWPOS_UNDEFINED, width,
                                            height, SDL_WINDOW_SHOWN);
  if (sdl_window == nullptr) return Status::Error("preview window: SDL_CreateWindow failed: " + sdl::Error());
  w->window_ = sdl_window;
  SDL_Renderer* renderer = SDL_CreateRenderer(sdl_window, -1, SDL_RENDERER_ACCELERATED);
  if (renderer == nullptr) renderer = SDL_CreateRenderer(sdl_window, -1, SDL_RENDERER_SOFTWARE);
  if (renderer == nullptr) return Status::Error("preview window: SDL_CreateRenderer failed: " + sdl::Error());
  w->renderer_ = renderer;
  SDL_SetRenderDrawColor(renderer, 0, 0, 0, 255);
  SDL_Texture* texture = SDL_CreateTexture(renderer, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING, width, height);
  if (texture == nullptr) return Status::Error("preview window: SDL_CreateTexture failed: " + sdl::Error());
  w->texture_ = texture;
  w->width_ = width;
  w->height_ = height;
  *window = std::move(w);
  return Status::Ok();
}

}  // namespace thinslab
