#!/usr/bin/env bash
# A real SLURM cluster in the tests (issue 16, docs/distributed.md): brings up a single-node
# cluster on this machine (Debian's slurmctld, slurmd, slurm-client and munge, private to this
# script: its own munge socket, configuration, ports, state and logs in a temporary directory),
# submits a planned study (2 paper scenes × 3 integrators × K = 4 at 32×32) with the script
# `lumis study --plan DIR --slurm` writes, polls squeue until the array and its collect job
# have left the queue, and checks the collected results.csv against a local run of the same
# study (every column but the times). Stops every daemon it started.
#
# Usage: scripts/slurm/cluster-test.sh LUMIS
#   LUMIS: the lumis executable to test. Needs root (the daemons); installs the packages with
#   apt-get when they are missing (from the package index, or its local cache when offline);
#   exits with status 77 and a line saying why when it cannot run here.
set -euo pipefail
lumis=$(realpath "${1:?usage: cluster-test.sh LUMIS}")
repo=$(cd "$(dirname "$0")/../.." && pwd)
skip() { echo "SLURM cluster test skipped: $*"; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "it needs root to run the SLURM and munge daemons"
packages="slurmctld slurmd slurm-client munge"
installed() {
    for tool in slurmctld slurmd sbatch squeue sinfo munged; do
        command -v "$tool" >/dev/null 2>&1 || return 1
    done
}
if ! installed; then
    command -v apt-get >/dev/null 2>&1 || skip "the packages ($packages) are not installed and there is no apt-get"
    export DEBIAN_FRONTEND=noninteractive
    # Offline, the local package cache may still hold them; else refresh the index once.
    if ! apt-get install -y -q $packages >/dev/null 2>&1; then
        apt-get update -q >/dev/null 2>&1 && apt-get install -y -q $packages >/dev/null 2>&1 ||
            skip "cannot install $packages with apt-get (no package index reachable?)"
    fi
    installed || skip "the packages installed but their programs are missing"
fi
[ -r /etc/munge/munge.key ] || skip "no munge key in /etc/munge/munge.key"
id munge >/dev/null 2>&1 || skip "no munge user"

work=$(mktemp -d /tmp/lumis-slurm.XXXXXX)
chmod 755 "$work"
pids=()
# Whether process $1 runs (not exited, nor an exited child not yet waited for).
running() {
    local state
    state=$(ps -o stat= -p "$1" 2>/dev/null) && [ "${state#Z}" = "$state" ]
}
cleanup() {
    # Jobs still queued or running on this private cluster (after a timeout), then only the
    # daemons this script started, by their process ids.
    if [ -n "${SLURM_CONF:-}" ]; then
        squeue -h -o %A 2>/dev/null | xargs -r scancel 2>/dev/null || true
    fi
    for pid in "${pids[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${pids[@]}"; do
        for _ in $(seq 50); do running "$pid" || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
        wait "$pid" 2>/dev/null || true
    done
    rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# munge, as the munge user, on a private socket.
mkdir -p "$work/munge"
chown munge: "$work/munge"
chmod 755 "$work/munge"
setpriv --reuid=munge --regid=munge --init-groups munged --foreground --socket="$work/munge/munge.socket" \
    --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" \
    --seed-file="$work/munge/munged.seed" >"$work/munged.out" 2>&1 &
pids+=($!)
for _ in $(seq 50); do [ -S "$work/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$work/munge/munge.socket" ] || { cat "$work/munged.out" >&2; echo "munged did not start" >&2; exit 1; }

# slurm.conf: this host as controller and only node (its line from `slurmd -C`), ports that
# no system cluster uses, scheduling every second (else each wave of tasks waits ~10 s).
host=$(hostname -s)
node=$(slurmd -C | head -n 1)
port=$((20000 + RANDOM % 20000))
mkdir -p "$work/state" "$work/spool" "$work/log"
export SLURM_CONF="$work/slurm.conf"
cat >"$SLURM_CONF" <<CONF
ClusterName=lumis-test
SlurmctldHost=$host
SlurmUser=root
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
AuthInfo=socket=$work/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
SchedulerParameters=sched_interval=1,bf_interval=1
$node
PartitionName=lumis Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -D -f "$SLURM_CONF" >"$work/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" >"$work/log/slurmd.out" 2>&1 &
pids+=($!)
ready=
for _ in $(seq 100); do
    if sinfo -h -N -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then ready=1; break; fi
    sleep 0.2
done
[ -n "$ready" ] || { tail -n 20 "$work/log/"*.log >&2 || true; echo "the SLURM node did not come up" >&2; exit 1; }
echo "SLURM: controller and node $host up ($(sinfo -h -o '%c') CPUs)"

study=(scenes/paper/03.ron scenes/paper/06.ron --integrators balance,light,alpha
    --budgets 4,8 --runs 4 --max-runs 4 --reference-samples 64
    --set film.width=32 --set film.height=32 --threads 1 --quiet)
cd "$repo"
start=$(date +%s.%N)
"$lumis" study "${study[@]}" --out "$work/slurm-study" --plan "$work/plan" --slurm >/dev/null
cells=$(grep -c 'scene:' "$work/plan/manifest.ron")
sh "$work/plan/slurm.sh" | sed 's/^/SLURM: /'
for _ in $(seq 600); do
    [ -z "$(squeue -h -o %i)" ] && break
    sleep 0.2
done
[ -z "$(squeue -h -o %i)" ] || { squeue >&2; echo "the jobs did not finish in 120 s" >&2; exit 1; }
end=$(date +%s.%N)
if [ ! -f "$work/slurm-study/results.csv" ]; then
    cat "$work/plan/logs/collect.out" >&2 2>/dev/null || echo "the collect job did not run" >&2
    exit 1
fi
echo "SLURM: $cells cells and the collect job in $(echo "$end - $start" | bc) s of wall time (plan, submit, run, collect)"

local_start=$(date +%s.%N)
"$lumis" study "${study[@]}" --out "$work/local-study"
local_end=$(date +%s.%N)
echo "local run of the same study: $(echo "$local_end - $local_start" | bc) s"
python3 - "$work/local-study/results.csv" "$work/slurm-study/results.csv" <<'PY'
import csv, sys
def rows(path):
    # Every column but those that depend on measured time.
    timed = lambda k: "time" in k or "efficiency" in k
    return [{k: v for k, v in r.items() if not timed(k)} for r in csv.DictReader(open(path))]
local, slurm = rows(sys.argv[1]), rows(sys.argv[2])
if local != slurm or not local:
    sys.exit(f"SLURM results.csv differs from the local run's ({len(slurm)} rows against {len(local)})")
print(f"SLURM results.csv identical to the local run's ({len(local)} rows, {len(local[0])} columns compared, times aside)")
PY
