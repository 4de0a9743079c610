// SPDX-License-Identifier: Apache-2.0
// PatternWindow: the real Projector back-end, a (fullscreen) SDL2 window on a chosen display
// showing pattern ids (drivers/pattern_id.h) for projectors and CRT/LCD monitors.
// ShowPattern rasterises the pattern in linear levels, applies the inverse of the measured
// display gamma (a gamma table file; identity by default), uploads it to a streaming texture,
// presents, waits for `settle_presents` further vsynced presents and then `settle_s` seconds so
// the displayed light is stable before the caller exposes. See docs/drivers.md, "Display".
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/display_gamma.h"
#include "thinslab/drivers/pattern_id.h"

namespace thinslab {

struct PatternWindowOptions {
  int display_index = 0;
  double dot_radius_px = 2;
  // Wait after the pattern's first vsynced present: LCD response time and projector colour wheel
  // or CRT phosphor stabilisation. 50 ms covers common LCD panels (docs/drivers.md).
  double settle_s = 0.05;
  // Vsynced presents of the same frame after the first one, so a frame that was queued when
  // ShowPattern was called has certainly been scanned out.
  int settle_presents = 2;
  std::string gamma_table_path;  // Empty: identity (driven level = linear level).
  bool fullscreen = true;
  int width_px = 0, height_px = 0;  // 0 = the display's current mode.
};

// Rounds a requested exposure to a whole number (>= 1) of refresh periods so every pixel of a
// scanned display is integrated the same number of times. refresh_period_s <= 0 returns the
// request unchanged.
double ExposureAsRefreshMultiple(double requested_s, double refresh_period_s);

// Use a PatternWindow from the thread that opened it (SDL video calls are not thread-safe), and
// keep at most one open per process.
class PatternWindow : public Projector {
 public:
  ~PatternWindow() override;
  Status ShowPattern(const std::string& pattern) override;
  double refresh_period_s() const override { return refresh_period_s_; }
  int width() const { return width_; }
  int height() const { return height_; }
  // SDL render driver in use ("opengl", "opengles2", "software", ...), for logs and manifests.
  const std::string& renderer_name() const { return renderer_name_; }
  // The drive levels last uploaded (after gamma), 8-bit, row-major, width x height.
  const std::vector<uint8_t>& last_drive() const { return last_drive_; }
  // Reads the renderer's current back buffer (re-renders the last pattern first) as one
  // luminance channel in drive levels [0, 255] (mean of R, G, B).
  Status ReadBackFramebuffer(Image* image);

 private:
  friend Status OpenPatternWindow(const PatternWindowOptions&, std::unique_ptr<PatternWindow>*);
  PatternWindow() = default;
  Status Present();

  PatternWindowOptions options_;
  GammaTable gamma_;
  void* window_ = nullptr;    // SDL_Window*
  void* renderer_ = nullptr;  // SDL_Renderer*
  void* texture_ = nullptr;   // SDL_Texture*
  bool owns_sdl_video_ = false;
  int width_ = 0, height_ = 0;
  double refresh_period_s_ = 0;
  std::string renderer_name_;
  std::vector<uint8_t> last_drive_;
};

// Errors: display index out of range (names the index and the number of displays), SDL video
// initialisation failure (names SDL_GetError and $DISPLAY), unreadable gamma table.
Status OpenPatternWindow(const PatternWindowOptions& options, std::unique_ptr<PatternWindow>* out);

}  // namespace thinslab
