// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/exr_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "thinslab/core/file.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

class ExrIoTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_.path(); }

  // Three channels with distinct, non-trivial values (including negatives and tiny ones).
  static Image MakeImage(int width, int height) {
    Image image(width, height, {"tau", "status", "tau_plain"});
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        image.at(x, y, 0) = 0.001f * static_cast<float>(x * 31 + y * 7) - 0.5f;
        image.at(x, y, 1) = static_cast<float>((x + y) % 5);
        image.at(x, y, 2) = std::sin(0.1f * static_cast<float>(x)) * 1e-3f + static_cast<float>(y);
      }
    }
    return image;
  }

  TempDir temp_;
  std::string dir_;
};

TEST_F(ExrIoTest, FloatRoundTripKeepsChannelsValuesAndAttributes) {
  const std::string path = JoinPath(dir_, "tau.exr");
  Image image = MakeImage(23, 17);
  image.attributes()["thinslab_version"] = "0.1.0";
  image.attributes()["cam_from_sample"] = "[1, 0, 0, 0] [0, 0, 0.3]";
  image.attributes()["source_session"] = "session_glass_a";
  const Status status = WriteExr(path, image);
  ASSERT_TRUE(status.ok()) << status.message();

  Image read;
  const Status read_status = ReadExr(path, &read);
  ASSERT_TRUE(read_status.ok()) << read_status.message();
  EXPECT_EQ(read.width(), 23);
  EXPECT_EQ(read.height(), 17);
  ASSERT_EQ(read.num_channels(), 3);
  // Channels are looked up by name; EXR stores them sorted.
  for (const char* name : {"tau", "status", "tau_plain"}) {
    const int c_in = image.ChannelIndex(name);
    const int c_out = read.ChannelIndex(name);
    ASSERT_GE(c_out, 0) << name;
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x) {
        ASSERT_EQ(read.at(x, y, c_out), image.at(x, y, c_in)) << name << " " << x << "," << y;
      }
    }
  }
  EXPECT_EQ(read.attributes().at("thinslab_version"), "0.1.0");
  EXPECT_EQ(read.attributes().at("cam_from_sample"), "[1, 0, 0, 0] [0, 0, 0.3]");
  EXPECT_EQ(read.attributes().at("source_session"), "session_glass_a");
  // No temporary file is left next to the output.
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir_)) names.push_back(entry.path().filename());
  EXPECT_THAT(names, ElementsAre("tau.exr"));
}

TEST_F(ExrIoTest, HalfRoundTripWithinHalfPrecision) {
  const std::string path = JoinPath(dir_, "half.exr");
  const Image image = MakeImage(9, 5);
  const Status status = WriteExr(path, image, ExrPixelType::kHalf);
  ASSERT_TRUE(status.ok()) << status.message();
  Image read;
  const Status read_status = ReadExr(path, &read);
  ASSERT_TRUE(read_status.ok()) << read_status.message();
  ASSERT_EQ(read.num_channels(), 3);
  // Half has an 11-bit significand: relative rounding error <= 2^-11 for normal values.
  const float rel = std::ldexp(1.0f, -11);
  for (const char* name : {"tau", "status", "tau_plain"}) {
    const int c_in = image.ChannelIndex(name);
    const int c_out = read.ChannelIndex(name);
    ASSERT_GE(c_out, 0);
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x) {
        const float expected = image.at(x, y, c_in);
        // Absolute floor for values in the half subnormal range (~6e-5).
        EXPECT_NEAR(read.at(x, y, c_out), expected, std::abs(expected) * rel + 6e-8f)
            << name << " " << x << "," << y;
      }
    }
  }
}

TEST_F(ExrIoTest, WriteRefusesNonFiniteNamingTheChannel) {
  const std::string path = JoinPath(dir_, "nan.exr");
  Image image = MakeImage(4, 3);
  image.at(2, 1, image.ChannelIndex("tau_plain")) = std::numeric_limits<float>::quiet_NaN();
  const Status status = WriteExr(path, image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(path), HasSubstr("tau_plain"), HasSubstr("(2, 1)")));
  EXPECT_FALSE(FileExists(path));

  image.at(2, 1, image.ChannelIndex("tau_plain")) = 0.0f;
  image.at(0, 0, image.ChannelIndex("tau")) = std::numeric_limits<float>::infinity();
  const Status inf_status = WriteExr(path, image);
  ASSERT_FALSE(inf_status.ok());
  EXPECT_THAT(inf_status.message(), HasSubstr("'tau'"));
}

TEST_F(ExrIoTest, TruncatedFileGivesAnErrorNamingIt) {
  const std::string path = JoinPath(dir_, "truncated.exr");
  ASSERT_TRUE(WriteExr(path, MakeImage(64, 48)).ok());
  std::string bytes;
  ASSERT_TRUE(ReadFileToString(path, &bytes).ok());
  ASSERT_TRUE(WriteFileAtomically(path, bytes.substr(0, bytes.size() / 2)).ok());
  Image read;
  const Status status = ReadExr(path, &read);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr(path));
}

TEST_F(ExrIoTest, TextFileGivesAnErrorNamingIt) {
  const std::string path = JoinPath(dir_, "notes.exr");
  ASSERT_TRUE(WriteFileAtomically(path, "this is a text file, not an EXR\n").ok());
  Image read;
  const Status status = ReadExr(path, &read);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr(path));
}

TEST_F(ExrIoTest, MissingFileGivesAnErrorNamingIt) {
  const std::string path = JoinPath(dir_, "missing.exr");
  Image read;
  const Status status = ReadExr(path, &read);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr(path));
}

TEST_F(ExrIoTest, WriteRefusesAnEmptyImage) {
  const Status status = WriteExr(JoinPath(dir_, "empty.exr"), Image());
  EXPECT_FALSE(status.ok());
}

}  // namespace
}  // namespace thinslab
