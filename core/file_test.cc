// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/image.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/png_io.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::IsEmpty;
using ::testing::UnorderedElementsAre;

class FileTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_.path(); }

  // Names of the entries directly inside `dir`.
  static std::vector<std::string> List(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
      names.push_back(entry.path().filename().string());
    }
    return names;
  }

  static std::string Read(const std::string& path) {
    std::string bytes;
    const Status status = ReadFileToString(path, &bytes);
    EXPECT_TRUE(status.ok()) << status.message();
    return bytes;
  }

  TempDir temp_;
  std::string dir_;
};

TEST_F(FileTest, WriteFileAtomicallyReplacesContentAndLeavesNoTemporary) {
  const std::string path = JoinPath(dir_, "out.txt");
  ASSERT_TRUE(WriteFileAtomically(path, "first version, rather long").ok());
  EXPECT_EQ(Read(path), "first version, rather long");
  ASSERT_TRUE(WriteFileAtomically(path, "second").ok());
  EXPECT_EQ(Read(path), "second");
  EXPECT_THAT(List(dir_), ElementsAre("out.txt"));

  // Binary content, including NUL bytes, survives unchanged.
  const std::string binary("a\0b\xff\n", 5);
  ASSERT_TRUE(WriteFileAtomically(path, binary).ok());
  EXPECT_EQ(Read(path), binary);
  ASSERT_TRUE(WriteFileAtomically(path, "").ok());
  EXPECT_EQ(Read(path), "");
  EXPECT_THAT(List(dir_), ElementsAre("out.txt"));
}

TEST_F(FileTest, WriteFileAtomicallyIntoMissingFolderFailsNamingThePath) {
  const std::string path = JoinPath(dir_, "no_such_folder/out.txt");
  const Status status = WriteFileAtomically(path, "x");
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), ::testing::HasSubstr(path));
  EXPECT_THAT(List(dir_), IsEmpty());
}

TEST_F(FileTest, ReadFileToStringNamesAMissingFile) {
  std::string bytes;
  const std::string path = JoinPath(dir_, "missing.txt");
  const Status status = ReadFileToString(path, &bytes);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), ::testing::HasSubstr(path));
  EXPECT_FALSE(FileExists(path));
  EXPECT_TRUE(DirectoryExists(dir_));
  EXPECT_FALSE(FileExists(dir_));
}

TEST_F(FileTest, StagedDirectoryCommitMovesFilesIntoPlace) {
  const std::string final_dir = JoinPath(dir_, "fit");
  {
    StagedDirectory staged(final_dir, "fit tau");
    ASSERT_TRUE(staged.Init().ok());
    EXPECT_EQ(staged.final_path(), final_dir);
    EXPECT_NE(staged.path(), final_dir);
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "tau").ok());
    ASSERT_TRUE(CreateDirectories(JoinPath(staged.path(), "debug")).ok());
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "debug/pixel.txt"), "p").ok());
    EXPECT_FALSE(DirectoryExists(final_dir));  // Nothing visible before Commit().
    const Status status = staged.Commit();
    ASSERT_TRUE(status.ok()) << status.message();
  }
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "tau");
  EXPECT_EQ(Read(JoinPath(final_dir, "debug/pixel.txt")), "p");
  EXPECT_EQ(ReadOutputStamp(final_dir), "fit tau");
  EXPECT_THAT(List(dir_), ElementsAre("fit"));
}

TEST_F(FileTest, StagedDirectoryCommitReplacesAnOlderFolder) {
  const std::string final_dir = JoinPath(dir_, "fit");
  ASSERT_TRUE(CreateDirectories(final_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, kOutputStampName), OutputStampText("fit tau")).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "stale.txt"), "old").ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "tau.exr"), "old tau").ok());
  {
    StagedDirectory staged(final_dir + "/", "fit tau");  // A trailing slash names the same folder.
    ASSERT_TRUE(staged.Init().ok());
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "new tau").ok());
    // The old output stays intact until Commit().
    EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "old tau");
    ASSERT_TRUE(staged.Commit().ok());
  }
  EXPECT_THAT(List(final_dir), UnorderedElementsAre("tau.exr", kOutputStampName));
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "new tau");
  EXPECT_EQ(ReadOutputStamp(final_dir), "fit tau");
  EXPECT_THAT(List(dir_), ElementsAre("fit"));  // No staging or ".old" folder left behind.
}

TEST_F(FileTest, StagedDirectoryWithoutCommitLeavesNothing) {
  const std::string final_dir = JoinPath(dir_, "fit");
  std::string staging_dir;
  {
    StagedDirectory staged(final_dir, "fit tau");
    ASSERT_TRUE(staged.Init().ok());
    staging_dir = staged.path();
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "partial").ok());
    EXPECT_TRUE(DirectoryExists(staging_dir));
    // Leaves scope without Commit(), as on an error path.
  }
  EXPECT_FALSE(DirectoryExists(staging_dir));
  EXPECT_FALSE(DirectoryExists(final_dir));
  EXPECT_THAT(List(dir_), IsEmpty());
}

TEST_F(FileTest, StagedDirectoryWithoutCommitKeepsTheOlderFolder) {
  const std::string final_dir = JoinPath(dir_, "fit");
  ASSERT_TRUE(CreateDirectories(final_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, kOutputStampName), OutputStampText("fit tau")).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "tau.exr"), "old tau").ok());
  {
    StagedDirectory staged(final_dir, "fit tau");
    ASSERT_TRUE(staged.Init().ok());
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "partial").ok());
  }
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "old tau");
  EXPECT_THAT(List(dir_), ElementsAre("fit"));
}

// The user's own folder, or another command's output, is never replaced (issue #22).
TEST_F(FileTest, StagedDirectoryRefusesAFolderThinslabDidNotWrite) {
  const std::string final_dir = JoinPath(dir_, "mine");
  ASSERT_TRUE(CreateDirectories(final_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "thesis.tex"), "years of work").ok());
  StagedDirectory staged(final_dir, "fit tau");
  const Status status = staged.Init();
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), ::testing::HasSubstr(final_dir));
  EXPECT_THAT(status.message(), ::testing::HasSubstr("not written by thinslab"));
  EXPECT_EQ(Read(JoinPath(final_dir, "thesis.tex")), "years of work");
  EXPECT_THAT(List(dir_), ElementsAre("mine"));

  const std::string other = JoinPath(dir_, "dmf");
  ASSERT_TRUE(CreateDirectories(other).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(other, kOutputStampName), OutputStampText("fit dmf")).ok());
  StagedDirectory tau_over_dmf(other, "fit tau");
  const Status other_status = tau_over_dmf.Init();
  ASSERT_FALSE(other_status.ok());
  EXPECT_THAT(other_status.message(), ::testing::HasSubstr("fit dmf"));
}

TEST_F(FileTest, StagedDirectoryRefusesAFolderAppearingBeforeCommit) {
  const std::string final_dir = JoinPath(dir_, "fit");
  StagedDirectory staged(final_dir, "fit tau");
  ASSERT_TRUE(staged.Init().ok());
  ASSERT_TRUE(CreateDirectories(final_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "notes.txt"), "mine").ok());
  EXPECT_FALSE(staged.Commit().ok());
  EXPECT_EQ(Read(JoinPath(final_dir, "notes.txt")), "mine");
}

TEST_F(FileTest, StagedDirectoryRemovesStagingFoldersOfKilledRuns) {
  const std::string final_dir = JoinPath(dir_, "fit");
  // A pid that cannot be running: above the kernel's pid_max (4194304 at most).
  const std::string dead = final_dir + ".partial-999999999";
  const std::string alive = final_dir + ".partial-1";  // init: a run still going.
  ASSERT_TRUE(CreateDirectories(dead).ok());
  ASSERT_TRUE(CreateDirectories(alive).ok());
  StagedDirectory staged(final_dir, "fit tau");
  ASSERT_TRUE(staged.Init().ok());
  EXPECT_FALSE(DirectoryExists(dead));
  EXPECT_TRUE(DirectoryExists(alive));
}

TEST_F(FileTest, StagedDirectoryPutsBackAnOutputAKilledCommitMovedAside) {
  const std::string final_dir = JoinPath(dir_, "fit");
  const std::string old_dir = final_dir + ".old-999999999";
  ASSERT_TRUE(CreateDirectories(old_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(old_dir, kOutputStampName), OutputStampText("fit tau")).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(old_dir, "tau.exr"), "old tau").ok());
  StagedDirectory staged(final_dir, "fit tau");
  ASSERT_TRUE(staged.Init().ok());
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "old tau");
  EXPECT_FALSE(DirectoryExists(old_dir));
}

TEST_F(FileTest, OutputOutsideInputs) {
  const std::string capture = JoinPath(dir_, "S");
  ASSERT_TRUE(CreateDirectories(JoinPath(capture, "frames")).ok());
  const std::vector<InputPath> inputs = {{capture, {"fit", "calib"}}};
  EXPECT_TRUE(CheckOutputOutsideInputs(JoinPath(capture, "fit/tau"), inputs).ok());
  EXPECT_TRUE(CheckOutputOutsideInputs(JoinPath(capture, "calib/response.json"), inputs).ok());
  EXPECT_TRUE(CheckOutputOutsideInputs(JoinPath(dir_, "elsewhere"), inputs).ok());
  EXPECT_TRUE(CheckOutputOutsideInputs(JoinPath(dir_, "S2"), inputs).ok());  // A sibling with a common prefix.
  for (const std::string& bad : {capture, capture + "/", capture + "/frames", capture + "/session.json", dir_,
                                capture + "/fit/../frames", capture + "/fitx"}) {
    const Status status = CheckOutputOutsideInputs(bad, inputs);
    EXPECT_FALSE(status.ok()) << bad;
    EXPECT_THAT(status.message(), ::testing::HasSubstr(bad));
  }
  // Through a symlink that names the capture by another path.
  const std::string link = JoinPath(dir_, "link");
  fs::create_directory_symlink(capture, link);
  EXPECT_FALSE(CheckOutputOutsideInputs(link + "/frames", inputs).ok());
  // An input file: the output may not be it.
  const std::string layer = JoinPath(dir_, "layer.exr");
  ASSERT_TRUE(WriteFileAtomically(layer, "x").ok());
  EXPECT_FALSE(CheckOutputOutsideInputs(layer, {{layer, {}}}).ok());
  EXPECT_TRUE(CheckOutputOutsideInputs(layer + ".png", {{layer, {}}}).ok());
}

TEST_F(FileTest, ReplaceableFileIsOnlyOneThinslabWrote) {
  const std::string json = JoinPath(dir_, "response.json");
  EXPECT_TRUE(CheckReplaceableFile(json).ok());  // Absent.
  ASSERT_TRUE(WriteFileAtomically(json, R"({"format": "thinslab-response"})").ok());
  EXPECT_TRUE(CheckReplaceableFile(json).ok());
  ASSERT_TRUE(WriteFileAtomically(json, R"({"format": "my-lab"})").ok());
  EXPECT_FALSE(CheckReplaceableFile(json).ok());
  const std::string txt = JoinPath(dir_, "gamma.txt");
  ASSERT_TRUE(WriteFileAtomically(txt, "# thinslab display gamma table\n0 0\n").ok());
  EXPECT_TRUE(CheckReplaceableFile(txt).ok());
  ASSERT_TRUE(WriteFileAtomically(txt, "my notes\n").ok());
  const Status status = CheckReplaceableFile(txt);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), ::testing::HasSubstr(txt));
  EXPECT_FALSE(CheckReplaceableFile(dir_).ok());  // A folder where a file belongs.
  const std::string png = JoinPath(dir_, "photo.png");
  ASSERT_TRUE(WriteFileAtomically(png, "\x89PNG fake").ok());
  EXPECT_FALSE(CheckReplaceableFile(png).ok());
}

TEST_F(FileTest, JoinPath) {
  EXPECT_EQ(JoinPath("a", "b.json"), "a/b.json");
  EXPECT_EQ(JoinPath("a/", "b.json"), "a/b.json");
  EXPECT_EQ(JoinPath("", "b.json"), "b.json");
}

// The marks IsThinslabFile looks for are the ones thinslab's own writers put in, and a marked
// PNG stays a valid PNG (the text chunk's CRC is checked by libpng on reading).
TEST_F(FileTest, ThinslabWritersMarkTheirFiles) {
  const std::string png = JoinPath(dir_, "mark.png");
  cv::Mat pixels(7, 5, CV_8UC1, cv::Scalar(200));
  ASSERT_TRUE(WritePngAtomically(png, pixels).ok());
  EXPECT_TRUE(IsThinslabFile(png));
  const cv::Mat back = cv::imread(png, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(back.cols, 5);
  EXPECT_EQ(back.at<uint8_t>(3, 2), 200);
  const std::string foreign_png = JoinPath(dir_, "foreign.png");
  ASSERT_TRUE(cv::imwrite(foreign_png, pixels));
  EXPECT_FALSE(IsThinslabFile(foreign_png));

  const std::string exr = JoinPath(dir_, "mark.exr");
  Image image(3, 2, {"tau"});
  ASSERT_TRUE(WriteExr(exr, image).ok());
  EXPECT_TRUE(IsThinslabFile(exr));
  Image read;
  ASSERT_TRUE(ReadExr(exr, &read).ok());
  EXPECT_EQ(read.attributes().count("thinslab_version"), 1u);
  const std::string renamed = JoinPath(dir_, "mark.json");  // Not JSON: not thinslab's.
  fs::copy_file(exr, renamed);
  EXPECT_FALSE(IsThinslabFile(renamed));
}

}  // namespace
}  // namespace thinslab
