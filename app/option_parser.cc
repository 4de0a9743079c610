// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/option_parser.h"

#include "thinslab/app/verbosity.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace thinslab {
namespace {

bool IsBooleanWord(const std::string& s) {
  return s == "true" || s == "1" || s == "yes" || s == "false" || s == "0" || s == "no";
}

bool ParseDouble(const std::string& s, double* out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (errno != 0 || *end != '\0' || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

bool ParseInt64(const std::string& s, long long* out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (errno != 0 || *end != '\0') return false;
  *out = v;
  return true;
}

// The shortest text that reads back as the same double, so options.ini repeats a run exactly.
std::string FormatDouble(double v) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

std::string Trim(const std::string& s) {
  const size_t begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  return s.substr(begin, s.find_last_not_of(" \t\r") - begin + 1);
}

}  // namespace

void OptionParser::AddDouble(const std::string& name, double* value, const std::string& help) {
  options_.push_back({name, help, "number", [value](const std::string& s) { return ParseDouble(s, value); },
                      [value] { return FormatDouble(*value); }});
}

void OptionParser::AddInt(const std::string& name, int* value, const std::string& help) {
  options_.push_back({name, help, "integer",
                      [value](const std::string& s) {
                        long long v;
                        if (!ParseInt64(s, &v) || v < -2147483647LL || v > 2147483647LL) return false;
                        *value = static_cast<int>(v);
                        return true;
                      },
                      [value] { return std::to_string(*value); }});
}

void OptionParser::AddUint64(const std::string& name, uint64_t* value, const std::string& help) {
  options_.push_back({name, help, "non-negative integer",
                      [value](const std::string& s) {
                        long long v;
                        if (!ParseInt64(s, &v) || v < 0) return false;
                        *value = static_cast<uint64_t>(v);
                        return true;
                      },
                      [value] { return std::to_string(*value); }});
}

void OptionParser::AddString(const std::string& name, std::string* value, const std::string& help) {
  options_.push_back({name, help, "text",
                      [value](const std::string& s) {
                        *value = s;
                        return true;
                      },
                      [value] { return *value; }});
}

void OptionParser::AddBool(const std::string& name, bool* value, const std::string& help) {
  options_.push_back({name, help, "true/false",
                      [value](const std::string& s) {
                        if (s == "true" || s == "1" || s == "yes") {
                          *value = true;
                        } else if (s == "false" || s == "0" || s == "no") {
                          *value = false;
                        } else {
                          return false;
                        }
                        return true;
                      },
                      [value] { return std::string(*value ? "true" : "false"); }});
}

void OptionParser::AddPositional(const std::string& name, std::string* value, const std::string& help,
                                 bool required) {
  positionals_.push_back({name, help, value, required});
}

bool OptionParser::IsSet(const std::string& name) const {
  return std::find(set_names_.begin(), set_names_.end(), name) != set_names_.end();
}

Status OptionParser::ApplyConfig(const std::string& path, std::vector<bool>* positional_given) {
  const std::string where = "thinslab " + command_ + ": --config " + path;
  std::string text;
  const Status read = ReadFileToString(path, &text);
  if (!read.ok()) return Status::Error(where + ": " + read.message());
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::string at = where + " line " + std::to_string(number);
    line = Trim(line);
    if (number == 1 && line.rfind("# thinslab ", 0) == 0) {
      const std::string written_by = line.substr(2, line.find(':') == std::string::npos ? std::string::npos : line.find(':') - 2);
      if (written_by != "thinslab " + command_) {
        return Status::Error(where + ": written by `" + written_by + "`, not `thinslab " + command_ + "`");
      }
    }
    if (line.empty() || line[0] == '#') continue;
    const size_t eq = line.find('=');
    if (eq == std::string::npos) return Status::Error(at + ": expected 'name = value', got '" + line + "'");
    const std::string name = Trim(line.substr(0, eq)), value = Trim(line.substr(eq + 1));
    bool applied = false;
    for (size_t k = 0; k < positionals_.size(); ++k) {
      if (positionals_[k].name != name) continue;
      *positionals_[k].value = value;
      (*positional_given)[k] = !value.empty();
      applied = true;
    }
    for (const Option& o : options_) {
      if (o.name != name) continue;
      if (!o.set(value)) return Status::Error(at + ": " + name + " = '" + value + "' is not a valid " + o.kind);
      applied = true;
    }
    if (!applied) return Status::Error(at + ": '" + name + "' is not an option of thinslab " + command_);
  }
  return Status::Ok();
}

Status OptionParser::Parse(int argc, char** argv) {
  set_names_.clear();
  // --config first, whatever its place: the command line's options override the file's.
  std::vector<bool> positional_given(positionals_.size(), false);
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--config" || arg.rfind("--config=", 0) == 0) {
      std::string path = arg.size() > 8 ? arg.substr(9) : "";
      if (arg == "--config") {
        if (i + 1 >= argc) return Status::Error("thinslab " + command_ + ": option --config needs a value (an options.ini)");
        path = argv[++i];
      }
      THINSLAB_RETURN_IF_ERROR(ApplyConfig(path, &positional_given));
      continue;
    }
    args.push_back(argv[i]);
  }
  argc = static_cast<int>(args.size());
  argv = args.data();
  bool quiet = false, verbose = false;
  size_t next_positional = 0;
  for (int i = 0; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      help_requested_ = true;
      return Status::Ok();
    }
    if (arg.rfind("--", 0) == 0) {
      std::string name = arg.substr(2), value;
      const size_t eq = name.find('=');
      bool has_value = false;
      if (eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
        has_value = true;
      }
      const Option* option = nullptr;
      for (const auto& o : options_) {
        if (o.name == name) option = &o;
      }
      if (option == nullptr && (name == "quiet" || name == "verbose")) {
        // Every command's --quiet and --verbose (app/verbosity.h), unless it has its own.
        if (!has_value && i + 1 < argc && IsBooleanWord(argv[i + 1])) value = argv[++i], has_value = true;
        if (has_value && !IsBooleanWord(value)) {
          return Status::Error("thinslab " + command_ + ": option --" + name + " = '" + value + "' is not a valid true/false");
        }
        const bool on = !has_value || value == "true" || value == "1" || value == "yes";
        (name == "quiet" ? quiet : verbose) = on;
        continue;
      }
      if (option == nullptr) {
        return Status::Error("thinslab " + command_ + ": unknown option --" + name + " (see --help)");
      }
      if (!has_value) {
        // A flag takes the next argument only when it is a boolean word, so `--resume OUT` works.
        if (option->kind == "true/false" && (i + 1 >= argc || !IsBooleanWord(argv[i + 1]))) {
          value = "true";
        } else if (i + 1 >= argc) {
          return Status::Error("thinslab " + command_ + ": option --" + name + " needs a value (" + option->kind + ")");
        } else {
          value = argv[++i];
        }
      }
      if (!option->set(value)) {
        return Status::Error("thinslab " + command_ + ": option --" + name + " = '" + value + "' is not a valid " +
                             option->kind);
      }
      set_names_.push_back(name);
      continue;
    }
    if (next_positional >= positionals_.size()) {
      return Status::Error("thinslab " + command_ + ": unexpected argument '" + arg + "'");
    }
    positional_given[next_positional] = true;
    *positionals_[next_positional++].value = arg;
  }
  for (size_t k = 0; k < positionals_.size(); ++k) {
    if (positionals_[k].required && !positional_given[k]) {
      return Status::Error("thinslab " + command_ + ": missing argument " + positionals_[k].name + " (see --help)");
    }
  }
  if (quiet || verbose) SetVerbosity(quiet, verbose);
  return Status::Ok();
}

std::string OptionParser::Usage() const {
  std::ostringstream out;
  out << "usage: thinslab " << command_;
  for (const auto& p : positionals_) out << (p.required ? " " : " [") << p.name << (p.required ? "" : "]");
  out << " [options]\n";
  for (const auto& p : positionals_) out << "  " << p.name << "\n      " << p.help << "\n";
  for (const auto& o : options_) {
    out << "  --" << o.name << " <" << o.kind << ">  (default " << o.get() << ")\n      " << o.help << "\n";
  }
  out << "  --config <options.ini>\n      repeat an earlier run: the options.ini it wrote; options given here override it\n";
  for (const char* name : {"quiet", "verbose"}) {
    const bool own = std::any_of(options_.begin(), options_.end(), [&](const Option& o) { return o.name == name; });
    if (own) continue;
    out << "  --" << name
        << (name[0] == 'q' ? "\n      nothing on stdout, no progress (errors and warnings still on stderr)\n"
                           : "\n      progress even when stderr is not a terminal, and the libraries' log\n");
  }
  return out.str();
}

std::string OptionParser::ToIni() const {
  std::ostringstream out;
  out << "# thinslab " << command_ << ": effective options\n";
  for (const auto& p : positionals_) out << p.name << " = " << *p.value << "\n";
  for (const auto& o : options_) {
    out << (o.diagnostic ? "# " : "") << o.name << " = " << o.get() << (o.diagnostic ? "  (diagnostic: not in the digest)" : "")
        << "\n";
  }
  return out.str();
}

void OptionParser::MarkDiagnostic(const std::string& name) {
  for (auto& o : options_) {
    if (o.name == name) o.diagnostic = true;
  }
}

}  // namespace thinslab
