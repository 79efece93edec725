#!/usr/bin/env bash
# A real single-node Slurm (slurmctld + slurmd + munge on this host, private state in a temporary directory, started
# and stopped here), a small sweep run through scripts/slurm_sweep.sh as an array job plus its dependent merge job,
# and the merged CSV compared byte for byte with an unsharded run; then the same for a stepped-sine backlash_frf
# (scripts/slurm_frf.sh). Bounded: gives up after 240 s.
# usage: bash test/slurm/local_slurm_sweep.sh [PARTS]      exit 0 = equal
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
parts=${1:-4}
sweep=$here/build/devel/lib/backlash_servo/backlash_sweep
for tool in slurmctld slurmd sbatch squeue munged; do
  command -v $tool >/dev/null || { echo "local_slurm_sweep: $tool missing (apt-get install slurm-wlm munge)" >&2; exit 2; }
done
dir=$(mktemp -d /tmp/backlash_slurm.XXXXXX)
chmod 755 "$dir"
host=$(hostname -s)
cleanup() {
  [ -f "$dir/slurmd.pid" ] && kill "$(cat "$dir/slurmd.pid")" 2>/dev/null || true
  [ -f "$dir/slurmctld.pid" ] && kill "$(cat "$dir/slurmctld.pid")" 2>/dev/null || true
  [ -f "$dir/munged.pid" ] && kill "$(cat "$dir/munged.pid")" 2>/dev/null || true
  sleep 1
  rm -rf "$dir"
}
trap cleanup EXIT
# munge with a private key and socket.
mkdir -p "$dir/munge"
chmod 700 "$dir/munge"
dd if=/dev/urandom bs=1 count=1024 of="$dir/munge/munge.key" 2>/dev/null
chmod 400 "$dir/munge/munge.key"
munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
  --pid-file="$dir/munged.pid" --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/munged.seed"
mkdir -p "$dir/state" "$dir/spool"
cores=$(nproc)
cat > "$dir/slurm.conf" <<CONF
ClusterName=backlash_test
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/builtin
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
NodeName=$host CPUs=$cores RealMemory=512 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$dir/slurm.conf
slurmctld -c -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
deadline=$((SECONDS + 240))
until sinfo -h -o %t 2>/dev/null | grep -qE "idle|mix"; do
  [ $SECONDS -lt $deadline ] || { echo "local_slurm_sweep: the node never came up" >&2; tail -20 "$dir/slurmctld.log" "$dir/slurmd.log" >&2; exit 1; }
  sleep 0.5
done
# Submits an array job of PARTS parts and its merge job through SCRIPT, waits for the merge, and compares the merged
# CSV byte for byte with one unsharded run of EXE (its CSV flag OUT_FLAG) under the name NAME.
#   array_equals_unsharded LABEL SCRIPT EXE OUT_FLAG PARTS NAME ARGS...   (LABEL "" for the grid sweep)
array_equals_unsharded() {
  local label=$1 script=$2 exe=$3 out_flag=$4 n=$5 name=$6
  shift 6
  local ids merge_id
  ids=$(bash "$here/scripts/$script" -n "$n" -o "$dir/${name}merged.csv" -d "$dir/${name}parts" -- "$@" | tail -1)
  merge_id=${ids#* }
  while squeue -h -j "$merge_id" 2>/dev/null | grep -q .; do
    [ $SECONDS -lt $deadline ] || { echo "local_slurm_sweep: timed out waiting for merge job $merge_id" >&2; squeue >&2; exit 1; }
    sleep 0.5
  done
  "$exe" "$@" --jobs 1 "$out_flag" "$dir/${name}single.csv" >/dev/null 2>&1
  if ! cmp -s "$dir/${name}merged.csv" "$dir/${name}single.csv"; then
    echo "local_slurm_sweep: ${label:-the sweep}'s merged CSV differs from the unsharded run" >&2
    ls -la "$dir/${name}parts" >&2 || true
    cat "$dir/${name}parts/merge.log" "$dir/${name}parts"/part_*.log >&2 || true
    exit 1
  fi
  echo "local_slurm_sweep: $n-part ${label:+$label }array job + merge job = the unsharded CSV ($(($(wc -l < "$dir/${name}single.csv") - 1)) rows)"
}
array_equals_unsharded "" slurm_sweep.sh "$sweep" --output "$parts" "" \
  --zeta 0.2,0.5 --inertia-ratio 1,9 --friction-ratio 0,0.4 --restitution 0.6,1
# The same for the stepped-sine frequency response (scripts/slurm_frf.sh).
array_equals_unsharded backlash_frf slurm_frf.sh "$here/build/devel/lib/backlash_servo/backlash_frf" --csv 3 frf_ \
  --controller-rate 100 --restitution 0.8 --amplitude 0.5,1 --frequency 0.3,1,2
# A tolerance study (keys drawn per joint, the distributions' parentheses through sbatch's command line).
array_equals_unsharded "tolerance study" slurm_sweep.sh "$sweep" --output 3 mc_ \
  --monte-carlo 12 --seed 3 --backlash 'uniform(0.05,0.5)' --zeta 'normal(0.35,0.1)'
exit 0
