// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/option_parser.h"

#include <algorithm>
#include <cerrno>
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

std::string FormatDouble(double v) {
  std::ostringstream out;
  out.precision(10);
  out << v;
  return out.str();
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

Status OptionParser::Parse(int argc, char** argv) {
  set_names_.clear();
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
    *positionals_[next_positional++].value = arg;
  }
  for (size_t k = next_positional; k < positionals_.size(); ++k) {
    if (positionals_[k].required) {
      return Status::Error("thinslab " + command_ + ": missing argument " + positionals_[k].name + " (see --help)");
    }
  }
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
  return out.str();
}

std::string OptionParser::ToIni() const {
  std::ostringstream out;
  out << "# thinslab " << command_ << ": effective options\n";
  for (const auto& p : positionals_) out << p.name << " = " << *p.value << "\n";
  for (const auto& o : options_) out << o.name << " = " << o.get() << "\n";
  return out.str();
}

}  // namespace thinslab
