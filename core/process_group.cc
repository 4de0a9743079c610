// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/process_group.h"

#include <algorithm>
#include <cstdlib>

#ifdef THINSLAB_HAVE_MPI
#include "thinslab/core/mpi_transport.h"
#endif

namespace thinslab {
namespace {

bool g_mpi_started = false;

// The number of processes an MPI launcher started (Open MPI's mpirun, MPICH's hydra, Slurm's srun
// with PMI), 0 when none did.
int LaunchedProcesses() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"}) {
    const char* value = std::getenv(name);
    if (value != nullptr && std::atoi(value) > 0) return std::atoi(value);
  }
  return std::getenv("PMIX_RANK") != nullptr ? 1 : 0;
}

}  // namespace

ProcessGroup& ProcessGroup::World() {
  static ProcessGroup world;
  return world;
}

Status ProcessGroup::AllGather(const Status& local, const std::string& mine, std::vector<std::string>* all) {
  if (!distributed()) {
    if (!local.ok()) return local;
    all->assign(1, mine);
    return Status::Ok();
  }
  // Each message starts with 'E' (an error, its text follows) or 'O' (the data follows).
  std::string message = local.ok() ? "O" + mine : "E" + local.message();
  std::vector<std::string> received;
  const Status sent = exchange_(message, &received);
  std::string().swap(message);
  if (!sent.ok()) {
    shared_error_ = true;  // The transport failed on every process alike (MPI aborts otherwise).
    return sent;
  }
  for (int r = 0; r < size_; ++r) {
    if (received[r].empty() || received[r][0] != 'O') {
      shared_error_ = true;
      const std::string text = received[r].empty() ? "an empty message" : received[r].substr(1);
      return Status::Error("process " + std::to_string(r) + " of " + std::to_string(size_) + ": " + text);
    }
  }
  all->resize(size_);
  for (int r = 0; r < size_; ++r) (*all)[r] = received[r].substr(1);
  return Status::Ok();
}

Status ProcessGroup::Agree(const Status& local) {
  std::vector<std::string> unused;
  return AllGather(local, "", &unused);
}

Status DistributedFor(ProcessGroup& group, int n, int chunk, const std::string& what, const DistributedLoop& loop) {
  chunk = std::max(1, chunk);
  for (int first = 0; first < n; first += chunk) {
    const int last = std::min(n, first + chunk);
    if (!group.distributed()) {
      THINSLAB_RETURN_IF_ERROR(loop.compute(first, last));
      if (loop.chunk_done) THINSLAB_RETURN_IF_ERROR(loop.chunk_done(first, last));
      continue;
    }
    const int mine_begin = ShareBegin(first, last, group.rank(), group.size());
    const int mine_end = ShareBegin(first, last, group.rank() + 1, group.size());
    Status computed = loop.compute(mine_begin, mine_end);
    ByteWriter out;
    if (computed.ok()) {
      for (int i = mine_begin; i < mine_end; ++i) loop.pack(i, &out);
    }
    std::vector<std::string> shares;
    THINSLAB_RETURN_IF_ERROR(group.AllGather(computed, out.Release(), &shares));
    for (int r = 0; r < group.size(); ++r) {
      if (r == group.rank()) continue;
      ByteReader in(shares[r]);
      const int begin = ShareBegin(first, last, r, group.size()), end = ShareBegin(first, last, r + 1, group.size());
      bool ok = true;
      for (int i = begin; i < end && ok; ++i) ok = loop.unpack(i, &in);
      if (!ok || !in.at_end()) {
        // Every process reads the same messages, so every process fails here alike.
        return Status::Error(what + ": the results of items " + std::to_string(begin) + ".." + std::to_string(end - 1) +
                             " from process " + std::to_string(r) + " do not unpack (processes of different builds?)");
      }
      std::string().swap(shares[r]);
    }
    if (loop.chunk_done) {
      THINSLAB_RETURN_IF_ERROR(group.Agree(loop.chunk_done(first, last)));
    }
  }
  return Status::Ok();
}

Status StartProcessGroup(int* argc, char*** argv) {
  const int launched = LaunchedProcesses();
  if (launched == 0) return Status::Ok();
#ifdef THINSLAB_HAVE_MPI
  int rank = 0, size = 1;
  THINSLAB_RETURN_IF_ERROR(mpi_transport::Start(argc, argv, &rank, &size));
  g_mpi_started = true;
  ProcessGroup::World() = ProcessGroup(rank, size, mpi_transport::AllGather);
  return Status::Ok();
#else
  (void)argc;
  (void)argv;
  if (launched > 1) {
    return Status::Error("started by an MPI launcher as " + std::to_string(launched) +
                         " processes, but this thinslab was built without MPI (THINSLAB_WITH_MPI=OFF): each would "
                         "run the whole command alone; install libopenmpi-dev and rebuild, or run one process");
  }
  return Status::Ok();
#endif
}

void FinishProcessGroup(int exit_code) {
#ifdef THINSLAB_HAVE_MPI
  if (!g_mpi_started) return;
  const ProcessGroup& world = ProcessGroup::World();
  mpi_transport::Finish(exit_code != 0 && world.distributed() && !world.shared_error(), exit_code);
#else
  (void)exit_code;
  (void)g_mpi_started;
#endif
}

}  // namespace thinslab
