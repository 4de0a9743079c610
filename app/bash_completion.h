// SPDX-License-Identifier: Apache-2.0
// The bash completion of `thinslab` (`thinslab completion bash [FILE]`, installed into
// share/bash-completion/completions): commands and subcommands from the command tree, options
// from the command's own --help, files and folders otherwise.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace thinslab {

// `tree`: each command with its subcommands (none for a command without).
std::string BashCompletionScript(const std::vector<std::pair<std::string, std::vector<std::string>>>& tree);

}  // namespace thinslab
