#!/bin/sh
# Synthesises tiny trials for the study tests: make_trials.sh TIRSTRAIN DIR NORMAL_N... writes
# DIR/load_<N>/ (tirstrain synth: 160x128 px, 8 frames, Hertz contact at N newtons, channels) per load.
set -eu
tirstrain=$1
dir=$2
shift 2
mkdir -p "$dir"
for load in "$@"; do
  cat > "$dir/scene_$load.yaml" <<SCENE
calibration: {px_per_mm: 16, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
reference_pattern: {detect: false}
compute: [contact, tracking, strain]
synthesis:
  seed: 3
  image: {width_px: 160, height_px: 128, bit_depth: 8}
  timing: {frames: 8, frame_rate_hz: 100, jitter_s: 0.0}
  contact: {shape: hertz, normal_N: $load, radius_m: 0.02}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 5.0, shear_start_s: 0.02}
  truth: {grid_step_px: 8}
SCENE
  "$tirstrain" synth --scene "$dir/scene_$load.yaml" --out "$dir/load_$load" --quiet
done
