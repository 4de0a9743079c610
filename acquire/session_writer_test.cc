// SPDX-License-Identifier: Apache-2.0
// SessionWriter's durability rule: frame file, then journal line; session.json at bounded
// intervals; the frames after the last manifest write are rebuilt from the journal, a journal
// line cut short by a kill is dropped, and a frame file written without its record is removed.
#include "thinslab/acquire/session_writer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

Session Header() {
  Session header = TinySessionHeader("shadow_map");
  header.acquisition.present = true;
  header.acquisition.state = "running";
  return header;
}

FrameRecord Shadow(int k) {
  FrameRecord r;
  r.camera_id = "cam0";
  r.kind = "shadow";
  r.sample_state = "contaminated";
  r.exposure_time_us = 1000 + k;
  r.light.projector_pattern = "flat";
  return r;
}

SessionWriterOptions Journaled(int min_new_frames, double growth_fraction = 0) {
  SessionWriterOptions options;
  options.journal = true;
  options.manifest_min_new_frames = min_new_frames;
  options.manifest_growth_fraction = growth_fraction;
  options.manifest_max_age_s = 1e6;
  return options;
}

int ManifestFrames(const std::string& dir) {
  Session s;
  EXPECT_TRUE(ReadSession(dir, &s).ok());
  return static_cast<int>(s.frames.size());
}

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

void Append(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::app | std::ios::binary);
  out << text;
}

TEST(SessionWriter, ManifestIsRewrittenOnAGeometricScheduleAndTheJournalHoldsEveryFrame) {
  TempDir dir;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(), Journaled(/*min_new_frames=*/4, /*growth_fraction=*/0.5)).ok());
  std::vector<int> held;  // Frames in session.json after each AddFrame.
  for (int k = 0; k < 40; ++k) {
    ASSERT_TRUE(writer.AddFrame(Shadow(k), Image(8, 6, 100.0f + k)).ok());
    held.push_back(ManifestFrames(dir / "s"));
  }
  // Rewrites at 4, 8, 12 (4 >= 0.5 x 8), 18 (6 >= 0.5 x 12), 27 (9 >= 0.5 x 18).
  std::vector<int> rewrites;
  for (int k = 0; k < 40; ++k) {
    if (held[k] != (k == 0 ? 0 : held[k - 1])) rewrites.push_back(held[k]);
    // Never further behind than the schedule allows.
    EXPECT_LT(k + 1 - held[k], std::max(4.0, 0.5 * held[k])) << "after frame " << k;
  }
  EXPECT_EQ(rewrites, (std::vector<int>{4, 8, 12, 18, 27}));
  EXPECT_EQ(held.back(), 27);
  EXPECT_EQ(writer.unsaved_frames(), 13);
  // Every frame has its journal line, in order.
  const std::vector<std::string> lines = Lines(dir / "s/journal.log");
  ASSERT_EQ(lines.size(), 40u);
  for (int k = 0; k < 40; ++k) {
    EXPECT_NE(lines[k].find(" frame " + std::to_string(k) + " ok captures=0 discarded=0 {"), std::string::npos)
        << lines[k];
  }
  ASSERT_TRUE(writer.Save().ok());
  EXPECT_EQ(ManifestFrames(dir / "s"), 40);
  EXPECT_EQ(writer.unsaved_frames(), 0);
}

TEST(SessionWriter, AStaleManifestIsRewrittenAfterItsMaximumAge) {
  TempDir dir;
  SessionWriterOptions options = Journaled(1000);
  options.manifest_max_age_s = 1e-9;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(), options).ok());
  ASSERT_TRUE(writer.AddFrame(Shadow(0), Image(8, 6, 1.0f)).ok());
  EXPECT_EQ(ManifestFrames(dir / "s"), 1);
}

TEST(SessionWriter, FramesAfterTheLastManifestWriteAreRebuiltFromTheJournal) {
  TempDir dir;
  {
    SessionWriter writer;  // "Killed": destroyed without Save().
    ASSERT_TRUE(writer.Open(dir / "s", Header(), Journaled(1000)).ok());
    for (int k = 0; k < 6; ++k) {
      writer.mutable_session()->acquisition.camera_captures = 2 * k + 1;
      if (k == 2) {
        ASSERT_TRUE(writer.AddFailedFrame(Shadow(k), "timeout").ok());
      } else {
        ASSERT_TRUE(writer.AddFrame(Shadow(k), Image(8, 6, 100.0f + k)).ok());
      }
    }
    writer.mutable_session()->acquisition.discarded_frames = 4;  // After the last frame: not durable.
  }
  EXPECT_EQ(ManifestFrames(dir / "s"), 0);
  Session rebuilt;
  int journaled = -1;
  const Status status = ReadSessionWithJournal(dir / "s", &rebuilt, &journaled);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(journaled, 6);
  ASSERT_EQ(rebuilt.frames.size(), 6u);
  for (int k = 0; k < 6; ++k) {
    const FrameRecord& f = rebuilt.frames[k];
    EXPECT_EQ(f.index, k);
    EXPECT_EQ(f.kind, "shadow");
    EXPECT_EQ(f.exposure_time_us, 1000 + k);
    EXPECT_EQ(f.light.projector_pattern, "flat");
    EXPECT_EQ(f.status, k == 2 ? FrameStatus::kFailed : FrameStatus::kOk);
  }
  EXPECT_EQ(rebuilt.frames[2].error, "timeout");
  EXPECT_EQ(rebuilt.frames[5].file, "frames/cam0/shadow/0005.png");
  EXPECT_EQ(rebuilt.acquisition.camera_captures, 11);
  EXPECT_EQ(rebuilt.acquisition.discarded_frames, 0);
  Image frame;
  ASSERT_TRUE(LoadFrame(dir / "s", rebuilt, rebuilt.frames[5], &frame).ok());
  EXPECT_EQ(frame.at(0, 0), 105.0f);

  // Reopening resumes with all six; the next frame is index 6, and the first manifest write
  // holds all seven.
  SessionWriter resumed;
  ASSERT_TRUE(resumed.Open(dir / "s", Header(), Journaled(1)).ok());
  EXPECT_EQ(resumed.steps_on_disk(), 5);
  int index = -1;
  ASSERT_TRUE(resumed.AddFrame(Shadow(6), Image(8, 6, 1.0f), &index).ok());
  EXPECT_EQ(index, 6);
  EXPECT_EQ(ManifestFrames(dir / "s"), 7);
}

TEST(SessionWriter, AJournalLineCutShortByAKillIsDroppedAndItsFrameFileRemoved) {
  TempDir dir;
  {
    SessionWriter writer;
    ASSERT_TRUE(writer.Open(dir / "s", Header(), Journaled(1000)).ok());
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(writer.AddFrame(Shadow(k), Image(8, 6, 1.0f)).ok());
  }
  // Frame 3 was written, and the kill came while its journal line was being written.
  ASSERT_TRUE(WriteRawFrame(dir / "s/frames/cam0/shadow/0003.png", Image(8, 6, 3.0f), 12).ok());
  Append(dir / "s/journal.log", "2026-12-02T00:00:00.000Z frame 3 ok captures=0 discarded=0 {\"index\":3,\"cam");
  Session rebuilt;
  ASSERT_TRUE(ReadSessionWithJournal(dir / "s", &rebuilt).ok());
  EXPECT_EQ(rebuilt.frames.size(), 3u);

  SessionWriter resumed;
  ASSERT_TRUE(resumed.Open(dir / "s", Header(), Journaled(1000)).ok());
  EXPECT_FALSE(FileExists(dir / "s/frames/cam0/shadow/0003.png")) << "an unrecorded frame file was kept";
  EXPECT_TRUE(FileExists(dir / "s/frames/cam0/shadow/0002.png"));
  // The failed attempt takes index 3; without the removal 0003.png would stay behind unrecorded.
  ASSERT_TRUE(resumed.AddFailedFrame(Shadow(3), "timeout").ok());
  ASSERT_TRUE(resumed.AddFrame(Shadow(3), Image(8, 6, 4.0f)).ok());
  const std::vector<std::string> lines = Lines(dir / "s/journal.log");
  ASSERT_EQ(lines.size(), 5u);  // The incomplete line is gone; the new ones start on lines of their own.
  EXPECT_NE(lines[3].find(" frame 3 failed "), std::string::npos) << lines[3];
  EXPECT_NE(lines[4].find(" frame 4 ok "), std::string::npos) << lines[4];
  ASSERT_TRUE(ReadSessionWithJournal(dir / "s", &rebuilt).ok());
  ASSERT_EQ(rebuilt.frames.size(), 5u);
  EXPECT_EQ(rebuilt.frames[4].file, "frames/cam0/shadow/0004.png");
}

TEST(SessionWriter, AMalformedOrMissingJournalRecordIsAnErrorNamingTheLine) {
  TempDir dir;
  {
    SessionWriter writer;
    ASSERT_TRUE(writer.Open(dir / "s", Header(), Journaled(1000)).ok());
    ASSERT_TRUE(writer.AppendJournalLine("started at 0 frames").ok());
    ASSERT_TRUE(writer.AddFrame(Shadow(0), Image(8, 6, 1.0f)).ok());
  }
  const std::string journal = dir / "s/journal.log";
  std::string good;
  ASSERT_TRUE(ReadFileToString(journal, &good).ok());
  Session s;

  // Lines of the audit-only journal of earlier versions are not records and are skipped.
  ASSERT_TRUE(WriteFileAtomically(journal, good + "2026-11-23T00:00:00Z frame 1 ok frames/cam0/shadow/0001.png\n").ok());
  ASSERT_TRUE(ReadSessionWithJournal(dir / "s", &s).ok());
  EXPECT_EQ(s.frames.size(), 1u);

  ASSERT_TRUE(WriteFileAtomically(journal, good + "2026-12-02T00:00:00Z frame 1 ok captures=0 discarded=0 "
                                                  "{\"index\":1,\"camera\":\"cam0\"}\n").ok());
  Status status = ReadSessionWithJournal(dir / "s", &s);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("journal.log:3: frame.kind: required field is missing"), std::string::npos)
      << status.message();

  std::string skipped = good;
  const size_t at = skipped.find("\"index\":0");
  ASSERT_NE(at, std::string::npos);
  skipped.replace(at, 9, "\"index\":1");
  ASSERT_TRUE(WriteFileAtomically(journal, skipped).ok());
  status = ReadSessionWithJournal(dir / "s", &s);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("journal.log:2: frame record 1 follows frame -1: records are missing"),
            std::string::npos)
      << status.message();

  // A record whose file is gone is refused like a manifest entry would be.
  ASSERT_TRUE(WriteFileAtomically(journal, good).ok());
  std::filesystem::remove(dir / "s/frames/cam0/shadow/0000.png");
  status = ReadSessionWithJournal(dir / "s", &s);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("journal.log"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("frames[0].file"), std::string::npos) << status.message();
}

TEST(SessionWriterOptions, CheckNamesTheField) {
  std::string error;
  SessionWriterOptions options;
  EXPECT_TRUE(options.Check(&error));
  options.manifest_min_new_frames = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("SessionWriterOptions::manifest_min_new_frames = 0"), std::string::npos) << error;
  options = SessionWriterOptions();
  options.manifest_growth_fraction = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("manifest_growth_fraction"), std::string::npos) << error;
  options = SessionWriterOptions();
  options.manifest_max_age_s = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("manifest_max_age_s"), std::string::npos) << error;
  SessionWriter writer;
  TempDir dir;
  EXPECT_FALSE(writer.Open(dir / "s", Header(), options).ok());
  EXPECT_FALSE(FileExists(dir / "s/session.json"));
}

}  // namespace
}  // namespace thinslab
