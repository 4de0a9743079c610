// SPDX-License-Identifier: Apache-2.0
// `thinslab batch ROOT` (issue #29 item 2): refits every capture folder directly under ROOT with
// the fit its kind takes (shadow_map: fit tau, laser_lobe: fit phase, dot_scan: fit dmf), each
// as a child process of the thinslab binary, so a capture that fails (or crashes) leaves the rest
// running. A capture is skipped when its fit is complete and current: the batch state file
// records, per capture, the fit's options as the batch passed them and the digest of the
// options.ini the fit wrote; both must match (a fit redone by hand with other options is not
// current). The state is written atomically after every fit, so a killed batch resumes where it
// stopped (fits are atomic: a killed fit leaves only its staging folder, which the next run
// removes). `--shard K/N` takes every N-th capture from the K-th (0-based) of the sorted list,
// so N machines (a Slurm array, docs/batch.md) split a folder without talking to each other.
#pragma once

#include <map>
#include <ostream>
#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

struct BatchRun {
  std::string root;
  // Options per fit ("tau", "phase", "dmf"), split at white space and passed as they are.
  std::map<std::string, std::string> fit_options;
  int jobs = 1;  // Fits at once.
  int shard_index = 0, shard_count = 1;
  bool force = false;      // Refit current captures too.
  std::string state_path;  // "" = ROOT/thinslab_batch.json (thinslab_batch_<K>of<N>.json for a shard).
  std::string table_path;  // "" = the state's path with .csv for .json.
  std::string executable;  // The thinslab binary the fits run in.
};

// Parses "K/N" (0 <= K < N).
Status ParseShard(const std::string& text, int* index, int* count);

// Runs the batch; `*failures` counts captures whose fit failed. The table goes to `log` and to
// the table file.
Status RunBatchRefit(const BatchRun& run, std::ostream& log, int* failures);

}  // namespace thinslab
