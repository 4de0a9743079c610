// SPDX-License-Identifier: Apache-2.0
// `thinslab batch ROOT` (app/batch_refit.h runs it; this file parses its options): every capture
// under ROOT refitted, current fits skipped, resumable, one table at the end (issue #29 item 2).
#include <iostream>

#include "thinslab/app/batch_refit.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/process.h"

namespace thinslab {

int RunBatch(int argc, char** argv) {
  BatchRun run;
  std::string shard = "0/1";
  OptionParser parser("batch");
  parser.AddPositional("ROOT", &run.root, "folder whose subfolders are captures (folders with session.json)");
  parser.AddString("tau-options", &run.fit_options["tau"], "options of every `fit tau` (shadow maps), e.g. '--g 0.7'");
  parser.AddString("phase-options", &run.fit_options["phase"], "options of every `fit phase` (laser lobes)");
  parser.AddString("dmf-options", &run.fit_options["dmf"], "options of every `fit dmf` (dot scans)");
  parser.AddInt("jobs", &run.jobs, "fits at once (each child process also uses its own threads)");
  parser.AddString("shard", &shard,
                   "K/N: every N-th capture of the sorted list from the K-th (0-based), for N machines");
  parser.AddBool("force", &run.force, "refit captures whose fit is current too");
  parser.AddString("state", &run.state_path,
                   "state file (default ROOT/thinslab_batch.json, ROOT/thinslab_batch_KofN.json for a shard)");
  parser.AddString("table", &run.table_path, "summary table, CSV (default: the state file's name with .csv)");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParseShard(shard, &run.shard_index, &run.shard_count);
  if (status.ok()) status = SelfExecutable(&run.executable);
  int failures = 0;
  if (status.ok()) status = RunBatchRefit(run, std::cout, &failures);
  if (!status.ok()) return CommandFailed(status);
  if (failures > 0) {
    std::cerr << "error: " << failures << " capture" << (failures == 1 ? "" : "s") << " failed (see the table)\n";
    return 1;
  }
  return 0;
}

}  // namespace thinslab
