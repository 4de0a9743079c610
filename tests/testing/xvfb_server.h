// SPDX-License-Identifier: Apache-2.0
// A private X server for tests of the SDL2 pattern window (drivers/pattern_window.h) and of
// `thinslab acquire --display`: Xvfb on a display number it picks itself, stopped with the test.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>

namespace thinslab {

// Starts Xvfb on a display it picks itself (-displayfd avoids racing other servers for a
// number), with a known screen size.
class XvfbServer {
 public:
  bool Start(int width_px, int height_px, std::string* error) {
    int fds[2];
    if (pipe(fds) != 0) {
      *error = "pipe failed";
      return false;
    }
    const std::string size = std::to_string(width_px) + "x" + std::to_string(height_px) + "x24";
    pid_ = fork();
    if (pid_ == 0) {
      // The server must not outlive a crashed test.
      prctl(PR_SET_PDEATHSIG, SIGTERM);
      close(fds[0]);
      const int devnull = open("/dev/null", O_WRONLY);
      if (devnull >= 0) {
        dup2(devnull, 1);
        dup2(devnull, 2);
      }
      const std::string fd = std::to_string(fds[1]);
      execlp("Xvfb", "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", size.c_str(), "-nolisten",
             "tcp", "-noreset", static_cast<char*>(nullptr));
      _exit(127);
    }
    close(fds[1]);
    std::string number;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < deadline) {
      pollfd p{fds[0], POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char c;
      const ssize_t n = read(fds[0], &c, 1);
      if (n <= 0) break;
      if (c == '\n') break;
      number += c;
    }
    close(fds[0]);
    if (number.empty()) {
      *error = "Xvfb did not report a display number within 10 s (is xvfb installed?)";
      return false;
    }
    display_ = ":" + number;
    return true;
  }
  void Stop() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status;
      waitpid(pid_, &status, 0);
      pid_ = -1;
    }
  }
  ~XvfbServer() { Stop(); }
  const std::string& display() const { return display_; }

 private:
  pid_t pid_ = -1;
  std::string display_;
};

}  // namespace thinslab
