// SPDX-License-Identifier: Apache-2.0
#include "core/file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <string>
#include <vector>

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
    StagedDirectory staged(final_dir);
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
  EXPECT_THAT(List(dir_), ElementsAre("fit"));
}

TEST_F(FileTest, StagedDirectoryCommitReplacesAnOlderFolder) {
  const std::string final_dir = JoinPath(dir_, "fit");
  ASSERT_TRUE(CreateDirectories(final_dir).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "stale.txt"), "old").ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "tau.exr"), "old tau").ok());
  {
    StagedDirectory staged(final_dir + "/");  // A trailing slash names the same folder.
    ASSERT_TRUE(staged.Init().ok());
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "new tau").ok());
    // The old output stays intact until Commit().
    EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "old tau");
    ASSERT_TRUE(staged.Commit().ok());
  }
  EXPECT_THAT(List(final_dir), UnorderedElementsAre("tau.exr"));
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "new tau");
  EXPECT_THAT(List(dir_), ElementsAre("fit"));  // No staging or ".old" folder left behind.
}

TEST_F(FileTest, StagedDirectoryWithoutCommitLeavesNothing) {
  const std::string final_dir = JoinPath(dir_, "fit");
  std::string staging_dir;
  {
    StagedDirectory staged(final_dir);
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
  ASSERT_TRUE(WriteFileAtomically(JoinPath(final_dir, "tau.exr"), "old tau").ok());
  {
    StagedDirectory staged(final_dir);
    ASSERT_TRUE(staged.Init().ok());
    ASSERT_TRUE(WriteFileAtomically(JoinPath(staged.path(), "tau.exr"), "partial").ok());
  }
  EXPECT_EQ(Read(JoinPath(final_dir, "tau.exr")), "old tau");
  EXPECT_THAT(List(dir_), ElementsAre("fit"));
}

TEST_F(FileTest, JoinPath) {
  EXPECT_EQ(JoinPath("a", "b.json"), "a/b.json");
  EXPECT_EQ(JoinPath("a/", "b.json"), "a/b.json");
  EXPECT_EQ(JoinPath("", "b.json"), "b.json");
}

}  // namespace
}  // namespace thinslab
