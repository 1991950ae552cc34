#!/usr/bin/env bash
# A real single-node Slurm cluster on localhost (issue 14): munged, slurmctld and slurmd started directly
# (no systemd), with a key, sockets, state and logs in the build tree and a slurm.conf written there. The
# cook of a real DEM is planned into >= 8 units, submitted with cooker/cluster/submit.sh as a job array
# plus an afterany merge job, first with one unit made to fail (the merge must refuse, naming it), then
# again without the failure (the merge must succeed, byte-identical to the one-process cook).
#   slurm_cluster_test.sh TERRAIN_COOK CLUSTER_DIR SCRATCH_DIR [DATA_DIR]
# DATA_DIR (default ../shared/data beside the checkout) holds kilauea_utm5n.tif; $TERRAIN_DATA_DIR wins.
# Prints "SKIP: ..." and exits 0 when the Slurm or MUNGE daemons are not installed or we are not root.
set -euo pipefail
usage() { echo "usage: slurm_cluster_test.sh TERRAIN_COOK CLUSTER_DIR SCRATCH_DIR [DATA_DIR]" >&2; exit 2; }
[ $# -eq 3 ] || [ $# -eq 4 ] || usage
cook=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
cluster_dir=$(cd "$2" && pwd)
scratch=$3
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)

for b in munged mungekey slurmctld slurmd sbatch squeue sinfo scontrol scancel python3; do
  command -v "$b" >/dev/null || { echo "SKIP: $b is not installed (scripts/setup.sh installs slurm-wlm and munge)"; exit 0; }
done
[ "$(id -u)" -eq 0 ] || { echo "SKIP: the test cluster runs its daemons as root (SlurmUser=root)"; exit 0; }

fail() { echo "FAIL: $*" >&2; exit 1; }
now() { date +%s.%N; }
secs() { python3 -c "print(f'{$2 - $1:.1f}')"; }

# ---- The DEM: Kilauea from the shared data, else the Jacksboro DEM Debian ships -----------------
data_dir=${TERRAIN_DATA_DIR:-${4:-$here/../../../shared/data}}
if [ -f "$data_dir/kilauea_utm5n.tif" ]; then
  input=$data_dir/kilauea_utm5n.tif flags=()
else
  input=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz flags=(--crs EPSG:4326)
  [ -f "$input" ] || { echo "SKIP: neither kilauea_utm5n.tif in $data_dir nor $input is present"; exit 0; }
fi

# ---- Layout in the build tree ---------------------------------------------------------------------
rm -rf "$scratch"
mkdir -p "$scratch"
scratch=$(cd "$scratch" && pwd)
# munged refuses group/world-writable folders on the way to its key, socket and logs.
chmod 0755 "$scratch"
mkdir -m 0755 "$scratch/munge"   # the socket folder must be searchable by all
mkdir -p "$scratch/state" "$scratch/log" "$scratch/work"
# Unix sockets (MUNGE's, slurmd's and each job step's, in the spool) take paths of at most 107 bytes, and
# a build tree can be deep: they live in a short folder of their own, removed at exit.
sockets=$(mktemp -d /tmp/terrain-slurm.XXXXXX)
chmod 0755 "$sockets"
conf=$scratch/slurm.conf
key=$scratch/munge/munge.key
socket=$sockets/munge.socket

# Two free TCP ports on the loopback (bound then released; Slurm re-binds them at once).
read -r ctld_port slurmd_port < <(python3 - <<'PY'
import socket
socks = [socket.socket() for _ in range(2)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(*[s.getsockname()[1] for s in socks])
PY
)
cpus=$(nproc)

munged_pid="" ctld_pid="" slurmd_pid=""
cleanup() {
  local rc=$?
  set +e
  if [ -n "$ctld_pid" ] && kill -0 "$ctld_pid" 2>/dev/null; then
    # Cancel what is left and give the steps a moment to end before the daemons go.
    scancel --full $(squeue -h -o %i 2>/dev/null) 2>/dev/null
    for _ in $(seq 1 20); do [ -z "$(squeue -h -o %i 2>/dev/null)" ] && break; sleep 0.5; done
  fi
  for pid in $slurmd_pid $ctld_pid $munged_pid; do
    kill "$pid" 2>/dev/null
  done
  for pid in $slurmd_pid $ctld_pid $munged_pid; do
    for _ in $(seq 1 40); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
    kill -0 "$pid" 2>/dev/null && kill -9 "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
  done
  # The last job steps' slurmstepd (daemons of their own) end once their job is gone: wait for them.
  for _ in $(seq 1 20); do pgrep -x slurmstepd >/dev/null || break; sleep 0.5; done
  rm -rf "$sockets"
  if [ $rc -ne 0 ]; then
    for f in "$scratch"/log/*.log "$scratch"/work/slurm-logs/*; do
      [ -f "$f" ] && { echo "---- tail of $f"; tail -n 15 "$f"; }
    done
  fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---- MUNGE ----------------------------------------------------------------------------------------
mungekey -c -k "$key" 2>/dev/null || dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
chmod 0400 "$key"
munged -F --key-file="$key" --socket="$socket" --pid-file="$scratch/munge/munged.pid" \
  --log-file="$scratch/log/munged.log" --seed-file="$scratch/munge/munged.seed" >"$scratch/log/munged.out" 2>&1 &
munged_pid=$!
for _ in $(seq 1 40); do [ -S "$socket" ] && break; sleep 0.25; done
[ -S "$socket" ] || fail "munged did not create $socket"

# ---- slurm.conf -----------------------------------------------------------------------------------
cat > "$conf" <<EOF
ClusterName=terraintest
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
StateSaveLocation=$scratch/state
SlurmdSpoolDir=$sockets/spool
SlurmctldPidFile=$scratch/state/slurmctld.pid
SlurmdPidFile=$scratch/state/slurmd.pid
SlurmctldLogFile=$scratch/log/slurmctld.log
SlurmdLogFile=$scratch/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MinJobAge=600
MailProg=/bin/true
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=1024 State=UNKNOWN
PartitionName=test Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$conf

t0=$(now)
slurmctld -D -f "$conf" >"$scratch/log/slurmctld.out" 2>&1 &
ctld_pid=$!
slurmd -D -N localhost -f "$conf" >"$scratch/log/slurmd.out" 2>&1 &
slurmd_pid=$!
state=""
for _ in $(seq 1 120); do
  kill -0 "$ctld_pid" 2>/dev/null || fail "slurmctld exited"
  kill -0 "$slurmd_pid" 2>/dev/null || fail "slurmd exited"
  state=$(sinfo -h -N -o %T 2>/dev/null || true)
  [ "$state" = idle ] && break
  sleep 0.5
done
[ "$state" = idle ] || fail "the node is not idle after 60 s (sinfo: '$state')"
echo "cluster up in $(secs "$t0" "$(now)") s: $(slurmctld -V), $cpus CPUs, ports $ctld_port/$slurmd_port"

# job_state ID: the JobState of one job (for an array, of every task, one a line).
job_state() { scontrol -o show job "$1" | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p'; }
# wait_for ID LIMIT: waits until the job has ended (the merge ends last: it waits on the array).
wait_for() {
  local id=$1 limit=$2 start state
  start=$(date +%s)
  while :; do
    state=$(job_state "$id")
    case $state in
      COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|BOOT_FAIL|DEADLINE|PREEMPTED) return 0 ;;
    esac
    [ $(( $(date +%s) - start )) -lt "$limit" ] || { squeue; fail "job $id still '$state' after $limit s"; }
    sleep 1
  done
}
# submit: runs submit.sh and sets units_job, merge_job.
submit() {
  local out
  out=$(TERRAIN_COOK=$cook "$cluster_dir/submit.sh" "$work" "$scratch/cluster.terrain" --max-parallel "$cpus" \
        --partition test "$@")
  units_job=$(sed -n 's/^units_job=//p' <<<"$out")
  merge_job=$(sed -n 's/^merge_job=//p' <<<"$out")
  [[ $units_job =~ ^[0-9]+$ && $merge_job =~ ^[0-9]+$ ]] || fail "submit.sh printed no job ids: $out"
}

# ---- The one-process reference cook ---------------------------------------------------------------
t0=$(now)
"$cook" "$input" -o "$scratch/local.terrain" "${flags[@]}" >"$scratch/log/local_cook.out" 2>&1 \
  || fail "the one-process cook failed: $(tail -n 5 "$scratch/log/local_cook.out")"
local_secs=$(secs "$t0" "$(now)")

# ---- Plan -----------------------------------------------------------------------------------------
work=$scratch/work
# Units of 4 x 4 roots: 16 units on Kilauea and on Jacksboro (1 x 1 gives 169 and 256, and Slurm takes
# a few seconds to start each pair of tasks on 2 CPUs). The archive is the same for any unit size.
unit_roots=4
plan_out=$("$cook" plan "$input" --work-dir "$work" "${flags[@]}" --unit-roots $unit_roots --json) || fail "plan failed"
units=$(python3 -c 'import json,sys; print(json.loads(sys.argv[1])["units"])' "$plan_out") \
  || fail "plan --json printed no unit count: $plan_out"
[ "$units" -ge 8 ] || fail "$(basename "$input") planned into $units units with --unit-roots $unit_roots; the test needs >= 8"
echo "planned $(basename "$input") into $units units of $unit_roots x $unit_roots roots; one-process cook $local_secs s"

# written_since MARKER: files of W (not the job logs) written after MARKER was touched.
written_since() { find "$work" -type f -newer "$1" ! -path "$work/slurm-logs/*" | wc -l; }

# ---- Run 1: unit 2 fails on purpose; the merge runs (afterany) and refuses, naming unit 2 ----------
touch "$scratch/run1.marker"
t0=$(now)
TERRAIN_COOK_FAIL_UNITS=2 submit
wait_for "$merge_job" 600
run1_secs=$(secs "$t0" "$(now)")
mapfile -t task_states < <(job_state "$units_job")
[ ${#task_states[@]} -eq "$units" ] || fail "array $units_job has ${#task_states[@]} tasks, expected $units"
failed_tasks=$(scontrol -o show job "$units_job" | grep -c 'JobState=FAILED' || true)
[ "$failed_tasks" -eq 1 ] || fail "array $units_job: $failed_tasks failed tasks, expected 1 (unit 2): ${task_states[*]}"
scontrol -o show job "$units_job" | grep 'ArrayTaskId=2 ' | grep -q 'JobState=FAILED' \
  || fail "array task 2 did not fail"
[ "$(job_state "$merge_job")" = FAILED ] || fail "merge job $merge_job is $(job_state "$merge_job"), expected FAILED"
merge_log=$work/slurm-logs/merge-$merge_job.out
grep -Eq 'unit 2([^0-9]|$)' "$merge_log" || fail "the merge log does not name unit 2: $(cat "$merge_log")"
[ ! -e "$scratch/cluster.terrain" ] || fail "a failed merge left $scratch/cluster.terrain"
echo "run 1 (unit 2 failing): $run1_secs s; 1 of $units tasks FAILED; merge refused: $(grep -E 'unit 2([^0-9]|$)' "$merge_log" | head -n 1)"

run1_written=$(written_since "$scratch/run1.marker")

# ---- Run 2: the array again without the failure; complete units are skipped ----------------------
touch "$scratch/run2.marker"
t0=$(now)
submit
wait_for "$merge_job" 600
run2_secs=$(secs "$t0" "$(now)")
completed=$(scontrol -o show job "$units_job" | grep -c 'JobState=COMPLETED' || true)
[ "$completed" -eq "$units" ] || fail "re-run array $units_job: $completed of $units tasks COMPLETED"
[ "$(job_state "$merge_job")" = COMPLETED ] \
  || fail "merge job $merge_job is $(job_state "$merge_job"): $(cat "$work/slurm-logs/merge-$merge_job.out")"
# Complete units are not redone: the re-run writes only unit 2's files, fewer than run 1's (every other unit).
run2_written=$(written_since "$scratch/run2.marker")
[ "$run2_written" -ge 1 ] && [ "$run2_written" -lt "$run1_written" ] \
  || fail "files written in W: run 1 $run1_written, run 2 $run2_written (the re-run should redo only unit 2)"
echo "files written in W: run 1 (all units but 2) $run1_written, run 2 (unit 2 only) $run2_written"
cmp "$scratch/local.terrain" "$scratch/cluster.terrain" \
  || fail "the cluster archive differs from the one-process cook"
echo "run 2 (re-run): $run2_secs s; $units of $units tasks COMPLETED; merge COMPLETED"
echo "cluster archive byte-identical to the one-process cook: $(stat -c %s "$scratch/cluster.terrain") bytes"
echo "PASS: slurm cluster: $units units; one-process $local_secs s, run 1 $run1_secs s, run 2 $run2_secs s"
