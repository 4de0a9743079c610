// SPDX-License-Identifier: Apache-2.0
// Issue #26 item 3: `thinslab help` lists every command and subcommand, each listed one runs
// (its --help names it and offers --config, --quiet and --verbose), the bash completion
// completes commands, subcommands and options, and --quiet mutes stdout.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

// The "  <command> <subcommand> ..." lines of `thinslab help` (and the commands without one).
std::vector<std::string> ListedCommands(const std::string& help) {
  std::vector<std::string> listed;
  std::istringstream lines(help);
  std::string line, command;
  while (std::getline(lines, line)) {
    if (line.rfind("    ", 0) == 0) {  // "    fit tau CAPTURE   ..."
      std::istringstream words(line);
      std::string first, second;
      words >> first >> second;
      listed.push_back(first + " " + second);
    } else if (line.rfind("  ", 0) == 0 && line[2] != ' ') {
      std::istringstream words(line);
      words >> command;
      listed.push_back(command);
    }
  }
  return listed;
}

TEST(CliHelp, EveryListedCommandRunsAndTakesTheCommonOptions) {
  const RunResult help = RunThinslabOk("help");
  const std::vector<std::string> listed = ListedCommands(help.output);
  for (const char* named_in_the_issue : {"sim dot-scan", "calib pose", "calib gamma", "fit dmf", "acquire dot-scan"}) {
    EXPECT_NE(std::find(listed.begin(), listed.end(), named_in_the_issue), listed.end()) << named_in_the_issue;
  }
  int with_options = 0;
  for (const std::string& command : listed) {
    const bool group = std::any_of(listed.begin(), listed.end(),
                                   [&](const std::string& other) { return other.rfind(command + " ", 0) == 0; });
    if (command == "help" || command == "version" || command == "completion" || group) {
      continue;  // No options of their own, or a group whose subcommands are listed.
    }
    const RunResult r = RunThinslab(command + " --help");
    EXPECT_EQ(r.exit_code, 0) << command << "\n" << r.output;
    EXPECT_NE(r.output.find("usage: thinslab " + command), std::string::npos) << r.output;
    for (const char* option : {"--config", "--quiet", "--verbose"}) {
      EXPECT_NE(r.output.find(option), std::string::npos) << command << " --help lacks " << option;
    }
    ++with_options;
  }
  EXPECT_GE(with_options, 25);
  // A group without its subcommand lists them; an unknown one is an error naming it.
  const RunResult group = RunThinslab("calib");
  EXPECT_NE(group.output.find("thinslab calib gamma SESSION"), std::string::npos) << group.output;
  const RunResult unknown = RunThinslab("fit shape");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.output.find("error: thinslab fit: unknown subcommand 'shape'"), std::string::npos);
}

// COMPREPLY of the installed completion for a command line (the last word is being completed).
std::string Complete(const std::string& script, const std::string& words) {
  const std::string command = "bash -c 'source " + script + "; COMP_WORDS=(" + ThinslabBinary() + " " + words +
                              "); COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _thinslab; echo \"${COMPREPLY[*]}\"' 2>&1";
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buffer[4096];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) out += buffer;
  pclose(pipe);
  return out;
}

TEST(CliHelp, BashCompletionCompletesCommandsSubcommandsAndOptions) {
  TempDir dir;
  const std::string script = dir / "thinslab.bash";
  RunThinslabOk("completion bash " + script);
  EXPECT_EQ(Complete(script, "ca"), "calib\n");
  EXPECT_EQ(Complete(script, "sim d"), "dot-scan\n");
  EXPECT_EQ(Complete(script, "calib g"), "gamma\n");
  EXPECT_EQ(Complete(script, "fit tau --alb"), "--albedo\n");
  EXPECT_EQ(Complete(script, "predict --conf"), "--config\n");
  EXPECT_EQ(Complete(script, "info --verb"), "--verbose\n");
  EXPECT_NE(RunThinslab("completion zsh").exit_code, 0);
}

TEST(CliHelp, QuietMutesStdoutAndVerboseIsAccepted) {
  TempDir dir;
  const std::string capture = dir / "capture";
  const RunResult sim =
      RunThinslabOk("sim shadow-maps " + capture + " --camera-width-px 80 --camera-height-px 60 --photons 2000 --quiet");
  EXPECT_EQ(sim.output, "");
  EXPECT_NE(RunThinslabOk("info " + capture).output, "");
  EXPECT_EQ(RunThinslabOk("info " + capture + " --quiet").output, "");
  EXPECT_NE(RunThinslabOk("info " + capture + " --verbose").output.find("Session"), std::string::npos);
  // Errors still reach stderr under --quiet.
  const RunResult error = RunThinslab("info " + (dir / "none") + " --quiet");
  EXPECT_EQ(error.exit_code, 1);
  EXPECT_NE(error.output.find("error:"), std::string::npos);
}

}  // namespace
}  // namespace thinslab
