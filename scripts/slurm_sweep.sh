#!/usr/bin/env bash
# Runs a backlash_sweep on a Slurm cluster: an array job of N parts (backlash_sweep --shard K/N, one task per part,
# resumable if requeued) plus a merge job that starts when every part succeeded and writes exactly the CSV a single
# run would (backlash_sweep --merge). Prints the two job ids; the merged CSV appears at OUTPUT.
#
# usage: bash scripts/slurm_sweep.sh -n PARTS -o OUTPUT [-d WORKDIR] [-- SBATCH_OPTION...] -- SWEEP_ARGUMENT...
#   -n PARTS     number of parts (array tasks), e.g. 100
#   -o OUTPUT    merged CSV (absolute or relative to the current directory)
#   -d WORKDIR   where parts and Slurm logs go (default: OUTPUT.parts/); must be on a filesystem all nodes share
#   sbatch options (partition, time limit, account, ...) go between the first and the second "--", e.g.
#   bash scripts/slurm_sweep.sh -n 50 -o fine.csv -- --partition=short --time=00:30:00 -- --preset thesis
# Environment: BACKLASH_SWEEP = the backlash_sweep executable (default: this checkout's build, else PATH).
exec bash "$(dirname "$0")/slurm_shards.sh" backlash_sweep "$@"
