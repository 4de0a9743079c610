// SPDX-License-Identifier: Apache-2.0
// The MPI calls behind ProcessGroup::World() (core/process_group.h), in the one file that
// includes mpi.h (core/mpi_transport.cc, built with THINSLAB_WITH_MPI). Internal to core.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab::mpi_transport {

// MPI_Init; *rank and *size of MPI_COMM_WORLD.
Status Start(int* argc, char*** argv, int* rank, int* size);
// MPI_Allgather of the sizes, then MPI_Allgatherv of the bytes over MPI_COMM_WORLD.
Status AllGather(const std::string& mine, std::vector<std::string>* all);
// MPI_Finalize, or MPI_Abort(exit_code) when `abort`.
void Finish(bool abort, int exit_code);

}  // namespace thinslab::mpi_transport
