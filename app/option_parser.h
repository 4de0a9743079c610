// SPDX-License-Identifier: Apache-2.0
// Command-line options: each subcommand registers typed options bound to its stage's Options
// fields, parses "--name value" / "--name=value", and can write the effective values as an
// INI file (options.ini) next to its outputs. Errors name the option and what is wrong.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "thinslab/core/file.h"  // Digest
#include "thinslab/core/status.h"

namespace thinslab {

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

  // Parses the command line. `--config FILE` (any command) first applies FILE, an options.ini an
  // earlier run of the same command wrote ("name = value" lines, positionals included), so the
  // run repeats it exactly; options on the command line override the file's.
  Status Parse(int argc, char** argv);
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
    std::function<bool(const std::string&)> set;
    std::function<std::string()> get;
    bool diagnostic = false;
  };
  struct Positional {
    std::string name, help;
    std::string* value;
    bool required;
  };
  Status ApplyConfig(const std::string& path, std::vector<bool>* positional_given);

  std::string command_;
  std::vector<Option> options_;
  std::vector<Positional> positionals_;
  bool help_requested_ = false;
  std::vector<std::string> set_names_;
};

}  // namespace thinslab
