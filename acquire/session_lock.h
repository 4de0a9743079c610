// SPDX-License-Identifier: Apache-2.0
// One writer per session folder. `thinslab acquire` (new or resumed) and `thinslab acquire
// fold-journal` hold an exclusive flock(2) on OUTPUT/acquire.lock while they run, so a second
// process cannot append to the journal, rewrite session.json, remove "stale" temporaries or
// cut the journal's "incomplete" last line under a capture that is still running. The kernel
// drops the lock when its holder exits or is killed: a killed capture never leaves a stale lock
// (the file stays; it holds the pid of its last holder, for the message).
#pragma once

#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

constexpr char kSessionLockName[] = "acquire.lock";

// Whether a process holds `session_dir`'s lock now, without creating anything: `holder_pid` gets
// the pid written in the lock file when held. (A free lock is taken for an instant and released.)
enum class SessionLockState { kNoLockFile, kFree, kHeld };
SessionLockState ProbeSessionLock(const std::string& session_dir, std::string* holder_pid);

class SessionFolderLock {
 public:
  SessionFolderLock() = default;
  ~SessionFolderLock() { Release(); }
  SessionFolderLock(const SessionFolderLock&) = delete;
  SessionFolderLock& operator=(const SessionFolderLock&) = delete;

  // Creates `session_dir` if needed and takes the lock without waiting. Error, naming the
  // folder and the holder's pid, when another process (or another lock in this one) holds it.
  Status Acquire(const std::string& session_dir);
  void Release();
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

}  // namespace thinslab
