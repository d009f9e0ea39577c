#!/bin/sh
# tirstrain study with the local executor on three tiny synthetic trials and one broken one: results,
# study.csv, the failure recorded while the study goes on, the power law of contact area against load
# (Hertz: area ~ P^(2/3)), the averaged maps, and resumption (an unchanged second run processes only the
# failed trial and leaves the results and aggregate/ as they were). What changes a trial's hash is
# study_file_test's.
set -eu
tirstrain=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)
rm -rf "$work"
mkdir -p "$work"
"$here/make_trials.sh" "$tirstrain" "$work/rec" 1 2 4

cat > "$work/study.yaml" <<'YAML'
trials:
  - {name: p1, input: rec/load_1, scene: rec/load_1/scene.yaml, conditions: {normal_N: 1, finger: index}}
  - {name: p2, input: rec/load_2, scene: rec/load_2/scene.yaml, conditions: {normal_N: 2, finger: index}}
  - {name: p4, input: rec/load_4, scene: rec/load_4/scene.yaml, conditions: {normal_N: 4, finger: index}}
  - {name: broken, input: rec/missing, conditions: {normal_N: 3, finger: middle}}
compute: [fit]
aggregate:
  power_laws:
    - {name: area, normal: normal_N, mu: peak_contact_area_mm2}
  maps: {by: [finger]}
  table: {by: [finger]}
YAML

fail() { echo "FAIL: $*" >&2; exit 1; }

# A failing trial makes the run exit 1 after everything else is done and aggregated.
if "$tirstrain" study run "$work/study.yaml" --out "$work/out" --jobs 2 2> "$work/run1.log"; then
  fail "a study with a broken trial exited 0"
fi
cat "$work/run1.log"
grep -q "4 of 4 trials to process" "$work/run1.log" || fail "first run did not process all trials"
python3 - "$work/out" <<'PY'
import csv, json, math, sys
out = sys.argv[1]
rows = {r["name"]: r for r in csv.DictReader(open(out + "/study.csv"))}
assert list(rows) == ["p1", "p2", "p4", "broken"], list(rows)
for n in ("p1", "p2", "p4"):
    assert rows[n]["status"] == "done", rows[n]
    assert rows[n]["frames"] == "8", rows[n]
assert rows["broken"]["status"] == "failed" and "missing" in rows["broken"]["error"], rows["broken"]
# Hertz: a ~ P^(1/3), so the contact area grows as P^(2/3).
area = {n: float(rows[n]["peak_contact_area_mm2"]) for n in ("p1", "p2", "p4")}
assert area["p1"] < area["p2"] < area["p4"], area
# The fitted muP (friction 1 in the synthetic scenes: muP = P) within 20 % where frames resolve the slip
# annulus (measured: 3 % and 7 % low at 1 and 2 N). At 4 N the 8 frames reach only Q = 0.38 P, the annulus
# stays in the outer 15 % of the radius, beyond the tracks, and muP is not identifiable from one frame (the
# largest-Q frame comes out in partial slip or in full slip): there only that the limit lies above the
# largest true Q of its partial-slip frames (0.95 N) and below 1.2 P.
for n, load in (("p1", 1.0), ("p2", 2.0)):
    assert abs(float(rows[n]["mu_P_N"]) - load) < 0.2 * load, (n, rows[n]["mu_P_N"])
assert 0.9 < float(rows["p4"]["mu_P_N"]) < 4.8, rows["p4"]["mu_P_N"]
law = json.load(open(out + "/aggregate/power_law_area.json"))
assert abs(law["b"] - 2.0 / 3.0) < 0.1, law["b"]
assert law["samples"] == 3, law
table = list(csv.DictReader(open(out + "/aggregate/conditions.csv")))
by = {r["finger"]: r for r in table}
assert by["index"]["trials"] == "3" and by["index"]["trials_done"] == "3", by
assert by["middle"]["trials"] == "1" and by["middle"]["trials_done"] == "0", by
mean = float(by["index"]["peak_contact_area_mm2_mean"])
assert abs(mean - sum(area.values()) / 3) < 1e-6 * mean, (mean, area)
assert by["index"]["peak_contact_area_mm2_n"] == "3", by
agg = json.load(open(out + "/aggregate/aggregate.json"))
assert agg["trials_done"] == 3, agg
assert agg["report"] == "report.html", agg
page = open(out + "/aggregate/report.html").read()
# The three done trials in one page, the broken one not among them.
for name in ("p1", "p2", "p4"):
    assert '"result":"%s"' % name in page, name
assert '"result":"broken"' not in page
PY
[ -f "$work/out/aggregate/maps/finger=index/average.h5" ] || fail "no averaged maps for finger=index"
[ ! -e "$work/out/aggregate/maps/finger=middle" ] || fail "maps averaged over no done trial"
h5dump -a /maps/inputs_and_frames "$work/out/aggregate/maps/finger=index/average.h5" | grep -q "p4/result.h5" ||
  fail "the finger=index average does not hold p4"
"$tirstrain" study status "$work/out" > "$work/status.txt"
grep -q "4 trials" "$work/status.txt" && grep -q "3 done 1 failed" "$work/status.txt" || fail "status: $(cat "$work/status.txt")"

# Unchanged: nothing but the broken trial runs again, and the results stay the same files.
aggregate_inode=$(stat -c %i "$work/out/aggregate")
before=$(stat -c %Y.%i "$work/out/trials/p1/result.h5" "$work/out/trials/p2/result.h5" "$work/out/trials/p4/result.h5")
"$tirstrain" study run "$work/study.yaml" --out "$work/out" --jobs 2 2> "$work/run2.log" || true
grep -q "1 of 4 trials to process (3 unchanged" "$work/run2.log" || fail "second run: $(cat "$work/run2.log")"
after=$(stat -c %Y.%i "$work/out/trials/p1/result.h5" "$work/out/trials/p2/result.h5" "$work/out/trials/p4/result.h5")
[ "$before" = "$after" ] || fail "an unchanged trial was reprocessed"
[ "$(stat -c %i "$work/out/aggregate")" = "$aggregate_inode" ] || fail "aggregate/ was rebuilt with nothing changed"

# A trial left "running" by a process that is gone (killed with the study) is shown as failed, interrupted.
sleep 0 & gone=$!; wait "$gone"
python3 - "$work/out/status/p1.json" "$gone" "$(hostname)" <<'PY'
import json, sys
path, pid, host = sys.argv[1], int(sys.argv[2]), sys.argv[3]
s = json.load(open(path)); s.update(status="running", pid=pid, host=host); json.dump(s, open(path, "w"))
PY
"$tirstrain" study status "$work/out" > "$work/status_gone.txt"
grep -q "2 done 2 failed" "$work/status_gone.txt" || fail "a gone trial's status: $(cat "$work/status_gone.txt")"
grep -q "interrupted" "$work/status_gone.txt" || fail "no reason given: $(cat "$work/status_gone.txt")"

# A folder of the user's (here a process result) is not taken for a study folder: refused, left as it was.
mkdir -p "$work/not_a_study" && echo '{}' > "$work/not_a_study/summary.json"
if "$tirstrain" study run "$work/study.yaml" --out "$work/not_a_study" 2> "$work/refused.log"; then
  fail "a folder holding summary.json was taken for a study folder"
fi
grep -q "holds 'summary.json', which a study does not write" "$work/refused.log" || fail "refusal: $(cat "$work/refused.log")"
[ "$(ls "$work/not_a_study")" = "summary.json" ] || fail "the refused folder was changed: $(ls "$work/not_a_study")"

# SIGTERM to the study alone (not to its process group): the running trial stops with it and is recorded
# as interrupted, no trial process outlives it, and the next run finishes every trial.
"$tirstrain" study run "$work/study.yaml" --out "$work/out_term" --jobs 1 2> "$work/term.log" &
study=$!
for _ in $(seq 1 200); do
  grep -qs '"running"' "$work/out_term/status/"*.json && break
  sleep 0.05
done
kill -TERM "$study"
if wait "$study"; then fail "a study stopped by SIGTERM exited 0"; fi
grep -q "interrupted" "$work/term.log" || fail "the stop is not said: $(cat "$work/term.log")"
if pgrep -f "run-trial $work/out_term" > /dev/null; then fail "a trial process outlived the study"; fi
"$tirstrain" study run "$work/study.yaml" --out "$work/out_term" --jobs 2 2> "$work/term2.log" || true
"$tirstrain" study status "$work/out_term" > "$work/status_term.txt"
grep -q "3 done 1 failed" "$work/status_term.txt" || fail "after the stopped run: $(cat "$work/status_term.txt")"

echo "study local: ok"
