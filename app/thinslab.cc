// SPDX-License-Identifier: Apache-2.0
// The thinslab command: a table of subcommands (COLMAP's exe/colmap.cc pattern).
// Exit codes (docs/cli.md): 0 success; 1 the command refused its input or failed (one line
// "error: ..." naming the file, field, option or device); 2 unknown command; 3 out of memory;
// 4 internal error (an exception no command handled, named with the command).
#include <glog/logging.h>

#include <cstring>
#include <exception>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "thinslab/app/commands.h"
#include "thinslab/app/data_directory.h"
#include "thinslab/core/version.h"

namespace {

struct Command {
  const char* name;
  int (*run)(int, char**);
  const char* help;
};

int RunVersion(int, char**) {
  std::cout << "thinslab " << THINSLAB_VERSION_STRING << " (git " << THINSLAB_GIT_HASH << ")\n"
            << "data: " << thinslab::DataDirectory() << "\n";
  return 0;
}

int RunHelp(int, char**);

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"help", RunHelp, "list the commands"},
      {"version", RunVersion, "print version, git hash and the data folder"},
      {"info", thinslab::RunInfo, "validate a capture session and summarise it"},
      {"acquire", thinslab::RunAcquire, "run a capture session on a rig (default: the simulated rig)"},
      {"sim", thinslab::RunSim, "simulate a capture session (sim shadow-maps | laser | dot-scan | pattern)"},
      {"calib", thinslab::RunCalib, "calibrate (calib camera | pose | dots | response | hdr | flat | gamma)"},
      {"fit", thinslab::RunFit, "fit a model to a capture (fit tau | phase | dmf)"},
      {"predict", thinslab::RunPredict, "what a fit (tau, phase, dmf) predicts for light states it was not fitted to"},
      {"demo", thinslab::RunDemo, "simulate a shadow-map capture, fit tau, report accuracy"},
      {"synth", thinslab::RunSynth, "synthesize contamination layers from measured prototypes"},
      {"bench", thinslab::RunBench, "speed-against-accuracy sweep of the fit knobs (bench sweep)"},
      {"charts", thinslab::RunCharts, "model-vs-Monte-Carlo charts of the optics models (docs/models)"},
  };
  return commands;
}

int RunHelp(int, char**) {
  std::cout << "thinslab " << THINSLAB_VERSION_STRING
            << ": measurement and fitting for thin transparent samples\n\nusage: thinslab <command> [args]\n\n";
  for (const auto& c : Commands()) std::cout << "  " << c.name << std::string(10 - std::strlen(c.name), ' ') << c.help << "\n";
  std::cout << "\n'thinslab <command> --help' lists a command's options.\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;
  if (argc < 2) {
    RunHelp(0, nullptr);
    return 1;
  }
  const std::string name = argv[1];
  for (const auto& c : Commands()) {
    if (name != c.name) continue;
    const std::string command = "thinslab " + name + (argc > 2 && argv[2][0] != '-' ? std::string(" ") + argv[2] : "");
    try {
      return c.run(argc - 2, argv + 2);
    } catch (const std::bad_alloc&) {
      std::cerr << "error: " << command << ": out of memory (the input needs more memory than this machine has)\n";
      return 3;
    } catch (const std::exception& e) {
      std::cerr << "error: " << command << ": internal error: " << e.what() << "\n";
      return 4;
    } catch (...) {
      std::cerr << "error: " << command << ": internal error (unknown exception)\n";
      return 4;
    }
  }
  std::cerr << "thinslab: unknown command '" << name << "' (try 'thinslab help')\n";
  return 2;
}
