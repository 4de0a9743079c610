// SPDX-License-Identifier: Apache-2.0
// Image quilting (Efros and Freeman 2001) as used for dust by Gu et al. 2007, Sec. 5.3:
// statistics of the source are reproduced, seams are invisible by a boundary-error measure
// that a naive tiling fails, the seed fixes the output bit for bit, bad inputs are refused.
#include "synth/quilting.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include "core/math.h"

namespace thinslab {
namespace {

// A dust-like tau texture: Gaussian specks (sigma 1.2-3.5 px, peak 0.2-1.2) at random places,
// wrapped around the borders so the source is stationary.
Image DustTexture(int w, int h, int specks, uint64_t seed) {
  Image tau(w, h, {"tau"});
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int i = 0; i < specks; ++i) {
    const double cx = uni(rng) * w, cy = uni(rng) * h, sigma = 1.2 + 2.3 * uni(rng), peak = 0.2 + uni(rng);
    const int r = static_cast<int>(std::ceil(4 * sigma));
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const int x = ((static_cast<int>(cx) + dx) % w + w) % w, y = ((static_cast<int>(cy) + dy) % h + h) % h;
        const double d2 = Sqr(static_cast<int>(cx) + dx + 0.5 - cx) + Sqr(static_cast<int>(cy) + dy + 0.5 - cy);
        tau.at(x, y) += static_cast<float>(peak * std::exp(-0.5 * d2 / Sqr(sigma)));
      }
    }
  }
  return tau;
}

// Two-sample Kolmogorov-Smirnov statistic of the pixel values.
double KsDistance(const Image& a, const Image& b) {
  std::vector<float> x = a.data(), y = b.data();
  std::sort(x.begin(), x.end());
  std::sort(y.begin(), y.end());
  size_t i = 0, j = 0;
  double d = 0;
  while (i < x.size() && j < y.size()) {
    const float v = std::min(x[i], y[j]);
    while (i < x.size() && x[i] <= v) ++i;
    while (j < y.size() && y[j] <= v) ++j;
    d = std::max(d, std::abs(static_cast<double>(i) / x.size() - static_cast<double>(j) / y.size()));
  }
  return d;
}

// Normalised autocovariance at lag (dx, dy), over the pixels where both ends are inside.
double Autocorrelation(const Image& t, int dx, int dy) {
  double mean = 0;
  for (float v : t.data()) mean += v;
  mean /= t.data().size();
  double var = 0, cov = 0;
  int64_t n = 0;
  for (float v : t.data()) var += Sqr(v - mean);
  var /= t.data().size();
  for (int y = 0; y + dy < t.height(); ++y) {
    for (int x = 0; x + dx < t.width(); ++x) {
      cov += (t.at(x, y) - mean) * (t.at(x + dx, y + dy) - mean);
      ++n;
    }
  }
  return cov / n / var;
}

// Boundary error: mean |difference| between 4-neighbours that come from different patches
// (across a seam), divided by the same over neighbours from the same patch. A visible seam
// is a jump, so it raises the ratio above 1; an invisible one keeps it near or below 1 (the
// minimum-error cut runs where the two patches agree).
double SeamRatio(const Image& t, const Image& ids) {
  double across = 0, within = 0;
  int64_t n_across = 0, n_within = 0;
  for (int y = 0; y < t.height(); ++y) {
    for (int x = 0; x < t.width(); ++x) {
      for (int k = 0; k < 2; ++k) {
        const int x2 = x + (k == 0), y2 = y + (k == 1);
        if (x2 >= t.width() || y2 >= t.height()) continue;
        const double d = std::abs(t.at(x, y) - t.at(x2, y2));
        if (ids.at(x, y) != ids.at(x2, y2)) {
          across += d;
          ++n_across;
        } else {
          within += d;
          ++n_within;
        }
      }
    }
  }
  EXPECT_GT(n_across, 0);
  EXPECT_GT(n_within, 0);
  return (across / n_across) / (within / n_within);
}

// Naive tiling (random source blocks side by side, no overlap, no cut): the negative control
// that shows the seam measure can fail.
void NaiveTiling(const Image& src, int w, int h, int block, uint64_t seed, Image* out, Image* ids) {
  *out = Image(w, h, {"tau"});
  *ids = Image(w, h, {"patch_index"});
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> px(0, src.width() - block), py(0, src.height() - block);
  int id = 0;
  for (int by = 0; by < h; by += block) {
    for (int bx = 0; bx < w; bx += block, ++id) {
      const int sx = px(rng), sy = py(rng);
      for (int y = by; y < std::min(h, by + block); ++y) {
        for (int x = bx; x < std::min(w, bx + block); ++x) {
          out->at(x, y) = src.at(sx + x - bx, sy + y - by);
          ids->at(x, y) = static_cast<float>(id);
        }
      }
    }
  }
}

TEST(QuiltingTest, ReproducesHistogramAndAutocorrelation) {
  const Image source = DustTexture(128, 128, 110, 3);
  QuiltingOptions options;
  options.seed = 11;
  Image out, ids;
  QuiltingSummary summary;
  ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &out, &ids, &summary).ok());
  ASSERT_EQ(out.width(), 256);
  ASSERT_EQ(out.height(), 256);
  EXPECT_GT(summary.patches, 100);
  // Histogram: two-sample KS distance of the tau values <= 0.05, and mean tau within 2%.
  EXPECT_LE(KsDistance(source, out), 0.05);
  double ms = 0, mo = 0;
  for (float v : source.data()) ms += v;
  for (float v : out.data()) mo += v;
  ms /= source.data().size();
  mo /= out.data().size();
  EXPECT_NEAR(mo / ms, 1.0, 0.02);  // Histogram specification keeps the amount of dust.
  // Autocorrelation: normalised autocovariance at lags 1..16 px along x and y within 0.1 of
  // the source's (the specks are 2-8 px wide, so this covers their shape and spacing).
  for (int lag = 1; lag <= 16; ++lag) {
    EXPECT_NEAR(Autocorrelation(out, lag, 0), Autocorrelation(source, lag, 0), 0.1) << "x lag " << lag;
    EXPECT_NEAR(Autocorrelation(out, 0, lag), Autocorrelation(source, 0, lag), 0.1) << "y lag " << lag;
  }
}

TEST(QuiltingTest, SeamsAreInvisibleButNaiveTilingSeamsAreNot) {
  const Image source = DustTexture(128, 128, 110, 5);
  QuiltingOptions options;
  options.seed = 2;
  Image out, ids;
  ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &out, &ids).ok());
  const double quilted = SeamRatio(out, ids);
  Image naive, naive_ids;
  NaiveTiling(source, 256, 256, options.patch_px, 2, &naive, &naive_ids);
  const double tiled = SeamRatio(naive, naive_ids);
  // Stated tolerance (docs/models/contamination_synthesis.md): quilting seams <= 1.2x the
  // within-patch difference; the naive control must exceed 1.5x, or the measure is blind.
  EXPECT_LE(quilted, 1.2) << "naive tiling: " << tiled;
  EXPECT_GE(tiled, 1.5) << "quilted: " << quilted;
}

TEST(QuiltingTest, SameSeedSameBitsOtherSeedOtherOutput) {
  const Image source = DustTexture(96, 80, 60, 9);
  QuiltingOptions options;
  options.patch_px = 24;
  options.overlap_px = 6;
  options.max_candidates = 300;  // Exercise the sampled-candidate path too.
  options.seed = 42;
  Image a, b, c;
  ASSERT_TRUE(QuiltTexture(source, 200, 150, options, &a).ok());
  ASSERT_TRUE(QuiltTexture(source, 200, 150, options, &b).ok());
  EXPECT_EQ(a.data(), b.data());
  options.seed = 43;
  ASSERT_TRUE(QuiltTexture(source, 200, 150, options, &c).ok());
  EXPECT_NE(a.data(), c.data());
}

TEST(QuiltingTest, OutputValuesComeFromTheSource) {
  // Quilting copies pixels (no blending), so every output value occurs in the source.
  const Image source = DustTexture(64, 64, 30, 1);
  std::vector<float> values = source.data();
  std::sort(values.begin(), values.end());
  QuiltingOptions options;
  options.patch_px = 16;
  options.overlap_px = 4;
  Image out;
  ASSERT_TRUE(QuiltTexture(source, 70, 33, options, &out).ok());
  EXPECT_EQ(out.width(), 70);
  EXPECT_EQ(out.height(), 33);
  for (float v : out.data()) EXPECT_TRUE(std::binary_search(values.begin(), values.end(), v));
}

TEST(QuiltingTest, BadInputsGiveClearErrors) {
  const Image source = DustTexture(64, 64, 30, 1);
  QuiltingOptions options;
  Image out;
  Status s = QuiltTexture(Image(20, 20, {"tau"}), 64, 64, options, &out);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("smaller than one 32 px patch"), std::string::npos) << s.message();
  s = QuiltTexture(source, 0, 64, options, &out);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("impossible"), std::string::npos) << s.message();
  s = QuiltTexture(source, 64, 100000, options, &out);
  EXPECT_FALSE(s.ok());
  Image nan_source = source;
  nan_source.at(3, 4) = std::nanf("");
  s = QuiltTexture(nan_source, 64, 64, options, &out);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("(3, 4)"), std::string::npos) << s.message();
  options.overlap_px = 20;
  s = QuiltTexture(source, 64, 64, options, &out);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("QuiltingOptions::overlap_px"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
