#!/usr/bin/env bash
# tirstrain study's two targets: an unchanged second run recomputes nothing (its time, s), and --jobs 2
# against --jobs 1 (speedup on this machine's cores). Trials: TRIALS synthetic trials of
# samples/scenes/default.yaml (640x512, 60 frames, contact + tracking + strain), seeds 1..TRIALS.
# Usage: bench/study_bench.sh TIRSTRAIN [WORK_DIR] [TRIALS]   (default WORK_DIR /tmp/tirstrain-study-bench, 4)
set -euo pipefail
tirstrain=$(realpath "$1")
work=${2:-/tmp/tirstrain-study-bench}
trials=${3:-4}
scene=$(cd "$(dirname "$0")/.." && pwd)/samples/scenes/default.yaml
mkdir -p "$work/rec"
{
  echo "trials:"
  for i in $(seq "$trials"); do
    [ -d "$work/rec/t$i" ] || "$tirstrain" synth --scene "$scene" --seed "$i" --out "$work/rec/t$i" --quiet
    echo "  - {name: t$i, input: rec/t$i, scene: rec/t$i/scene.yaml, conditions: {seed: $i}}"
  done
} > "$work/study.yaml"

seconds() { local t0 t1; t0=$(date +%s.%N); "$@"; t1=$(date +%s.%N); echo "$t1 - $t0" | bc; }
rm -rf "$work/j1" "$work/j2"
j1=$(seconds "$tirstrain" study run "$work/study.yaml" --out "$work/j1" --jobs 1 --quiet)
j2=$(seconds "$tirstrain" study run "$work/study.yaml" --out "$work/j2" --jobs 2 --quiet)
again=$(seconds "$tirstrain" study run "$work/study.yaml" --out "$work/j1" --jobs 1 2> "$work/again.log")
grep -q "^0 of $trials trials to process" "$work/again.log" || { echo "second run reprocessed: $(cat "$work/again.log")"; exit 1; }
# Error: the key results of the two runs must be equal (the parallel run changes nothing but the time).
same=$(cmp -s <(cut -d, -f1-13 "$work/j1/study.csv") <(cut -d, -f1-13 "$work/j2/study.csv") && echo yes || echo NO)
echo "trials: $trials x (640x512, 60 frames), $(nproc) cores"
printf "study run --jobs 1: %.1f s   --jobs 2: %.1f s   speedup %.2fx   study.csv equal: %s\n" \
  "$j1" "$j2" "$(echo "$j1 / $j2" | bc -l)" "$same"
printf "unchanged second run: %.2f s (0 of %d trials processed)\n" "$again" "$trials"
