// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/subcommands.h"

#include <algorithm>
#include <iostream>

namespace thinslab {

std::string SubcommandLines(const std::string& command, const std::vector<Subcommand>& table) {
  std::vector<std::string> heads;
  size_t width = 0;
  for (const Subcommand& s : table) {
    heads.push_back("  " + command + " " + s.name + (s.args[0] != '\0' ? std::string(" ") + s.args : ""));
    width = std::max(width, heads.back().size() + 2);
  }
  std::string lines;
  for (size_t k = 0; k < table.size(); ++k) lines += heads[k] + std::string(width - heads[k].size(), ' ') + table[k].help + "\n";
  return lines;
}

int DispatchSubcommand(const std::string& command, const std::vector<Subcommand>& table, int argc, char** argv,
                       const std::string& what, const std::string& extra_usage) {
  const std::string name = argc > 0 ? argv[0] : "";
  for (const Subcommand& s : table) {
    if (name == s.name) return s.run(argc - 1, argv + 1);
  }
  std::cerr << "usage: thinslab " << command << " <" << what << "> [args] [options]   (each with --help)\n"
            << SubcommandLines("thinslab " + command, table) << extra_usage;
  if (name.empty() || name == "--help" || name == "-h" || name == "help") return 0;
  std::cerr << "error: thinslab " << command << ": unknown " << what << " '" << name << "'\n";
  return 2;
}

}  // namespace thinslab
