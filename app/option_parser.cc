// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/option_parser.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "thinslab/app/verbosity.h"

namespace thinslab {
namespace {

constexpr const char* kBooleanKind = "true/false";

bool IsBooleanWord(const std::string& s) {
  return s == "true" || s == "1" || s == "yes" || s == "false" || s == "0" || s == "no";
}

bool ConvertDouble(const std::string& s, double* out) {
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

bool ConvertInt(const std::string& s, int* out) {
  long long v;
  if (!ParseInt64(s, &v) || v < -2147483647LL || v > 2147483647LL) return false;
  *out = static_cast<int>(v);
  return true;
}

bool ConvertUint64(const std::string& s, uint64_t* out) {
  long long v;
  if (!ParseInt64(s, &v) || v < 0) return false;
  *out = static_cast<uint64_t>(v);
  return true;
}

bool ConvertString(const std::string& s, std::string* out) {
  *out = s;
  return true;
}

bool ConvertBool(const std::string& s, bool* out) {
  if (!IsBooleanWord(s)) return false;
  *out = s == "true" || s == "1" || s == "yes";
  return true;
}

// The shortest text that reads back as the same double, so options.ini repeats a run exactly.
std::string FormatDouble(const double& v) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

template <typename T>
std::string FormatInteger(const T& v) {
  return std::to_string(v);
}

std::string FormatString(const std::string& s) { return s; }
std::string FormatBool(const bool& b) { return b ? "true" : "false"; }

std::string Trim(const std::string& s) {
  const size_t begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  return s.substr(begin, s.find_last_not_of(" \t\r") - begin + 1);
}

}  // namespace

template <typename T>
void OptionParser::Add(const std::string& name, T* value, const std::string& help, const char* kind,
                       bool (*convert)(const std::string&, T*), std::string (*format)(const T&)) {
  options_.push_back({name, help, kind, [value, convert](const std::string& s) { return convert(s, value); },
                      [convert](const std::string& s) {
                        T scratch{};
                        return convert(s, &scratch);
                      },
                      [value, format] { return format(*value); }});
}

void OptionParser::AddDouble(const std::string& name, double* value, const std::string& help) {
  Add(name, value, help, "number", ConvertDouble, FormatDouble);
}

void OptionParser::AddInt(const std::string& name, int* value, const std::string& help) {
  Add(name, value, help, "integer", ConvertInt, FormatInteger<int>);
}

void OptionParser::AddUint64(const std::string& name, uint64_t* value, const std::string& help) {
  Add(name, value, help, "non-negative integer", ConvertUint64, FormatInteger<uint64_t>);
}

void OptionParser::AddString(const std::string& name, std::string* value, const std::string& help) {
  Add(name, value, help, "text", ConvertString, FormatString);
}

void OptionParser::AddBool(const std::string& name, bool* value, const std::string& help) {
  Add(name, value, help, kBooleanKind, ConvertBool, FormatBool);
}

void OptionParser::AddPositional(const std::string& name, std::string* value, const std::string& help,
                                 bool required) {
  positionals_.push_back({name, help, value, required});
}

void OptionParser::AddPositionalList(const std::string& name, std::vector<std::string>* values,
                                     const std::string& help) {
  positionals_.push_back({name, help, nullptr, false, values});
}

const OptionParser::Option* OptionParser::FindOption(const std::string& name) const {
  for (const Option& o : options_) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

bool OptionParser::IsSet(const std::string& name) const {
  return std::find(set_names_.begin(), set_names_.end(), name) != set_names_.end();
}

// options.ini as a CLI11 configuration: "name = value" lines (positionals by their name), '#'
// comments, the first line naming the command that wrote it. Each line is checked here, so an
// error names its line; CLI11 then applies the values to every option the command line left
// unset.
class OptionParser::IniConfig : public CLI::Config {
 public:
  explicit IniConfig(const OptionParser* parser) : parser_(parser) {}

  std::string to_config(const CLI::App*, bool, bool, std::string) const override { return parser_->ToIni(); }

  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    const std::string& command = parser_->command_;
    std::vector<CLI::ConfigItem> parsed;
    std::string line;
    for (int number = 1; std::getline(input, line); ++number) {
      const std::string at = "line " + std::to_string(number) + ": ";
      line = Trim(line);
      if (number == 1 && line.rfind("# thinslab ", 0) == 0) {
        const size_t colon = line.find(':');
        const std::string written_by = line.substr(2, colon == std::string::npos ? std::string::npos : colon - 2);
        if (written_by != "thinslab " + command) {
          throw CLI::ConfigError("written by `" + written_by + "`, not `thinslab " + command + "`");
        }
      }
      if (line.empty() || line[0] == '#') continue;
      const size_t eq = line.find('=');
      if (eq == std::string::npos) throw CLI::ConfigError(at + "expected 'name = value', got '" + line + "'");
      CLI::ConfigItem item;
      item.name = Trim(line.substr(0, eq));
      const std::string value = Trim(line.substr(eq + 1));
      const auto positional = std::find_if(parser_->positionals_.begin(), parser_->positionals_.end(),
                                           [&](const Positional& p) { return p.name == item.name; });
      if (positional != parser_->positionals_.end()) {
        if (value.empty()) continue;  // An optional positional left out.
        if (positional->list != nullptr) {
          std::istringstream parts(value);
          for (std::string part; std::getline(parts, part, ',');) item.inputs.push_back(part);
        } else {
          item.inputs.push_back(value);
        }
      } else if (const Option* option = parser_->FindOption(item.name)) {
        if (!option->check(value)) {
          throw CLI::ConfigError(at + item.name + " = '" + value + "' is not a valid " + option->kind);
        }
        item.inputs.push_back(value);
      } else if (parser_->ignore_unknown_) {
        continue;
      } else {
        throw CLI::ConfigError(at + "'" + item.name + "' is not an option of thinslab " + command);
      }
      parsed.push_back(std::move(item));
    }
    return parsed;
  }

 private:
  const OptionParser* parser_;
};

namespace {

// "usage: thinslab <command> CAPTURE [options]" in place of CLI11's "Usage: ..." line, and each
// option as "--name <kind>  (default value)".
class UsageFormatter : public CLI::Formatter {
 public:
  explicit UsageFormatter(std::string line) : line_(std::move(line)) {}
  std::string make_usage(const CLI::App*, std::string) const override { return line_ + "\n"; }
  std::string make_option_name(const CLI::Option* option, bool positional) const override {
    if (positional) return option->get_name(true, false);
    std::string names;
    for (const std::string& s : option->get_snames()) names += "-" + s + ",";
    return names + "--" + option->get_lnames().front();
  }
  std::string make_option_opts(const CLI::Option* option) const override {
    if (option->get_positional()) return option->get_required() ? "" : "  (optional)";
    const std::string kind = option->get_type_name();
    const std::string value = option->get_default_str();
    return (kind.empty() ? "" : " " + kind) + (value.empty() ? "" : "  (default " + value + ")");
  }

 private:
  std::string line_;
};

bool IsBooleanOption(const std::string& arg, const std::vector<std::string>& flags) {
  return arg.rfind("--", 0) == 0 && std::find(flags.begin(), flags.end(), arg.substr(2)) != flags.end();
}

}  // namespace

std::unique_ptr<CLI::App> OptionParser::MakeApp() const {
  auto app = std::make_unique<CLI::App>("", "thinslab " + command_);
  // As before CLI11: an option given twice takes its last value; options and positionals mix.
  app->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  std::string usage = usage_line_;
  if (usage.empty()) {
    usage = "usage: thinslab " + command_;
    for (const Positional& p : positionals_) {
      const std::string name = p.name + (p.list != nullptr ? "..." : "");
      usage += p.required ? " " + name : " [" + name + "]";
    }
    usage += " [options]";
  }
  app->formatter(std::make_shared<UsageFormatter>(usage));
  app->get_formatter()->column_width(34);
  if (!footer_.empty()) app->footer(footer_);
  raw_values_.assign(options_.size(), "");
  raw_positionals_.assign(positionals_.size(), "");
  raw_list_.clear();
  raw_verbosity_.assign(2, "");
  for (size_t k = 0; k < positionals_.size(); ++k) {
    const Positional& p = positionals_[k];
    CLI::Option* option = p.list != nullptr ? app->add_option(p.name, raw_list_, p.help)
                                            : app->add_option(p.name, raw_positionals_[k], p.help);
    if (p.required) option->required();
  }
  for (size_t k = 0; k < options_.size(); ++k) {
    const Option& o = options_[k];
    const std::string names = (o.short_name != 0 ? std::string("-") + o.short_name + "," : "") + "--" + o.name;
    CLI::Option* option = o.kind == kBooleanKind ? app->add_flag(names + "{true}", raw_values_[k], o.help)
                                                 : app->add_option(names, raw_values_[k], o.help);
    option->type_name(o.kind == kBooleanKind ? "[=true|false]" : "<" + o.kind + ">")->default_str(o.get());
  }
  app->set_config("--config", "", "repeat an earlier run: the options.ini it wrote; options given here override it")
      ->type_name("<options.ini>");
  app->config_formatter(std::make_shared<IniConfig>(this));
  if (ignore_unknown_) app->allow_extras();
  const char* verbosity_help[2] = {"nothing on stdout, no progress (errors and warnings still on stderr)",
                                   "progress even when stderr is not a terminal, and the libraries' log"};
  for (int k = 0; k < 2 && !ignore_unknown_; ++k) {
    const std::string name = k == 0 ? "quiet" : "verbose";
    if (FindOption(name) == nullptr) {
      app->add_flag("--" + name + "{true}", raw_verbosity_[k], verbosity_help[k])->type_name("[=true|false]");
    }
  }
  return app;
}

Status OptionParser::ErrorFromCli11(const CLI::App& app, const std::exception& error) const {
  const std::string where = "thinslab " + command_ + ": ";
  // An unknown option is the likeliest cause of any other complaint: named first.
  for (const std::string& extra : app.remaining()) {
    if (extra.size() > 1 && extra[0] == '-') {
      return Status::Error(where + "unknown option " + extra.substr(0, extra.find('=')) + " (see --help)");
    }
  }
  if (dynamic_cast<const CLI::ConfigError*>(&error) != nullptr ||
      dynamic_cast<const CLI::FileError*>(&error) != nullptr) {
    const CLI::Option* config = app.get_config_ptr();
    const std::string path = config != nullptr && config->count() > 0 ? config->results().back() : "";
    const std::string message = dynamic_cast<const CLI::FileError*>(&error) != nullptr ? "no such file" : error.what();
    return Status::Error(where + "--config " + path + (message.rfind("line ", 0) == 0 ? " " : ": ") + message);
  }
  if (dynamic_cast<const CLI::ExtrasError*>(&error) != nullptr && !app.remaining().empty()) {
    return Status::Error(where + "unexpected argument '" + app.remaining().front() + "'");
  }
  if (dynamic_cast<const CLI::RequiredError*>(&error) != nullptr) {
    for (const Positional& p : positionals_) {
      if (p.required && app.get_option(p.name)->count() == 0) {
        return Status::Error(where + "missing argument " + p.name + " (see --help)");
      }
    }
  }
  const std::string text = error.what();
  if (dynamic_cast<const CLI::ArgumentMismatch*>(&error) != nullptr && text.rfind("--", 0) == 0) {
    const std::string name = text.substr(2, text.find(':') - 2);
    if (const Option* option = FindOption(name)) {
      return Status::Error(where + "option --" + name + " needs a value (" + option->kind + ")");
    }
  }
  return Status::Error(where + text);
}

Status OptionParser::Parse(int argc, char** argv) {
  set_names_.clear();
  help_requested_ = false;
  // "--flag false": a flag takes the next argument only when it is a boolean word, so that
  // `--resume OUT` works; CLI11 takes a flag's value as "--flag=false".
  std::vector<std::string> flags = {"quiet", "verbose"};
  for (const Option& o : options_) {
    if (o.kind == kBooleanKind) flags.push_back(o.name);
  }
  std::vector<std::string> args;
  for (int i = 0; i < argc; ++i) {
    std::string arg = argv[i];
    if (IsBooleanOption(arg, flags) && i + 1 < argc && IsBooleanWord(argv[i + 1])) arg += std::string("=") + argv[++i];
    args.push_back(arg);
  }
  std::reverse(args.begin(), args.end());  // CLI11 takes them last first.
  std::unique_ptr<CLI::App> app = MakeApp();
  try {
    app->parse(args);
  } catch (const CLI::CallForHelp&) {
    help_requested_ = true;
    return Status::Ok();
  } catch (const CLI::ParseError& e) {
    return ErrorFromCli11(*app, e);
  }
  for (const CLI::Option* given : app->parse_order()) {
    if (given->get_lnames().empty()) continue;
    const std::string name = given->get_lnames().front();
    if (std::find(set_names_.begin(), set_names_.end(), name) == set_names_.end()) set_names_.push_back(name);
  }
  for (size_t k = 0; k < options_.size(); ++k) {
    const Option& o = options_[k];
    if (app->get_option("--" + o.name)->count() == 0) continue;
    if (!o.set(raw_values_[k])) {
      return Status::Error("thinslab " + command_ + ": option --" + o.name + " = '" + raw_values_[k] +
                           "' is not a valid " + o.kind);
    }
  }
  for (size_t k = 0; k < positionals_.size(); ++k) {
    const Positional& p = positionals_[k];
    if (app->get_option(p.name)->count() == 0) continue;
    if (p.list != nullptr) {
      *p.list = raw_list_;
    } else {
      *p.value = raw_positionals_[k];
    }
  }
  bool verbosity[2] = {false, false};
  for (int k = 0; k < 2; ++k) {
    const std::string& raw = raw_verbosity_[k];
    if (!raw.empty() && !ConvertBool(raw, &verbosity[k])) {
      return Status::Error("thinslab " + command_ + ": option --" + (k == 0 ? "quiet" : "verbose") + " = '" + raw +
                           "' is not a valid " + kBooleanKind);
    }
  }
  if (verbosity[0] || verbosity[1]) SetVerbosity(verbosity[0], verbosity[1]);
  return Status::Ok();
}

Status OptionParser::PeekValue(const std::string& command, int argc, char** argv, const std::string& name,
                               std::string* value) {
  OptionParser peek(command);
  peek.ignore_unknown_ = true;
  peek.AddString(name, value, "");  // Left as it is unless given.
  std::vector<char*> args;          // Without --help: the full parse answers it.
  for (int i = 0; i < argc; ++i) {
    if (std::string(argv[i]) != "--help" && std::string(argv[i]) != "-h") args.push_back(argv[i]);
  }
  return peek.Parse(static_cast<int>(args.size()), args.data());
}

int CommandFailed(const Status& status) {
  std::cerr << "error: " << status.message() << "\n";
  return 1;
}

bool OptionParser::ParseCommandLine(int argc, char** argv, int* exit_code) {
  const Status status = Parse(argc, argv);
  if (help_requested_) {
    std::cout << Usage();
    *exit_code = 0;
    return false;
  }
  if (!status.ok()) {
    *exit_code = CommandFailed(status);
    return false;
  }
  return true;
}

std::string OptionParser::Usage() const {
  // A fresh app shows the values as they are now: the defaults, before a parse.
  return MakeApp()->help();
}

std::string OptionParser::ToIni() const {
  std::ostringstream out;
  out << "# thinslab " << command_ << ": effective options\n";
  for (const auto& p : positionals_) {
    out << p.name << " = ";
    if (p.list != nullptr) {
      for (size_t k = 0; k < p.list->size(); ++k) out << (k > 0 ? "," : "") << (*p.list)[k];
    } else {
      out << *p.value;
    }
    out << "\n";
  }
  for (const auto& o : options_) {
    out << (o.diagnostic ? "# " : "") << o.name << " = " << o.get() << (o.diagnostic ? "  (diagnostic: not in the digest)" : "")
        << "\n";
  }
  return out.str();
}

void OptionParser::SetShortName(const std::string& name, char c) {
  for (auto& o : options_) {
    if (o.name == name) o.short_name = c;
  }
}

void OptionParser::MarkDiagnostic(const std::string& name) {
  for (auto& o : options_) {
    if (o.name == name) o.diagnostic = true;
  }
}

}  // namespace thinslab
