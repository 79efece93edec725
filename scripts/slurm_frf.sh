#!/usr/bin/env bash
# Runs a stepped-sine backlash_frf on a Slurm cluster: an array job of N parts (backlash_frf --shard K/N: contiguous
# points, amplitude-major) plus a merge job that starts when every part succeeded and writes exactly the CSV a single
# run would (backlash_frf --merge). Prints the two job ids; the merged CSV appears at OUTPUT.
#
# usage: bash scripts/slurm_frf.sh -n PARTS -o OUTPUT [-d WORKDIR] [-- SBATCH_OPTION...] -- FRF_ARGUMENT...
#   -n PARTS     number of parts (array tasks)
#   -o OUTPUT    merged CSV (absolute or relative to the current directory)
#   -d WORKDIR   where parts and Slurm logs go (default: OUTPUT.parts/); must be on a filesystem all nodes share
#   e.g. bash scripts/slurm_frf.sh -n 20 -o bode.csv -- --time=01:00:00 -- --config joint.yaml --amplitude 0.01,0.1 \
#        --frequency-range 1:1000:200
# Environment: BACKLASH_FRF = the backlash_frf executable (default: this checkout's build, else PATH).
exec bash "$(dirname "$0")/slurm_shards.sh" backlash_frf "$@"
