// SPDX-License-Identifier: Apache-2.0
// The thinslab command: a table of subcommands (COLMAP's exe/colmap.cc pattern).
// Exit codes (docs/cli.md): 0 success; 1 the command refused its input or failed (one line
// "error: ..." naming the file, field, option or device); 2 unknown command; 3 out of memory;
// 4 internal error (an exception no command handled, named with the command).
#include <glog/logging.h>

#include <cstring>
#include <exception>
#include <malloc.h>

#include <iostream>
#include <sstream>
#include <new>
#include <string>
#include <vector>

#include "thinslab/app/bash_completion.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/data_directory.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/app/verbosity.h"
#include "thinslab/core/file.h"
#include "thinslab/core/process_group.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/version.h"

namespace {

struct Command {
  const char* name;
  int (*run)(int, char**);
  const char* help;
  const std::vector<thinslab::Subcommand>& (*subcommands)();  // nullptr: none.
};

int RunVersion(int, char**) {
  std::cout << "thinslab " << THINSLAB_VERSION_STRING << " (git " << THINSLAB_GIT_HASH << ")\n"
            << "data: " << thinslab::DataDirectory() << "\n";
  return 0;
}

int RunHelp(int, char**);
int RunCompletion(int argc, char** argv);

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"help", RunHelp, "list the commands", nullptr},
      {"version", RunVersion, "print version, git hash and the data folder", nullptr},
      {"info", thinslab::RunInfo, "validate a capture session and summarise it", nullptr},
      {"check", thinslab::RunCheck, "is a capture good enough to fit? (saturation, exposure, motion, flicker, geometry)",
       nullptr},
      {"acquire", thinslab::RunAcquire, "run a capture session on a rig (default: the simulated rig)",
       thinslab::AcquireSubcommands},
      {"sim", thinslab::RunSim, "simulate a capture session", thinslab::SimSubcommands},
      {"calib", thinslab::RunCalib, "calibrate the rig", thinslab::CalibSubcommands},
      {"fit", thinslab::RunFit, "fit a model to a capture", thinslab::FitSubcommands},
      {"predict", thinslab::RunPredict, "what a fit (tau, phase, dmf) predicts for light states it was not fitted to",
       nullptr},
      {"export", thinslab::RunExport, "a fit as a Mitsuba 3, pbrt-v4 or Blender scene", thinslab::ExportSubcommands},
      {"preview", thinslab::RunPreviewFit, "a fit in a canonical scene (checkerboard, window pane), with its own models",
       nullptr},
      {"roundtrip", thinslab::RunRoundTrip,
       "a fit tau rendered by Blender under the capture's own rig, against the capture and predict", nullptr},
      {"batch", thinslab::RunBatch, "refit every capture in a folder; current fits skipped, resumable, one table", nullptr},
      {"demo", thinslab::RunDemo, "simulate a shadow-map capture, fit tau, report accuracy", nullptr},
      {"synth", thinslab::RunSynth, "synthesize contamination layers from measured prototypes", thinslab::SynthSubcommands},
      {"bench", thinslab::RunBench, "speed against accuracy of the fit knobs", thinslab::BenchSubcommands},
      {"charts", thinslab::RunCharts, "model-vs-Monte-Carlo charts of the optics models (docs/models)", nullptr},
      {"completion", RunCompletion, "print the bash completion script (completion bash [FILE])", nullptr},
  };
  return commands;
}

int RunHelp(int, char**) {
  std::cout << "thinslab " << THINSLAB_VERSION_STRING
            << ": measurement and fitting for thin transparent samples\n\nusage: thinslab <command> [args]\n\n";
  for (const auto& c : Commands()) {
    std::cout << "  " << c.name << std::string(12 - std::strlen(c.name), ' ') << c.help << "\n";
    if (c.subcommands != nullptr) std::cout << thinslab::SubcommandLines("  " + std::string(c.name), c.subcommands());
  }
  std::cout << "\n'thinslab <command> [<subcommand>] --help' lists a command's options. Every command also takes\n"
               "--config FILE (repeat a run from its options.ini), --quiet and --verbose (docs/cli.md).\n";
  return 0;
}

int RunCompletion(int argc, char** argv) {
  if (argc < 1 || std::string(argv[0]) != "bash" || argc > 2) {
    std::cerr << "usage: thinslab completion bash [FILE]   (bash is the one shell supported)\n";
    return argc == 0 ? 2 : 1;
  }
  std::vector<std::pair<std::string, std::vector<std::string>>> tree;
  for (const auto& c : Commands()) {
    std::vector<std::string> names;
    if (c.subcommands != nullptr) {
      for (const auto& s : c.subcommands()) names.push_back(s.name);
    }
    tree.emplace_back(c.name, names);
  }
  const std::string script = thinslab::BashCompletionScript(tree);
  if (argc == 1) {
    std::cout << script;
    return 0;
  }
  const thinslab::Status status = thinslab::WriteFileAtomically(argv[1], script);
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
  return 0;
}

int RunCommandLine(int argc, char** argv);

}  // namespace

int main(int argc, char** argv) {
  // Frame-sized buffers (a camera image is a few MB) are allocated and freed once per frame:
  // from glibc's default mmap threshold and heap trimming each one came back as fresh pages,
  // and their page faults cost about a quarter of a dot scan's processing (perf, 2026-12-06).
  // Kept in the heap instead (up to 128 MiB of free heap before it is returned), freed buffers
  // are reused.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 128 << 20);
  // Under mpirun (issue #29 item 2): every process runs the command; rank 0 alone speaks.
  if (const thinslab::Status started = thinslab::StartProcessGroup(&argc, &argv); !started.ok()) {
    std::cerr << "error: " << started.message() << "\n";
    return 1;
  }
  const int code = RunCommandLine(argc, argv);
  thinslab::FinishProcessGroup(code);
  return code;
}

namespace {

int RunCommand(int argc, char** argv);

// Processes other than rank 0 of a group print nothing; their error output is kept and shown
// (named with the rank) only when the error is theirs alone (the shared ones rank 0 prints).
int RunCommandLine(int argc, char** argv) {
  thinslab::ProcessGroup& group = thinslab::ProcessGroup::World();
  if (!group.distributed()) return RunCommand(argc, argv);
  const bool shared_out = argc > 2 && std::string(argv[1]) == "fit" && std::string(argv[2]) == "dmf";
  if (!shared_out) {
    const std::string refusal = "thinslab " + std::string(argc > 1 ? argv[1] : "") +
                                " runs as one process; under mpirun only `thinslab fit dmf` shares its work out "
                                "(docs/batch.md)";
    group.Agree(thinslab::Status::Error(refusal));  // Every process knows: none is left waiting.
    if (group.root()) std::cerr << "error: " << refusal << "\n";
    return 1;
  }
  if (group.root()) return RunCommand(argc, argv);
  std::ostringstream quiet_out, kept_err;
  std::streambuf* out = std::cout.rdbuf(quiet_out.rdbuf());
  std::streambuf* err = std::cerr.rdbuf(kept_err.rdbuf());
  const int code = RunCommand(argc, argv);
  std::cout.rdbuf(out);
  std::cerr.rdbuf(err);
  if (code != 0 && !group.shared_error()) {
    std::istringstream lines(kept_err.str());
    for (std::string line; std::getline(lines, line);) {
      std::cerr << "process " << group.rank() << " of " << group.size() << ": " << line << "\n";
    }
  }
  return code;
}

int RunCommand(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;
  if (argc < 2) {
    RunHelp(0, nullptr);
    return 1;
  }
  const std::string name = argv[1];
  std::string command_line = "thinslab";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool plain = !arg.empty() && arg.find_first_of(" \t'\"\\$*?;&|<>()") == std::string::npos;
    command_line += " " + (plain ? arg : "'" + arg + "'");
  }
  thinslab::SetCommandLine(command_line);
  for (const auto& c : Commands()) {
    if (name != c.name) continue;
    const std::string command = "thinslab " + name + (argc > 2 && argv[2][0] != '-' ? std::string(" ") + argv[2] : "");
    try {
      const thinslab::VerbosityScope verbosity;  // A command's --quiet ends with it.
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

}  // namespace
