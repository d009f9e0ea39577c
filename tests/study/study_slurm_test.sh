#!/bin/bash
# tirstrain study through a real Slurm: starts munged, slurmctld and slurmd on this machine with a
# temporary configuration (their own key, socket, ports, state and log folders), runs a three-trial study
# with --executor slurm (submitted without waiting and followed with study status, then one changed trial
# resubmitted and waited for, with a fourth trial cancelled while it runs), checks that study.csv's results
# and every result.h5 dataset and attribute (h5diff) equal those of the local executor, that the cancelled
# trial is recorded as failed with the Slurm state sacct gives for it, and stops the daemons. Exits 77
# (skipped) with the reason when Slurm, munge or h5diff is not installed or the test does not run as root.
set -euo pipefail
tirstrain=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)

skip() { echo "SKIP: $*"; exit 77; }
for tool in munged slurmctld slurmd sbatch squeue sinfo sacct scancel; do
  command -v "$tool" > /dev/null || PATH=$PATH:/usr/sbin command -v "$tool" > /dev/null ||
    skip "$tool not found (Debian packages slurm-wlm and munge; scripts/install-deps)"
done
export PATH=$PATH:/usr/sbin
[ "$(id -u)" -eq 0 ] || skip "the daemons run as root in this test (SlurmUser=root); run as root"
command -v h5diff > /dev/null || skip "h5diff not found (Debian package hdf5-tools)"

rm -rf "$work"
mkdir -p "$work"/{state,spool,log,munge}
chmod 711 "$work/munge"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2> /dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2> /dev/null || true; done
}
trap cleanup EXIT

# Two free TCP ports for slurmctld and slurmd.
read -r ctld_port slurmd_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')

dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
munged --foreground --force --key-file="$work/munge/munge.key" --socket="$work/munge/munge.sock" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/log/munged.log" --seed-file="$work/munge/seed" \
  > "$work/log/munged.out" 2>&1 &
pids+=($!)

# No slurmdbd (it needs a MySQL server): sacct's accounting form fails ("Slurm accounting storage is
# disabled") and the executor asks the job completion log instead (jobcomp/filetxt, sacct --completion).
export SLURM_CONF=$work/slurm.conf
cat > "$SLURM_CONF" <<CONF
ClusterName=tirstraintest
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$work/munge/munge.sock
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$work/log/jobcomp.txt
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 RealMemory=512 State=UNKNOWN
PartitionName=studytest Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF

for i in $(seq 50); do [ -S "$work/munge/munge.sock" ] && break; sleep 0.1; done
slurmctld -D -f "$SLURM_CONF" > "$work/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N localhost -f "$SLURM_CONF" > "$work/log/slurmd.out" 2>&1 &
pids+=($!)
idle=0
for i in $(seq 150); do
  if [ "$(sinfo -h -N -o %t 2> /dev/null | head -1)" = "idle" ]; then idle=1; break; fi
  sleep 0.2
done
if [ "$idle" -ne 1 ]; then
  echo "the node never became idle; logs:" >&2
  tail -n 20 "$work"/log/* >&2
  exit 1
fi

"$here/make_trials.sh" "$tirstrain" "$work/rec" 1 2 4
cat > "$work/study.yaml" <<'YAML'
trials:
  - {name: p1, input: rec/load_1, scene: rec/load_1/scene.yaml, conditions: {normal_N: 1}}
  - {name: p2, input: rec/load_2, scene: rec/load_2/scene.yaml, conditions: {normal_N: 2}}
  - {name: p4, input: rec/load_4, scene: rec/load_4/scene.yaml, conditions: {normal_N: 4}}
slurm: {partition: studytest, cpus_per_task: 1, mem_MB: 100, time_min: 5}
YAML

# sbatch refusing the job (here: no configuration it can read) leaves no trial "queued" for a job that does
# not exist: each is failed with sbatch's message.
if SLURM_CONF=$work/no_such.conf "$tirstrain" study run "$work/study.yaml" --out "$work/refused" \
    --executor slurm --no-wait 2> "$work/refused.log"; then
  echo "study run succeeded although sbatch failed"; exit 1
fi
"$tirstrain" study status "$work/refused" > "$work/refused_status.txt"
grep -q "0 done 3 failed" "$work/refused_status.txt" || { echo "after a failed sbatch: $(cat "$work/refused_status.txt")"; exit 1; }
grep -q "not submitted" "$work/refused/status/p1.json" || { echo "no reason: $(cat "$work/refused/status/p1.json")"; exit 1; }

# Submitted without waiting: study status follows the job, study aggregate summarises it.
"$tirstrain" study run "$work/study.yaml" --out "$work/slurm" --executor slurm --no-wait
grep -q -- "--partition=studytest" "$work/slurm/slurm/job.sh"
grep -q -- "--array=0,1,2" "$work/slurm/slurm/job.sh"
for i in $(seq 200); do
  "$tirstrain" study status "$work/slurm" | grep -q "3 done" && break
  sleep 0.2
done
"$tirstrain" study status "$work/slurm" | grep -q "3 done 0 failed"
"$tirstrain" study aggregate "$work/slurm"
[ -f "$work/slurm/aggregate/conditions.csv" ]

# A changed scene and a new trial, cut, which is cancelled (scancel) while it runs: two tasks submitted,
# waited for (squeue), cut's end asked of sacct, then aggregated. cut processes for about 1.4 s after its
# status says running, and the cancel follows within 0.1 s.
cp "$work/study.yaml" "$work/study2.yaml"
sed -i '/p4, input/a\  - {name: cut, input: rec/load_4, scene: rec/load_4/scene.yaml, conditions: {normal_N: 4}}' \
  "$work/study2.yaml"
echo "# edited" >> "$work/rec/load_2/scene.yaml"
"$tirstrain" study run "$work/study2.yaml" --out "$work/slurm" --executor slurm --poll-s 0.5 \
  2> "$work/slurm2.log" &
run=$!
cancelled=0
for i in $(seq 300); do
  if [ -s "$work/slurm/slurm/job_id" ] &&
    grep -q '"status": "running"' "$work/slurm/status/cut.json" 2> /dev/null; then
    scancel "$(cat "$work/slurm/slurm/job_id")_3"
    cancelled=1
    break
  fi
  sleep 0.05
done
[ "$cancelled" -eq 1 ] || { echo "cut never ran" >&2; exit 1; }
status=0
wait "$run" || status=$?
cat "$work/slurm2.log"
[ "$status" -eq 1 ] || { echo "a study with a cancelled trial exited $status" >&2; exit 1; }
grep -q "2 of 4 trials to process" "$work/slurm2.log"
grep -q -- "--array=1,3$" "$work/slurm/slurm/job.sh"
if grep -q "sacct cannot say" "$work/slurm2.log"; then echo "sacct did not answer" >&2; exit 1; fi
"$tirstrain" study run "$work/study.yaml" --out "$work/local" --jobs 2 --quiet

python3 - "$work/slurm" "$work/local" <<'PY'
import csv, sys
slurm, local = sys.argv[1], sys.argv[2]
def rows(d):
    return {r["name"]: r for r in csv.DictReader(open(d + "/study.csv"))}
a, b = rows(slurm), rows(local)
assert list(a) == ["p1", "p2", "p4", "cut"], list(a)
cut = a.pop("cut")
# Recorded by the executor from sacct --completion: the task left no outcome of its own.
assert cut["status"] == "failed", cut
assert "Slurm state CANCELLED" in cut["error"] and "without recording its outcome" in cut["error"], cut
for name in a:
    assert a[name]["status"] == "done", a[name]
    for key in ("frames", "peak_contact_area_mm2", "mu_dynamic", "U_t90_J", "mu_P_N", "hash"):
        assert a[name][key] == b[name][key], (name, key, a[name][key], b[name][key])
    assert float(a[name]["peak_contact_area_mm2"]) > 0, a[name]
PY
for name in p1 p2 p4; do
  # Every dataset and attribute equal (h5diff exits 1 on any difference).
  h5diff "$work/slurm/trials/$name/result.h5" "$work/local/trials/$name/result.h5"
  [ "$(h5ls -r "$work/slurm/trials/$name/result.h5" | grep -c Dataset)" -gt 10 ]
done
grep -q '"status": "done"' "$work/slurm/status/p1.json"
echo "study slurm: ok"
