// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/command_progress.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace thinslab {
namespace {

std::string Lines(const std::vector<ProgressUpdate>& updates) {
  char* text = nullptr;
  size_t size = 0;
  std::FILE* out = open_memstream(&text, &size);
  const ProgressCallback print = ProgressLines(out, 5);
  for (const ProgressUpdate& u : updates) print(u);
  std::fclose(out);
  std::string lines(text, size);
  std::free(text);
  return lines;
}

ProgressUpdate At(const std::string& stage, int64_t done, int64_t total, double elapsed_s) {
  ProgressUpdate u;
  u.stage = stage;
  u.done = done;
  u.total = total;
  u.elapsed_s = elapsed_s;
  u.eta_s = done > 0 ? elapsed_s * (total - done) / done : -1;
  return u;
}

// Each stage gets its own lines every 5 s of its own time, also after a long stage (a 58-s stage
// once silenced every later stage shorter than 63 s: their elapsed time starts at 0).
TEST(ProgressLines, EveryStageEveryFiveSecondsOfItsOwn) {
  const std::string lines = Lines({At("long", 0, 100, 0), At("long", 50, 100, 29), At("long", 100, 100, 58),
                                   At("short", 0, 30, 0), At("short", 10, 30, 3), At("short", 20, 30, 6),
                                   At("short", 30, 30, 9), At("short", 0, 30, 0), At("short", 30, 30, 2)});
  EXPECT_EQ(lines,
            "long: 0/100, 0 s\nlong: 50/100, 29 s, ETA 29 s\nlong: 100/100, 58 s\n"
            "short: 0/30, 0 s\nshort: 20/30, 6 s, ETA 3 s\nshort: 30/30, 9 s\n"
            "short: 0/30, 0 s\nshort: 30/30, 2 s\n");
}

}  // namespace
}  // namespace thinslab
