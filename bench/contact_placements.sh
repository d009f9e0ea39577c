#!/bin/sh
# Contact accuracy against where the fingerprint lies under the contact. The same contact (same truth mask
# and truth ellipse) is synthesised with the fingerprint's core moved to each offset, and `tirstrain validate`
# measures the segmented contact against the truth: the ridge phase along the border differs each time, which
# is what decides the outline where a valley lies along the border (BENCHMARKS.md, contact/). An entry
# seed=N synthesises the scene with seed N instead: another fingerprint (ridge flow, minutiae, noise) and
# another irregular border, same contact size and loading.
# Usage:
#   bench/contact_placements.sh TIRSTRAIN_BINARY OUT_DIR [SCENE.yaml] [FRAMES]
# SCENE defaults to samples/scenes/hard_tiny_contact.yaml, FRAMES to 2 (frames at rest; more frames add the
# plate's motion). Environment: TIRSTRAIN_BENCH_CORES, the core offsets in mm as "x,y x,y ..." (default: the
# scene's own first, then eleven more: inside, near and well outside the contact), or seed=N entries, e.g.
# TIRSTRAIN_BENCH_CORES="seed=1 seed=2 seed=3".
# Prints one line per placement: the contact's segmentation ms/frame, worst IoU, ellipse centre error (RMS and
# worst, px) and worst semi-axis error (%), then the RMS and worst over all placements.
set -eu
cli=$1; out=$2
scene=${3:-$(dirname "$0")/../samples/scenes/hard_tiny_contact.yaml}
frames=${4:-2}
cores=${TIRSTRAIN_BENCH_CORES:-"scene 0.2,-0.1 0.05,-0.2 0.1,0.1 -0.2,0.15 0.25,0.25 -0.1,-0.3 0,0 1.5,1.0 -2.0,0.5 0.8,-1.2 -1.0,-1.0"}
mkdir -p "$out"
column() {  # column NAME of the validation.csv row QUANTITY
  awk -F, -v q="$1" -v c="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == c) k = i } $1 == q { print $k }' "$3"
}
printf "%-14s %9s %8s %10s %10s %9s\n" placement contact_ms IoU_min centre_rms centre_max axis_max |
  tee "$out/placements.txt"
i=0
for core in $cores; do
  dir=$out/placement_$i
  rm -rf "$dir"
  mkdir -p "$dir"
  sed -e "s/\(timing: {frames: \)[0-9]*/\1$frames/" "$scene" > "$dir/scene.yaml"
  case $core in
  seed=*)
    sed -i "s/^\(  seed: \)[0-9]*/\1${core#seed=}/" "$dir/scene.yaml"
    grep -q "^  seed: ${core#seed=}\$" "$dir/scene.yaml" || { echo "no synthesis seed in $scene" >&2; exit 2; }
    ;;
  scene) ;;
  *)
    sed -i "s/core_offset_mm: \[[^]]*\]/core_offset_mm: [$core]/" "$dir/scene.yaml"
    grep -q "core_offset_mm: \[$core\]" "$dir/scene.yaml" || { echo "no core_offset_mm in $scene" >&2; exit 2; }
    ;;
  esac
  "$cli" validate --scene "$dir/scene.yaml" --out "$dir/validation" --quiet --no-maps > "$dir/validate.log" 2>&1 ||
    { echo "validate failed: $dir/validate.log" >&2; exit 1; }
  csv=$dir/validation/validation.csv
  ms=$(sed -n 's/.*"segment_ms_per_frame": *\([0-9.e+-]*\).*/\1/p' "$dir/validation/result/summary.json" | head -n 1)
  iou_min=$(awk -v d="$(column contact_1-IoU max_abs "$csv")" 'BEGIN { printf "%.4f", 1 - d }')
  major=$(column contact_semi_major max_abs "$csv")
  minor=$(column contact_semi_minor max_abs "$csv")
  printf "%-14s %9.2f %8s %10.3f %10.3f %9.2f\n" "$core" "$ms" "$iou_min" "$(column contact_centre rms "$csv")" \
    "$(column contact_centre max_abs "$csv")" "$(awk -v a="$major" -v b="$minor" 'BEGIN { print (a > b ? a : b) }')" |
    tee -a "$out/placements.txt"
  i=$((i + 1))
done
awk 'NR > 1 { n += 1; s += $4 * $4; if ($5 > w) w = $5; if ($5 > 1) over += 1 }
     END { printf "all %d placements: centre RMS %.3f px, worst %.3f px; %d of them worse than 1 px somewhere\n",
                  n, sqrt(s / n), w, over }' "$out/placements.txt"
