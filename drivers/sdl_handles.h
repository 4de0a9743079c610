// SPDX-License-Identifier: Apache-2.0
// Internal to the SDL2 back-ends (pattern_window.cc, preview_window.cc): their public headers
// hold SDL handles as void* so that users do not include SDL; these turn them back, and the
// SDL error text for messages.
#pragma once

#include <SDL.h>

#include <string>

namespace thinslab {
namespace sdl {

inline SDL_Window* AsWindow(void* p) { return static_cast<SDL_Window*>(p); }
inline SDL_Renderer* AsRenderer(void* p) { return static_cast<SDL_Renderer*>(p); }
inline SDL_Texture* AsTexture(void* p) { return static_cast<SDL_Texture*>(p); }

inline std::string Error() {
  const char* e = SDL_GetError();
  return e != nullptr && e[0] != '\0' ? std::string(e) : std::string("unknown SDL error");
}

}  // namespace sdl
}  // namespace thinslab
