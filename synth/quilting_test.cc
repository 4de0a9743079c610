// SPDX-License-Identifier: Apache-2.0
// Image quilting (Efros and Freeman 2001) as used for dust by Gu et al. 2007, Sec. 5.3:
// statistics of the source are reproduced, seams are invisible by a boundary-error measure
// that a naive tiling fails, the seed fixes the output bit for bit, bad inputs are refused.
#include "thinslab/synth/quilting.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/synth/prototype_library.h"
#include "thinslab/synth/texture_statistics.h"

namespace thinslab {
namespace {

// A dust-like tau texture: Gaussian specks (sigma 1.2-3.5 px by default, peak 0.2-1.2) at
// random places, wrapped around the borders so the source is stationary.
Image DustTexture(int w, int h, int specks, uint64_t seed, double min_sigma_px = 1.2, double max_sigma_px = 3.5) {
  Image tau(w, h, {"tau"});
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int i = 0; i < specks; ++i) {
    const double cx = uni(rng) * w, cy = uni(rng) * h;
    const double sigma = min_sigma_px + (max_sigma_px - min_sigma_px) * uni(rng), peak = 0.2 + uni(rng);
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

// The statistics of one quilted output against its source.
struct QuiltStatistics {
  double ks = 0, mean_ratio = 0, autocorrelation_deviation = 0, seam_ratio = 0;
  double source_zero_fraction = 0, output_zero_fraction = 0;
  double seconds = 0;  // QuiltingSummary::total_s.
};

QuiltStatistics Measure(const Image& source, const Image& out, const Image& ids) {
  QuiltStatistics s;
  s.ks = KsDistance(source, out);
  s.mean_ratio = MeanValue(out) / MeanValue(source);
  s.autocorrelation_deviation = MaxAutocorrelationDeviation(out, source, 16);
  s.seam_ratio = SeamRatio(out, ids).ratio;
  s.source_zero_fraction = ZeroFraction(source);
  s.output_zero_fraction = ZeroFraction(out);
  return s;
}

QuiltStatistics QuiltAndMeasure(const Image& source, QuiltingOptions options, bool match_histogram) {
  options.match_histogram = match_histogram;
  Image out, ids;
  QuiltingSummary summary;
  const Status s = QuiltTexture(source, 256, 256, options, &out, &ids, &summary);
  EXPECT_TRUE(s.ok()) << s.message();
  QuiltStatistics stats = Measure(source, out, ids);
  stats.seconds = summary.total_s;
  return stats;
}

std::string ToString(const QuiltStatistics& s) {
  std::ostringstream o;
  o << "KS " << s.ks << ", mean ratio " << s.mean_ratio << ", autocorrelation deviation " << s.autocorrelation_deviation
    << ", seam ratio " << s.seam_ratio << ", zeros " << s.source_zero_fraction << " -> " << s.output_zero_fraction;
  return o.str();
}

// The statistics of quilting itself: QuiltingOptions::match_histogram is off, so nothing
// after patch selection and the boundary cut touches the values. Five 128x128 dust sources
// (110 specks each), 256x256 outputs, default options (mass-matched selection). Measured over
// these sources x 8 seeds (DISABLED_MeasureStatistics below; docs/models/contamination_synthesis.md,
// Sec. 4): KS 0.024 mean / 0.062 worst, mean tau ratio 0.987 / 0.944, autocorrelation
// deviation 0.075 / 0.139 (5 of 40 runs over 0.1), seam ratio 0.92 / 1.05. The per-run
// histogram bounds are that envelope plus about 15% (a regression guard; the KS 0.05
// and 2% hold in 37 and 28 of the 40 runs); autocorrelation and seams are asserted at the
// issue's tolerances on these five runs.
TEST(QuiltingTest, RawQuiltingReproducesHistogramAutocorrelationWithoutSeams) {
  double ks_sum = 0, mean_ratio_sum = 0;
  for (uint64_t source_seed = 1; source_seed <= 5; ++source_seed) {
    const Image source = DustTexture(128, 128, 110, source_seed);
    QuiltingOptions options;
    options.seed = 10 + source_seed;
    const QuiltStatistics s = QuiltAndMeasure(source, options, /*match_histogram=*/false);
    std::cout << "source seed " << source_seed << ": " << ToString(s) << "\n";
    SCOPED_TRACE("source seed " + std::to_string(source_seed) + ": " + ToString(s));
    EXPECT_LE(s.autocorrelation_deviation, /*max_autocorrelation_abs_error=*/0.1);
    EXPECT_LE(s.seam_ratio, /*max_seam_ratio=*/1.2);
    EXPECT_LE(s.ks, /*max_raw_ks_distance=*/0.07);
    EXPECT_GE(s.mean_ratio, /*min_raw_mean_tau_ratio=*/0.935);
    EXPECT_LE(s.mean_ratio, /*max_raw_mean_tau_ratio=*/1.05);
    ks_sum += s.ks;
    mean_ratio_sum += s.mean_ratio;
  }
  // Averages over the five (measured KS 0.020 and mean tau ratio 0.991; over the 40 runs 0.024
  // and 0.987).
  EXPECT_LE(ks_sum / 5, /*max_raw_mean_ks_distance=*/0.025);
  EXPECT_NEAR(mean_ratio_sum / 5, 1.0, /*max_raw_mean_of_mean_tau_rel_error=*/0.02);
}

// The bias the mass-matched selection removes: with Efros-Freeman's uniform draw among the
// qualifying candidates (kSsd), the same five runs lose dust (measured: mean tau ratio 0.889
// on average) and their histograms are further from the source's; the mass-matched draw
// keeps the dust within 2% on average and halves the KS distance.
TEST(QuiltingTest, MassMatchedSelectionKeepsTheDustUniformSelectionLoses) {
  double ratio[2] = {0, 0}, ks[2] = {0, 0};
  for (uint64_t source_seed = 1; source_seed <= 5; ++source_seed) {
    const Image source = DustTexture(128, 128, 110, source_seed);
    for (const int rule : {0, 1}) {
      QuiltingOptions options;
      options.selection = rule == 0 ? QuiltingSelection::kSsd : QuiltingSelection::kMassMatched;
      options.seed = 10 + source_seed;
      const QuiltStatistics s = QuiltAndMeasure(source, options, /*match_histogram=*/false);
      ratio[rule] += s.mean_ratio / 5;
      ks[rule] += s.ks / 5;
    }
  }
  EXPECT_LT(ratio[0], 0.95) << "uniform selection no longer loses dust: the comparison is void";
  EXPECT_NEAR(ratio[1], 1.0, 0.02);
  EXPECT_LT(ks[1], 0.6 * ks[0]);
}

// How far a texture's statistics are from the source's, over many runs: the mean and the
// worst of each statistic (|mean tau ratio - 1| for the amount of dust).
struct StatisticsSpread {
  double ks_mean = 0, ks_worst = 0, mass_mean = 0, mass_worst = 0, acf_mean = 0, acf_worst = 0;
  int runs = 0;
  void Add(const Image& texture, const Image& source) {
    const double ks = KsDistance(texture, source);
    const double mass = std::abs(MeanValue(texture) / MeanValue(source) - 1);
    const double acf = MaxAutocorrelationDeviation(texture, source, 16);
    ks_mean = (ks_mean * runs + ks) / (runs + 1);
    mass_mean = (mass_mean * runs + mass) / (runs + 1);
    acf_mean = (acf_mean * runs + acf) / (runs + 1);
    ks_worst = std::max(ks_worst, ks);
    mass_worst = std::max(mass_worst, mass);
    acf_worst = std::max(acf_worst, acf);
    ++runs;
  }
  std::string ToString() const {
    std::ostringstream o;
    o << "KS " << ks_mean << " / " << ks_worst << ", |mean tau ratio - 1| " << mass_mean << " / " << mass_worst
      << ", autocorrelation deviation " << acf_mean << " / " << acf_worst << " (mean / worst of " << runs << ")";
    return o.str();
  }
};

// The tolerance of each statistic is its own sampling spread. A 128 x 128 source holds ~110
// specks, so its histogram, mean and autocorrelation are themselves noisy estimates of its
// process's: a second, independent 256 x 256 sample of the very process that made the source
// (DustTexture with 4x the specks, another seed) differs from it by autocorrelation deviation
// 0.100 on average and 0.170 at worst (15 of 40 runs over 0.1), KS 0.032 / 0.080, mean tau
// 6% / 14% (measured here). No synthesis can be asked to match the source more closely than
// its own process does, so quilting passes when, over the same 40 runs, its mean and worst
// distance are no larger than the independent samples' (measured raw: autocorrelation
// 0.075 / 0.139, KS 0.024 / 0.062, mean tau 1.6% / 5.6%; remapped: 0.076 / 0.138,
// 0.009 / 0.026, 0.0% / 0.0%), and the seams stay invisible on every run. The criterion
// can fail: a sample of another process (specks twice as large) and quilting with 6 px patches,
// smaller than the specks, both exceed it (autocorrelation 0.46 and 0.30 on average).
TEST(QuiltingTest, QuiltingMatchesTheSourceAsCloselyAsAnIndependentSampleOfItsProcess) {
  StatisticsSpread independent, raw, remapped, other_process, small_patches;
  for (uint64_t source_seed = 1; source_seed <= 5; ++source_seed) {
    const Image source = DustTexture(128, 128, 110, source_seed);
    for (uint64_t seed = 0; seed < 8; ++seed) {
      independent.Add(DustTexture(256, 256, 4 * 110, 1000 + 10 * source_seed + seed), source);
      other_process.Add(DustTexture(256, 256, 110, 2000 + 10 * source_seed + seed, 2.4, 7.0), source);
      for (const bool match_histogram : {false, true}) {
        QuiltingOptions options;
        options.seed = 10 + source_seed + 100 * seed;
        options.match_histogram = match_histogram;
        Image out, ids;
        QuiltingSummary summary;
        ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &out, &ids, &summary).ok());
        (match_histogram ? remapped : raw).Add(out, source);
        EXPECT_LE(SeamRatio(out, ids).ratio, /*max_seam_ratio=*/1.2);
      }
      if (seed == 0) {
        QuiltingOptions options;
        options.seed = 10 + source_seed;
        options.patch_px = 6;
        options.overlap_px = 2;
        options.match_histogram = false;
        Image out, ids;
        QuiltingSummary summary;
        ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &out, &ids, &summary).ok());
        small_patches.Add(out, source);
      }
    }
  }
  std::cout << "independent samples: " << independent.ToString() << "\nquilting, raw: " << raw.ToString()
            << "\nquilting, remapped: " << remapped.ToString() << "\nanother process: " << other_process.ToString()
            << "\n6 px patches: " << small_patches.ToString() << "\n";
  auto within_spread = [&independent](const StatisticsSpread& s) {
    return s.ks_mean <= independent.ks_mean && s.ks_worst <= independent.ks_worst &&
           s.mass_mean <= independent.mass_mean && s.mass_worst <= independent.mass_worst &&
           s.acf_mean <= independent.acf_mean && s.acf_worst <= independent.acf_worst;
  };
  EXPECT_TRUE(within_spread(raw)) << raw.ToString() << "\nagainst " << independent.ToString();
  EXPECT_TRUE(within_spread(remapped)) << remapped.ToString() << "\nagainst " << independent.ToString();
  // The negative controls.
  EXPECT_GT(other_process.acf_mean, independent.acf_mean) << other_process.ToString();
  EXPECT_FALSE(within_spread(other_process));
  EXPECT_GT(small_patches.acf_mean, independent.acf_mean) << small_patches.ToString();
  EXPECT_FALSE(within_spread(small_patches));
}

TEST(QuiltingTest, NaiveTilingFailsTheSeamMeasure) {
  // The negative control: random 32 px blocks side by side (no overlap, no cut) must show
  // seams, or the measure above is blind.
  const Image source = DustTexture(128, 128, 110, 5);
  Image naive, naive_ids;
  NaiveTiling(source, 256, 256, QuiltingOptions().patch_px, 2, &naive, &naive_ids);
  EXPECT_GE(SeamRatio(naive, naive_ids).ratio, 1.5);
}

// What the remap (match_histogram, the default) does on top of quilting, same seed: it is a
// monotone function of the raw output (spatial order kept, every value a source value),
// clean pixels stay clean, and the histogram and the amount of dust come closer to the
// source's than raw quilting's.
TEST(QuiltingTest, HistogramRemapKeepsOrderAndCleanGlassAndMatchesTheSource) {
  for (uint64_t source_seed = 1; source_seed <= 5; ++source_seed) {
    const Image source = DustTexture(128, 128, 110, source_seed);
    QuiltingOptions options;
    options.seed = 10 + source_seed;
    options.match_histogram = false;
    Image raw, ids, remapped;
    ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &raw, &ids).ok());
    options.match_histogram = true;
    QuiltingSummary summary;
    ASSERT_TRUE(QuiltTexture(source, 256, 256, options, &remapped, nullptr, &summary).ok());
    const QuiltStatistics r = Measure(source, raw, ids), m = Measure(source, remapped, ids);
    SCOPED_TRACE("source seed " + std::to_string(source_seed) + ": raw " + ToString(r) + "; remapped " + ToString(m));
    EXPECT_DOUBLE_EQ(summary.quilted_zero_fraction, r.output_zero_fraction);
    EXPECT_DOUBLE_EQ(summary.source_zero_fraction, r.source_zero_fraction);
    // Order: sorting the pixels by raw value sorts the remapped values too.
    std::vector<std::pair<float, float>> pairs;
    for (size_t i = 0; i < raw.data().size(); ++i) pairs.emplace_back(raw.data()[i], remapped.data()[i]);
    std::sort(pairs.begin(), pairs.end());
    for (size_t i = 1; i < pairs.size(); ++i) ASSERT_LE(pairs[i - 1].second, pairs[i].second);
    // Clean glass stays clean; a positive value becomes 0 only while the output has fewer
    // zeros than the source (then exactly the source's share, up to one group of ties).
    for (size_t i = 0; i < raw.data().size(); ++i) {
      if (raw.data()[i] == 0.0f) {
        ASSERT_EQ(remapped.data()[i], 0.0f) << "pixel " << i;
      }
    }
    EXPECT_NEAR(m.output_zero_fraction, std::max(r.output_zero_fraction, r.source_zero_fraction), 0.002);
    // Histogram: within the tolerances (KS 0.05, 2%); measured over 40 runs KS 0.026
    // worst (0.046 with kSsd), mean tau ratio 0.9995 worst. The only remaining difference is
    // the clean area quilting added.
    EXPECT_LE(m.ks, /*max_ks_distance=*/0.03);
    EXPECT_LE(m.ks, std::max(0.0, r.output_zero_fraction - r.source_zero_fraction) + 0.002);
    EXPECT_LE(m.ks, r.ks + 1e-9);
    EXPECT_NEAR(m.mean_ratio, 1.0, /*max_mean_tau_rel_error=*/0.02);
    // The remap changes values, not places: the seam measure stays within tolerance
    // (measured 1.06 worst).
    EXPECT_LE(m.seam_ratio, /*max_seam_ratio=*/1.2);
  }
}

// A dense dust field (few clean pixels) with one clean 64x64 block: about a quarter of the
// source is clean glass. A small output whose first patch lands in the block stays clean
// (a clean overlap is matched best by clean candidates), so it has more than twice the
// source's clean share. The old mid-rank rule then gave the whole zero group the source
// quantile at half the output's clean share, a positive tau: a haze over all clean glass.
// Over many seeds, every pixel that quilting left clean must stay exactly 0. The case needs
// Efros-Freeman's uniform draw (kSsd): the mass-matched default steers the output's dust
// towards the source's and made it occur in 0 of the 60 runs.
TEST(QuiltingTest, CleanGlassStaysCleanWhenTheOutputIsCleanerThanTheSource) {
  Image source = DustTexture(128, 128, 300, 8);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) source.at(x, y) = 0.0f;
  }
  int cleaner_outputs = 0;
  for (uint64_t seed = 1; seed <= 60; ++seed) {
    QuiltingOptions options;
    options.selection = QuiltingSelection::kSsd;
    options.seed = seed;
    options.match_histogram = false;
    Image raw, remapped;
    QuiltingSummary summary;
    ASSERT_TRUE(QuiltTexture(source, 64, 64, options, &raw).ok());
    options.match_histogram = true;
    ASSERT_TRUE(QuiltTexture(source, 64, 64, options, &remapped, nullptr, &summary).ok());
    cleaner_outputs += summary.quilted_zero_fraction > 2 * summary.source_zero_fraction;
    for (size_t i = 0; i < raw.data().size(); ++i) {
      if (raw.data()[i] == 0.0f) {
        ASSERT_EQ(remapped.data()[i], 0.0f)
            << "seed " << seed << ": clean pixel " << i << " got a haze (" << summary.source_zero_fraction
            << " clean in the source, " << summary.quilted_zero_fraction << " in the output)";
      }
    }
  }
  std::cout << cleaner_outputs << " of 60 outputs are more than twice as clean as the source\n";
  EXPECT_GE(cleaner_outputs, 3) << "the case this test is for did not occur";
}

TEST(SpecifyHistogramTest, ZerosStayZeroAndOtherValuesTakeSourceQuantiles) {
  // Source: 30% zeros, then 1..70. Output with 80% zeros: the zeros stay 0 (the old rule gave
  // them the quantile at rank 40%, value 10), the positives keep their rank quantile.
  std::vector<float> source(100, 0.0f);
  for (int i = 30; i < 100; ++i) source[i] = static_cast<float>(i - 29);
  std::vector<float> values(50, 0.0f);
  for (int i = 40; i < 50; ++i) values[i] = 0.5f + i;
  SpecifyHistogram(source, &values);
  for (int i = 0; i < 40; ++i) EXPECT_EQ(values[i], 0.0f) << i;
  for (int i = 40; i < 50; ++i) {
    EXPECT_GT(values[i], 0.0f) << i;
    EXPECT_TRUE(std::binary_search(source.begin(), source.end(), values[i])) << values[i];
    if (i > 40) {
      EXPECT_GT(values[i], values[i - 1]);
    }
  }
  EXPECT_EQ(values[49], 70.0f);
  // Output with 10% zeros: the faintest values become 0 up to the source's 30%.
  std::vector<float> fewer(100);
  for (int i = 0; i < 100; ++i) fewer[i] = i < 10 ? 0.0f : static_cast<float>(i);
  SpecifyHistogram(source, &fewer);
  EXPECT_EQ(std::count(fewer.begin(), fewer.end(), 0.0f), 30);
  EXPECT_EQ(fewer, source);
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
  // Efros-Freeman's uniform draw too, and the two rules differ.
  options.seed = 42;
  options.selection = QuiltingSelection::kSsd;
  Image d, e;
  ASSERT_TRUE(QuiltTexture(source, 200, 150, options, &d).ok());
  ASSERT_TRUE(QuiltTexture(source, 200, 150, options, &e).ok());
  EXPECT_EQ(d.data(), e.data());
  EXPECT_NE(a.data(), d.data());
}

TEST(QuiltingTest, OutputValuesComeFromTheSource) {
  // Quilting copies pixels (no blending) and the remap picks source values, so with and
  // without it every output value occurs in the source.
  const Image source = DustTexture(64, 64, 30, 1);
  std::vector<float> values = source.data();
  std::sort(values.begin(), values.end());
  for (const bool match_histogram : {false, true}) {
    QuiltingOptions options;
    options.patch_px = 16;
    options.overlap_px = 4;
    options.match_histogram = match_histogram;
    Image out;
    ASSERT_TRUE(QuiltTexture(source, 70, 33, options, &out).ok());
    EXPECT_EQ(out.width(), 70);
    EXPECT_EQ(out.height(), 33);
    for (float v : out.data()) EXPECT_TRUE(std::binary_search(values.begin(), values.end(), v));
  }
}

// Not run by default: the measurements behind the tolerances above and the figures of
// docs/models/contamination_synthesis.md, Sec. 4. Run with
//   THINSLAB_SOURCE_DIR=$PWD build/synth/synth_quilting_test --gtest_also_run_disabled_tests
//     --gtest_filter='*MeasureStatistics*'
TEST(QuiltingTest, DISABLED_MeasureStatistics) {
  auto report = [](const std::string& name, const std::vector<QuiltStatistics>& runs) {
    QuiltStatistics mean, worst;
    worst.mean_ratio = 1;
    for (const auto& r : runs) {
      mean.ks += r.ks / runs.size();
      mean.mean_ratio += r.mean_ratio / runs.size();
      mean.autocorrelation_deviation += r.autocorrelation_deviation / runs.size();
      mean.seam_ratio += r.seam_ratio / runs.size();
      mean.source_zero_fraction += r.source_zero_fraction / runs.size();
      mean.output_zero_fraction += r.output_zero_fraction / runs.size();
      mean.seconds += r.seconds / runs.size();
      worst.ks = std::max(worst.ks, r.ks);
      if (std::abs(r.mean_ratio - 1) > std::abs(worst.mean_ratio - 1)) worst.mean_ratio = r.mean_ratio;
      worst.autocorrelation_deviation = std::max(worst.autocorrelation_deviation, r.autocorrelation_deviation);
      worst.seam_ratio = std::max(worst.seam_ratio, r.seam_ratio);
      worst.output_zero_fraction = std::max(worst.output_zero_fraction, r.output_zero_fraction);
    }
    // Runs beyond the tolerances the tests imply (KS 0.05, mean tau 2%,
    // autocorrelation 0.1, seam ratio 1.2).
    int over[4] = {0, 0, 0, 0};
    for (const auto& r : runs) {
      over[0] += r.ks > 0.05;
      over[1] += std::abs(r.mean_ratio - 1) > 0.02;
      over[2] += r.autocorrelation_deviation > 0.1;
      over[3] += r.seam_ratio > 1.2;
    }
    std::cout << name << " (" << runs.size() << " runs)\n  mean:  " << ToString(mean) << "\n  worst: KS " << worst.ks
              << ", mean ratio " << worst.mean_ratio << ", autocorrelation deviation "
              << worst.autocorrelation_deviation << ", seam ratio " << worst.seam_ratio << ", output zeros "
              << worst.output_zero_fraction << "\n  runs over KS 0.05: " << over[0] << ", over 2% mean: " << over[1]
              << ", over autocorrelation 0.1: " << over[2] << ", over seam 1.2: " << over[3]
              << "\n  quilting time per run: " << mean.seconds << " s\n";
  };
  // THINSLAB_QUILT_SEED_OFFSET shifts every seed, to see how much the figures move.
  const char* offset_text = std::getenv("THINSLAB_QUILT_SEED_OFFSET");
  const uint64_t offset = offset_text ? std::strtoull(offset_text, nullptr, 10) : 0;
  const char* source_dir = std::getenv("THINSLAB_SOURCE_DIR");
  Prototype dust;
  if (source_dir != nullptr) {
    const Status s = ReadPrototype(std::string(source_dir) + "/data/prototypes/dust_specks_a", &dust);
    ASSERT_TRUE(s.ok()) << s.message();
  }
  for (const QuiltingSelection selection : {QuiltingSelection::kSsd, QuiltingSelection::kMassMatched}) {
    const std::string rule = selection == QuiltingSelection::kSsd ? "selection=ssd" : "selection=mass_matched";
    for (const bool match_histogram : {false, true}) {
      const std::string remap = match_histogram ? ", match_histogram=on" : ", match_histogram=off";
      std::vector<QuiltStatistics> runs;
      for (uint64_t source_seed = 1; source_seed <= 5; ++source_seed) {
        const Image source = DustTexture(128, 128, 110, source_seed);
        for (uint64_t seed = 0; seed < 8; ++seed) {
          QuiltingOptions options;
          options.selection = selection;
          options.seed = 10 + source_seed + 100 * seed + offset;
          runs.push_back(QuiltAndMeasure(source, options, match_histogram));
        }
      }
      report("synthetic dust, 5 sources x 8 seeds, " + rule + remap, runs);
      if (source_dir == nullptr) continue;
      runs.clear();
      for (uint64_t seed = 1; seed <= 8; ++seed) {
        QuiltingOptions options;
        options.selection = selection;
        options.seed = seed + offset;
        runs.push_back(QuiltAndMeasure(dust.tau, options, match_histogram));
      }
      report("bundled dust_specks_a, 8 seeds, " + rule + remap, runs);
    }
  }
  if (source_dir == nullptr) return;
  Image naive, naive_ids;
  NaiveTiling(dust.tau, 256, 256, QuiltingOptions().patch_px, 2, &naive, &naive_ids);
  std::cout << "naive tiling of dust_specks_a: seam ratio " << SeamRatio(naive, naive_ids).ratio << "\n";
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
  options = QuiltingOptions();
  options.max_tilt = 0;
  s = QuiltTexture(source, 64, 64, options, &out);
  EXPECT_NE(s.message().find("QuiltingOptions::max_tilt"), std::string::npos) << s.message();
  options = QuiltingOptions();
  options.mass_feedback = -1;
  s = QuiltTexture(source, 64, 64, options, &out);
  EXPECT_NE(s.message().find("QuiltingOptions::mass_feedback"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
