// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/exr_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfMatrixAttribute.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>

#include <opencv2/imgcodecs.hpp>

#include "thinslab/core/file.h"
#include "thinslab/core/provenance.h"
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
    Image image(width, height, {"tau", "status", "tau_eq7"});
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
  for (const char* name : {"tau", "status", "tau_eq7"}) {
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
  for (const char* name : {"tau", "status", "tau_eq7"}) {
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
  image.at(2, 1, image.ChannelIndex("tau_eq7")) = std::numeric_limits<float>::quiet_NaN();
  const Status status = WriteExr(path, image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(path), HasSubstr("tau_eq7"), HasSubstr("(2, 1)")));
  EXPECT_FALSE(FileExists(path));

  image.at(2, 1, image.ChannelIndex("tau_eq7")) = 0.0f;
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

// Output maps (format 2.0): layer.channel names, the primary repeated as "Y", integer status,
// typed attributes and the provenance, as other programs read them.
TEST_F(ExrIoTest, MapLayoutIsWhatOtherProgramsRead) {
  const std::string path = JoinPath(dir_, "tau.exr");
  Image map = MakeImage(23, 17);
  map.numeric_attributes()["pixel_pitch_m"] = {1e-4};
  map.numeric_attributes()["region_min_m"] = {-0.01, 0.02};
  Rigid3d pose;
  pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  pose.translation = Eigen::Vector3d(0.01, -0.02, 0.4);
  SetWorldToCamera(pose, &map);
  const Provenance provenance{"fit tau", "session_glass_a", "", "threads = 2\n"};
  const Status status = WriteMapExr(path, map, {"tau", {"status"}}, provenance);
  ASSERT_TRUE(status.ok()) << status.message();

  // The file as OpenEXR itself lists it.
  Imf::InputFile file(path.c_str());
  const Imf::ChannelList& channels = file.header().channels();
  std::vector<std::string> names;
  for (auto it = channels.begin(); it != channels.end(); ++it) names.push_back(it.name());
  EXPECT_THAT(names, ElementsAre("Y", "status.Y", "tau.Y", "tau_eq7.Y"));
  EXPECT_EQ(channels.findChannel("status.Y")->type, Imf::UINT);
  EXPECT_EQ(channels.findChannel("tau.Y")->type, Imf::FLOAT);
  EXPECT_NE(file.header().findTypedAttribute<Imf::DoubleAttribute>("pixel_pitch_m"), nullptr);
  EXPECT_NE(file.header().findTypedAttribute<Imf::V2dAttribute>("region_min_m"), nullptr);
  // OpenEXR's standard camera attribute, in Imath's row-vector convention.
  const auto* w2c = file.header().findTypedAttribute<Imf::M44fAttribute>("worldToCamera");
  ASSERT_NE(w2c, nullptr);
  const Imath::V3f p_sample(0.003f, -0.002f, 0.0f);
  const Imath::V3f p_camera = p_sample * w2c->value();
  const Eigen::Vector3d expected = pose * Eigen::Vector3d(0.003, -0.002, 0.0);
  EXPECT_NEAR(p_camera.x, expected.x(), 1e-6);
  EXPECT_NEAR(p_camera.z, expected.z(), 1e-6);
  const auto* digest = file.header().findTypedAttribute<Imf::StringAttribute>("options_digest");
  ASSERT_NE(digest, nullptr);
  EXPECT_EQ(digest->value(), OptionsDigest("threads = 2\n"));
  for (const char* key : {"thinslab_version", "git_hash", "thinslab_command", "source_session", "comments"}) {
    EXPECT_NE(file.header().findTypedAttribute<Imf::StringAttribute>(key), nullptr) << key;
  }

  // cv::imread returns the primary map (OpenCV reads EXR only when the user enables it).
  setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 1);
  const cv::Mat seen = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(seen.empty());
  ASSERT_EQ(seen.type(), CV_32FC1);
  EXPECT_EQ(seen.at<float>(5, 7), map.at(7, 5, map.ChannelIndex("tau")));

  // ReadExr gives the plain names back, the values exact, the attributes typed.
  Image read;
  ASSERT_TRUE(ReadExr(path, &read).ok());
  ASSERT_EQ(read.num_channels(), 3);
  for (const char* name : {"tau", "status", "tau_eq7"}) {
    const int c_in = map.ChannelIndex(name), c_out = read.ChannelIndex(name);
    ASSERT_GE(c_out, 0) << name;
    for (size_t p = 0; p < map.num_pixels(); ++p) {
      ASSERT_EQ(read.data()[p * 3 + c_out], map.data()[p * 3 + c_in]) << name << " pixel " << p;
    }
  }
  ASSERT_NE(read.NumericAttribute("pixel_pitch_m", 1), nullptr);
  EXPECT_EQ((*read.NumericAttribute("pixel_pitch_m", 1))[0], 1e-4);
  Rigid3d back;
  ASSERT_TRUE(GetWorldToCamera(read, &back));
  EXPECT_LT((back.translation - pose.translation).norm(), 1e-6);
  EXPECT_GT(std::abs(back.rotation.dot(pose.rotation)), 1 - 1e-6);
  EXPECT_EQ(read.attributes().at("thinslab_command"), "fit tau");
}

TEST_F(ExrIoTest, MapRefusesANonIntegerInAnIntegerChannel) {
  const std::string path = JoinPath(dir_, "bad_status.exr");
  Image map = MakeImage(4, 3);
  map.at(1, 2, map.ChannelIndex("status")) = 2.5f;
  const Status status = WriteMapExr(path, map, {"tau", {"status"}}, {"fit tau", "s", "", ""});
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(path), HasSubstr("'status'"), HasSubstr("(1, 2)"),
                                      HasSubstr("not an unsigned integer")));
  EXPECT_FALSE(FileExists(path));
  EXPECT_FALSE(WriteMapExr(path, map, {"no_such_channel", {}}, {"fit tau", "s", "", ""}).ok());
}

// Maps written before format 2.0 still open, under today's names.
TEST_F(ExrIoTest, ReadsFormat1MapsUnderTodaysNames) {
  const std::string path = JoinPath(dir_, "old_maps.exr");
  Image old(5, 4, {"alpha", "smith_alpha", "residual", "tau_plain"}, 0.25f);
  old.attributes()["format_version"] = "1.0";
  old.attributes()["thinslab_version"] = "0.9.0";
  old.attributes()["pixel_pitch_m"] = "0.0002";
  old.attributes()["grid_min_m"] = "[-0.01, 0.005]";
  ASSERT_TRUE(WriteExr(path, old).ok());
  Image read;
  ASSERT_TRUE(ReadExr(path, &read).ok());
  for (const char* name : {"top_face_weight", "smith_alpha", "log_rms_residual", "tau_eq7"}) {
    EXPECT_GE(read.ChannelIndex(name), 0) << name;
  }
  ASSERT_NE(read.NumericAttribute("pixel_pitch_m", 1), nullptr);
  EXPECT_EQ((*read.NumericAttribute("pixel_pitch_m", 1))[0], 0.0002);
  ASSERT_NE(read.NumericAttribute("grid_min_m", 2), nullptr);
  EXPECT_EQ((*read.NumericAttribute("grid_min_m", 2))[1], 0.005);
}

}  // namespace
}  // namespace thinslab
