// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/process.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

extern char** environ;

namespace thinslab {

Status StartProgram(const std::vector<std::string>& argv, const std::string& log_path, pid_t* pid) {
  if (argv.empty() || argv[0].empty()) return Status::Error("StartProgram: no program");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int spawned = posix_spawnp(pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    return Status::Error("cannot run '" + argv[0] + "': " + std::strerror(spawned));
  }
  return Status::Ok();
}

Status WaitProgram(pid_t pid, pid_t* ended, int* exit_code) {
  int status = 0;
  pid_t done;
  while ((done = waitpid(pid, &status, 0)) < 0) {
    if (errno != EINTR) return Status::Error(std::string("waiting for a child process: ") + std::strerror(errno));
  }
  if (ended != nullptr) *ended = done;
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return Status::Ok();
}

Status PollProgram(pid_t pid, bool* ended, int* exit_code) {
  int status = 0;
  pid_t done;
  while ((done = waitpid(pid, &status, WNOHANG)) < 0) {
    if (errno != EINTR) return Status::Error(std::string("waiting for a child process: ") + std::strerror(errno));
  }
  *ended = done == pid;
  if (*ended) *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return Status::Ok();
}

Status RunProgram(const std::vector<std::string>& argv, const std::string& log_path, int* exit_code) {
  pid_t pid = 0;
  THINSLAB_RETURN_IF_ERROR(StartProgram(argv, log_path, &pid));
  return WaitProgram(pid, nullptr, exit_code);
}

Status SelfExecutable(std::string* path) {
  std::vector<char> buffer(4096);
  const ssize_t n = readlink("/proc/self/exe", buffer.data(), buffer.size() - 1);
  if (n <= 0) return Status::Error(std::string("/proc/self/exe: ") + std::strerror(errno));
  path->assign(buffer.data(), static_cast<size_t>(n));
  return Status::Ok();
}

}  // namespace thinslab
