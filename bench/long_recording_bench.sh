#!/usr/bin/env bash
# `tirstrain process` on a long recording: peak resident memory, time per frame, result.h5 size per frame, and
# the tracking error after the recording's length.
#
# The recording is a synthetic trial (default samples/scenes/paper_camera_1280.yaml: 1280x1024, ~2800 tracks)
# replayed back and forth to FRAMES frames (0, 1, ..., n-1, n-2, ..., 1, 0, 1, ...: symbolic links, so it
# costs no disk; synthesising 10 000 frames of that size takes hours). Every frame that replays frame 0 shows
# the skin exactly where it was at the start, so the error there is known exactly: the tracks' distance from
# their reference positions, after every round trip so far.
#
# Usage: bench/long_recording_bench.sh TIRSTRAIN WORK_DIR [FRAMES...]   (default FRAMES: 1000 10000)
#   SCENE=path/to/scene.yaml to replay another scene's trial.
set -euo pipefail
tirstrain=$(realpath "$1")
work=$2
shift 2
if [ $# -gt 0 ]; then lengths=("$@"); else lengths=(1000 10000); fi
root=$(cd "$(dirname "$0")/.." && pwd)
scene=${SCENE:-$root/samples/scenes/paper_camera_1280.yaml}
mkdir -p "$work"
[ -d "$work/source" ] || "$tirstrain" synth --scene "$scene" --out "$work/source" --quiet

make_replay() {  # DIR FRAMES
  local dir=$1 frames=$2
  rm -rf "$dir" && mkdir -p "$dir/frames"
  cp "$work/source/scene.yaml" "$dir/scene.yaml"
  /usr/bin/python3 - "$work/source" "$dir" "$frames" <<'EOF'
import csv, os, sys
source, out, frames = sys.argv[1], sys.argv[2], int(sys.argv[3])
times = [float(r["t_s"]) for r in csv.DictReader(open(os.path.join(source, "frames.csv")))]
n = len(times)
order = list(range(n)) + list(range(n - 2, 0, -1))
step = times[1] - times[0]
with open(os.path.join(out, "frames.csv"), "w") as f:
    f.write("index,t_s\n")
    for i in range(frames):
        k = order[i % len(order)]
        os.symlink(os.path.join(os.path.abspath(source), "frames", "%06d.png" % k),
                   os.path.join(out, "frames", "%06d.png" % i))
        f.write("%d,%.9f\n" % (i, i * step))
EOF
}

# RMS over the tracks alive at the frames that replay frame 0 (after the first) of position - reference, px;
# and the same at the last such frame.
replay_error() {  # RESULT_H5 SOURCE_FRAMES
  /usr/bin/python3 - "$1" "$2" <<'EOF'
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
n = int(sys.argv[2]); period = 2 * n - 2
pos = f["/tracks/position_px"]; ref = f["/tracks/reference_px"][...]
frames = list(range(period, pos.shape[0], period))
rms = []
for k in frames:
    d = pos[k, :, :] - ref
    d = d[np.isfinite(d).all(axis=1)]
    rms.append(np.sqrt(np.mean(np.sum(d * d, axis=1))) if len(d) else np.nan)
print("%.4f %.4f %d" % (np.sqrt(np.nanmean(np.square(rms))), rms[-1], len(frames)))
EOF
}

source_frames=$(($(wc -l < "$work/source/frames.csv") - 1))
echo "source trial: $scene, $source_frames frames, replayed back and forth; $(nproc) cores"
printf "%8s %10s %12s %12s %14s %18s %18s\n" frames wall_s ms_per_frame peak_RSS_MB h5_kB_per_frame \
  "err_rms_px(all)" "err_rms_px(last)"
for frames in "${lengths[@]}"; do
  dir="$work/replay_$frames"
  make_replay "$dir" "$frames"
  rm -rf "$work/out_$frames"
  /usr/bin/time -f "%e %M" -o "$work/time_$frames" \
    "$tirstrain" process "$dir" --scene "$dir/scene.yaml" --out "$work/out_$frames" --overlay none --quiet
  read -r wall rss_kB < "$work/time_$frames"
  size=$(stat -c %s "$work/out_$frames/result.h5")
  read -r err_all err_last rounds < <(replay_error "$work/out_$frames/result.h5" "$source_frames")
  printf "%8d %10.1f %12.2f %12.0f %14.1f %18s %18s\n" "$frames" "$wall" "$(echo "1000 * $wall / $frames" | bc -l)" \
    "$(echo "$rss_kB / 1024" | bc -l)" "$(echo "$size / 1024 / $frames" | bc -l)" "$err_all" "$err_last"
  rm -rf "$dir"
done
