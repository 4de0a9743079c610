// SPDX-License-Identifier: Apache-2.0
// The processes of one run (issue #29 item 2). `mpirun -n N thinslab fit dmf ...` starts N
// copies of the command on one machine or many; each reads the whole input, they share the work
// out (DistributedFor), every process ends with the same results, and rank 0 alone writes the
// output. Without an MPI launcher, or in a build without MPI (THINSLAB_WITH_MPI=OFF), the group
// is this one process and nothing is packed or sent.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "thinslab/core/byte_buffer.h"
#include "thinslab/core/status.h"

namespace thinslab {

class ProcessGroup {
 public:
  // Every process's bytes to every process, in rank order (MPI_Allgatherv under MPI).
  using Exchange = std::function<Status(const std::string& mine, std::vector<std::string>* all)>;

  ProcessGroup() = default;  // This process alone.
  ProcessGroup(int rank, int size, Exchange exchange) : rank_(rank), size_(size), exchange_(std::move(exchange)) {}

  // The group this program was started in (StartProcessGroup).
  static ProcessGroup& World();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  bool distributed() const { return size_ > 1; }

  // Every process's `mine` to every process (*all, in rank order). A process that failed passes
  // its error as `local` (and anything as `mine`): every process then returns that error, the
  // lowest failing rank's, prefixed "process K of N: ", and shared_error() turns true.
  // Collective: every process of the group calls it, in the same order.
  Status AllGather(const Status& local, const std::string& mine, std::vector<std::string>* all);
  // AllGather without data: an error of any process becomes every process's.
  Status Agree(const Status& local);
  // True once an error came out of AllGather: every process has it, so none needs to stop the
  // others (FinishProcessGroup) and only rank 0 prints it.
  bool shared_error() const { return shared_error_; }

 private:
  int rank_ = 0, size_ = 1;
  Exchange exchange_;
  bool shared_error_ = false;
};

// The first item of rank `rank`'s share of [begin, end) cut into `size` contiguous shares.
inline int ShareBegin(int begin, int end, int rank, int size) {
  return begin + static_cast<int>(static_cast<long long>(end - begin) * rank / size);
}

// One loop over items [0, n) shared out over a group (DistributedFor).
struct DistributedLoop {
  // Computes items [begin, end): this process's share of a chunk.
  std::function<Status(int begin, int end)> compute;
  // Item i's result, computed here, for the other processes; and read back there.
  std::function<void(int i, ByteWriter* out)> pack;
  std::function<bool(int i, ByteReader* in)> unpack;
  // Optional: after each chunk, on every process, with every item of [begin, end) known.
  std::function<Status(int begin, int end)> chunk_done;
};

// Items [0, n) in chunks of `chunk` items (the last may be shorter); each chunk is cut into
// group.size() contiguous shares (ShareBegin), each process computes its share, then every
// process unpacks the items the others computed, in item order, and runs chunk_done. A group
// of one only computes and runs chunk_done. An error in any process's compute, a message that
// does not unpack, or an error of chunk_done ends the loop on every process with that error.
// `what` names the loop in errors.
Status DistributedFor(ProcessGroup& group, int n, int chunk, const std::string& what, const DistributedLoop& loop);

// Called first in main. When an MPI launcher (mpirun, srun) started this process in a build
// with MPI: MPI_Init, and World() is the launcher's group. Launched as several processes by a
// build without MPI: an error (each would fit and write the same output on its own).
Status StartProcessGroup(int* argc, char*** argv);
// Called last in main with the command's exit code: MPI_Finalize; but when this process failed
// alone (an error not shared through AllGather), MPI_Abort, so that the others, waiting in a
// collective for it, stop too.
void FinishProcessGroup(int exit_code);

}  // namespace thinslab
