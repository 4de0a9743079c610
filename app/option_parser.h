// SPDX-License-Identifier: Apache-2.0
// Command-line options: each subcommand registers typed options bound to its stage's Options
// fields; CLI11 parses "--name value" / "--name=value", the positionals, --help and --config
// (through the options.ini reader below, a CLI11 Config). The effective values are written as
// an INI file (options.ini) next to the outputs. Errors name the option and what is wrong.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/file.h"  // Digest
#include "thinslab/core/status.h"

namespace CLI {
class App;
}

namespace thinslab {

// A command's refusal: prints "error: <message>" on stderr and returns the exit code 1.
int CommandFailed(const Status& status);

class OptionParser {
 public:
  explicit OptionParser(std::string command) : command_(std::move(command)) {}

  void AddDouble(const std::string& name, double* value, const std::string& help);
  void AddInt(const std::string& name, int* value, const std::string& help);
  void AddUint64(const std::string& name, uint64_t* value, const std::string& help);
  void AddString(const std::string& name, std::string* value, const std::string& help);
  void AddBool(const std::string& name, bool* value, const std::string& help);
  // Positional arguments in order; `required` ones must be given.
  void AddPositional(const std::string& name, std::string* value, const std::string& help, bool required = true);
  // The remaining bare arguments (after every AddPositional), e.g. IMAGES...; written to
  // options.ini as one line, comma-separated.
  void AddPositionalList(const std::string& name, std::vector<std::string>* values, const std::string& help);
  // Replaces the generated "usage: thinslab <command> ..." line.
  void SetUsageLine(std::string line) { usage_line_ = std::move(line); }
  // `-c` for `--name` (an option added before).
  void SetShortName(const std::string& name, char c);
  // Text after the options in --help.
  void SetHelpFooter(std::string text) { footer_ = std::move(text); }

  // Parses the command line. `--config FILE` (any command) first applies FILE, an options.ini an
  // earlier run of the same command wrote ("name = value" lines, positionals included), so the
  // run repeats it exactly; options on the command line override the file's.
  Status Parse(int argc, char** argv);
  // The value of option `name` of `command` from the command line or its --config file, when
  // given; every other argument is left for the full parse. For a command whose options depend
  // on one of them (`acquire --camera`: a simulated rig's options or a real one's).
  static Status PeekValue(const std::string& command, int argc, char** argv, const std::string& name,
                          std::string* value);
  // Parse() for a command's main: on --help prints the usage on stdout, on a bad command line
  // prints "error: ..." on stderr; either way returns false with the exit code (0 or 1).
  bool ParseCommandLine(int argc, char** argv, int* exit_code);
  bool help_requested() const { return help_requested_; }
  // True if the last Parse() set option `name` from the command line (not from --config).
  bool IsSet(const std::string& name) const;
  std::string Usage() const;
  // Option `name` changes what the command prints, not what it writes (`--pixel`): options.ini
  // records it as a comment line, which neither the options digest nor --config reads, so the
  // digest of a run with it equals the run's without it.
  void MarkDiagnostic(const std::string& name);
  // "name = value" lines, for options.ini; diagnostic options as "# name = value" lines.
  std::string ToIni() const;

 private:
  struct Option {
    std::string name, help, kind;
    std::function<bool(const std::string&)> set;    // Converts and stores; false: not a valid `kind`.
    std::function<bool(const std::string&)> check;  // Converts only.
    std::function<std::string()> get;
    bool diagnostic = false;
    char short_name = 0;
  };
  template <typename T>
  void Add(const std::string& name, T* value, const std::string& help, const char* kind,
           bool (*convert)(const std::string&, T*), std::string (*format)(const T&));
  struct Positional {
    std::string name, help;
    std::string* value;
    bool required;
    std::vector<std::string>* list = nullptr;  // AddPositionalList.
  };
  class IniConfig;
  // The CLI11 app of this command; each option's text goes to raw_values_[k] (options) and
  // raw_positionals_[k], converted by Option::set after the parse.
  std::unique_ptr<CLI::App> MakeApp() const;
  Status ErrorFromCli11(const CLI::App& app, const std::exception& error) const;
  const Option* FindOption(const std::string& name) const;

  std::string command_;
  std::vector<Option> options_;
  std::vector<Positional> positionals_;
  std::string usage_line_, footer_;
  mutable std::vector<std::string> raw_values_, raw_positionals_, raw_list_, raw_verbosity_;
  bool quiet_ = false, verbose_ = false;  // Every command's own (app/verbosity.h).
  bool help_requested_ = false;
  bool ignore_unknown_ = false;  // PeekValue.
  std::vector<std::string> set_names_;
};

}  // namespace thinslab
