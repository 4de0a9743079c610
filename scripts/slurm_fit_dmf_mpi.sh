#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# One dot-scan capture's `fit dmf` shared out over the tasks of a Slurm job with MPI (docs/batch.md,
# "One capture over several machines"): every task reads the capture, each merges its share of
# the dot frames and fits its share of the points, rank 0 writes the output. The capture and the
# output folder must be on a file system every node sees; --max-memory is per task.
#
#   sbatch --nodes=4 scripts/slurm_fit_dmf_mpi.sh /data/capture /data/capture/fit/dmf [fit options]
#
#SBATCH --job-name=thinslab-fit-dmf
#SBATCH --ntasks-per-node=1
#SBATCH --cpus-per-task=8
#SBATCH --mem=8G
#SBATCH --time=4:00:00
#SBATCH --output=thinslab-fit-dmf-%j.out
set -euo pipefail
capture=${1:?usage: sbatch --nodes=N slurm_fit_dmf_mpi.sh CAPTURE OUT [fit dmf options]}
out=${2:?usage: sbatch --nodes=N slurm_fit_dmf_mpi.sh CAPTURE OUT [fit dmf options]}
shift 2
thinslab=${THINSLAB:-thinslab}
# Open MPI's mpirun takes the job's tasks and nodes from Slurm; each task uses its cores.
exec mpirun -n "${SLURM_NTASKS:-1}" "$thinslab" fit dmf "$capture" --out "$out" \
  --threads "${SLURM_CPUS_PER_TASK:-1}" "$@"
