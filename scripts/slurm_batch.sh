#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Refit every capture under ROOT on a Slurm cluster: one array task per shard, each running
# `thinslab batch ROOT --shard K/N` on its own node (docs/batch.md). Shards share nothing but
# the captures' folders (each capture belongs to one shard; each shard has its own state file),
# so tasks never write the same file. Resubmitting the same job skips the fits that are complete
# and current, and resumes what a killed or timed-out task left.
#
#   sbatch --array=0-7 scripts/slurm_batch.sh /data/captures [--dmf-options '--pitch-mm 2']
#
#SBATCH --job-name=thinslab-batch
#SBATCH --cpus-per-task=8
#SBATCH --mem=8G
#SBATCH --time=12:00:00
#SBATCH --output=thinslab-batch-%A_%a.out
set -euo pipefail
root=${1:?usage: sbatch --array=0-(N-1) slurm_batch.sh ROOT [batch options]}
shift
thinslab=${THINSLAB:-thinslab}
# The fits use every core they see (--threads 0); on a shared node give the task's share in
# the fit options, e.g. --dmf-options "--threads $SLURM_CPUS_PER_TASK".
exec "$thinslab" batch "$root" --shard "${SLURM_ARRAY_TASK_ID:-0}/${SLURM_ARRAY_TASK_COUNT:-1}" "$@"
