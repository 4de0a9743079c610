// SPDX-License-Identifier: Apache-2.0
// PreviewWindow: an ordinary (not fullscreen) SDL2 window that shows RGB pictures as they come,
// for `thinslab acquire preview` (acquire/live_preview.h composes them). Use it from the thread
// that opened it, one per process.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

class PreviewWindow {
 public:
  ~PreviewWindow();
  // Shows an RGB8 picture of the window's size (row-major, width x height x 3).
  Status Show(const std::vector<uint8_t>& rgb);
  // True once the window was closed or q / Escape pressed (polls the event queue).
  bool CloseRequested();
  // What the window shows, read back from the renderer: RGB8, width x height x 3.
  Status ReadBack(std::vector<uint8_t>* rgb);
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  friend Status OpenPreviewWindow(int width, int height, const std::string& title, std::unique_ptr<PreviewWindow>*);
  PreviewWindow() = default;
  Status Render();
  void* window_ = nullptr;    // SDL_Window*
  void* renderer_ = nullptr;  // SDL_Renderer*
  void* texture_ = nullptr;   // SDL_Texture*
  int width_ = 0, height_ = 0;
  bool owns_sdl_video_ = false;
  bool close_requested_ = false;
};

// Opens the window on the default display ($DISPLAY). Errors name the SDL call and its message.
Status OpenPreviewWindow(int width, int height, const std::string& title, std::unique_ptr<PreviewWindow>* window);

}  // namespace thinslab
