// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/mpi_transport.h"

#include <mpi.h>

#include <climits>

namespace thinslab::mpi_transport {
namespace {

std::string MpiError(const char* call, int code) {
  char text[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, text, &length);
  return std::string(call) + " failed: " + std::string(text, length);
}

}  // namespace

Status Start(int* argc, char*** argv, int* rank, int* size) {
  int code = MPI_Init(argc, argv);
  if (code != MPI_SUCCESS) return Status::Error(MpiError("MPI_Init", code));
  // Errors come back as codes (and become Status) instead of aborting every process.
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, rank);
  MPI_Comm_size(MPI_COMM_WORLD, size);
  return Status::Ok();
}

Status AllGather(const std::string& mine, std::vector<std::string>* all) {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  long long my_bytes = static_cast<long long>(mine.size());
  std::vector<long long> bytes(size);
  int code = MPI_Allgather(&my_bytes, 1, MPI_LONG_LONG, bytes.data(), 1, MPI_LONG_LONG, MPI_COMM_WORLD);
  if (code != MPI_SUCCESS) return Status::Error(MpiError("MPI_Allgather", code));
  std::vector<int> counts(size), offsets(size);
  long long total = 0;
  for (int r = 0; r < size; ++r) {
    offsets[r] = static_cast<int>(total);
    counts[r] = static_cast<int>(bytes[r]);
    total += bytes[r];
  }
  if (total > INT_MAX) {
    // Every process sees the same sizes and returns here alike.
    return Status::Error("one exchange of " + std::to_string(total) + " bytes exceeds MPI's 2 GiB count limit");
  }
  std::string received(static_cast<size_t>(total), '\0');
  code = MPI_Allgatherv(mine.data(), static_cast<int>(my_bytes), MPI_BYTE, received.data(), counts.data(),
                        offsets.data(), MPI_BYTE, MPI_COMM_WORLD);
  if (code != MPI_SUCCESS) return Status::Error(MpiError("MPI_Allgatherv", code));
  all->resize(size);
  for (int r = 0; r < size; ++r) (*all)[r].assign(received, offsets[r], counts[r]);
  return Status::Ok();
}

void Finish(bool abort, int exit_code) {
  if (abort) MPI_Abort(MPI_COMM_WORLD, exit_code);
  MPI_Finalize();
}

}  // namespace thinslab::mpi_transport
