// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/session_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "thinslab/core/file.h"

namespace thinslab {

namespace {

std::string ReadHolder(int fd) {
  char holder[32] = {0};
  const ssize_t n = ::pread(fd, holder, sizeof(holder) - 1, 0);
  std::string pid = n > 0 ? std::string(holder, static_cast<size_t>(n)) : "";
  while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
  return pid;
}

}  // namespace

SessionLockState ProbeSessionLock(const std::string& session_dir, std::string* holder_pid) {
  holder_pid->clear();
  const std::string path = JoinPath(session_dir, kSessionLockName);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return SessionLockState::kNoLockFile;
  SessionLockState state = SessionLockState::kFree;
  if (::flock(fd, LOCK_SH | LOCK_NB) != 0) {
    state = SessionLockState::kHeld;
    *holder_pid = ReadHolder(fd);
  }
  ::close(fd);  // Drops the shared lock, if taken.
  return state;
}

Status SessionFolderLock::Acquire(const std::string& session_dir) {
  Release();
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(session_dir));
  const std::string path = JoinPath(session_dir, kSessionLockName);
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return Status::Error(path + ": cannot open the session lock: " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    const std::string pid = ReadHolder(fd);
    ::close(fd);
    if (err != EWOULDBLOCK) return Status::Error(path + ": cannot lock: " + std::strerror(err));
    return Status::Error(session_dir + ": the session folder is in use by another thinslab acquire" +
                         (pid.empty() ? std::string() : " (process " + pid + ")") +
                         "; wait for it to end or stop it first");
  }
  // The holder's pid, for the message above; the lock itself is the flock, not this text.
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int err = errno;
    ::close(fd);
    return Status::Error(path + ": cannot write the session lock: " + std::strerror(err));
  }
  fd_ = fd;
  return Status::Ok();
}

void SessionFolderLock::Release() {
  if (fd_ < 0) return;
  ::close(fd_);  // Drops the flock.
  fd_ = -1;
}

}  // namespace thinslab
