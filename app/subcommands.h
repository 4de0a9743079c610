// SPDX-License-Identifier: Apache-2.0
// The second level of the command tree, `thinslab <command> <subcommand>`: one table per
// command, used to dispatch, by `thinslab help` and by the bash completion, so a subcommand
// that runs is a subcommand that is listed.
#pragma once

#include <string>
#include <vector>

namespace thinslab {

struct Subcommand {
  const char* name;
  int (*run)(int argc, char** argv);  // The arguments after the subcommand's name.
  const char* args;                   // Its positional arguments, for the usage line.
  const char* help;
};

// Runs the subcommand argv[0] of `command`. A missing, `help` or unknown one prints the table
// (and `extra_usage`) on stderr; exit 0 for help, 2 otherwise, with an `error:` line naming an
// unknown one as a `what` (e.g. "subcommand", "session kind").
int DispatchSubcommand(const std::string& command, const std::vector<Subcommand>& table, int argc, char** argv,
                       const std::string& what = "subcommand", const std::string& extra_usage = "");
// "  <command> <name> <args>   <help>" lines.
std::string SubcommandLines(const std::string& command, const std::vector<Subcommand>& table);

const std::vector<Subcommand>& SimSubcommands();      // app/sim_commands.cc
const std::vector<Subcommand>& FitSubcommands();      // app/fit_commands.cc
const std::vector<Subcommand>& CalibSubcommands();    // app/calib_commands.cc
const std::vector<Subcommand>& SynthSubcommands();    // app/synth_commands.cc
const std::vector<Subcommand>& BenchSubcommands();    // app/bench_command.cc
const std::vector<Subcommand>& ExportSubcommands();   // app/export_command.cc
const std::vector<Subcommand>& AcquireSubcommands();  // app/acquire_commands.cc (thinslab_app)

}  // namespace thinslab
