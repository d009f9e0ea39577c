#!/bin/sh
# Sustained record rate from arv-fake-gv-camera-0.8 at 1280x1024 Mono8 into a folder, per image format.
# All camera traffic stays in a private network namespace with only loopback (never run the fake camera on
# the host network). Needs root (unshare). Usage:
#   bench/capture_record_bench.sh TIRSTRAIN_BINARY OUT_DIR [FPS] [SECONDS] [FORMATS...]
# Prints one line per format: fps requested, frames received/saved/lost/dropped, frames/s and MB/s saved.
set -eu
if [ "${TIRSTRAIN_BENCH_NETNS:-}" != 1 ]; then
  export TIRSTRAIN_BENCH_NETNS=1
  exec unshare -n sh -c 'PATH=$PATH:/usr/sbin:/sbin; ip link set lo up && exec "$0" "$@"' "$0" "$@"
fi
# /sys/class/net shows the namespace that mounted /sys, so ask the kernel through ip instead.
for ifc in $(ip -o link show | awk -F': ' '{print $2}'); do
  [ "$ifc" = lo ] || { echo "refusing: interface $ifc visible" >&2; exit 2; }
done
cli=$1; out=$2; fps=${3:-500}; seconds=${4:-10}; shift 2; [ $# -gt 0 ] && shift; [ $# -gt 0 ] && shift
formats=${*:-"pgm tiff png"}
mkdir -p "$out"
arv-fake-gv-camera-0.8 -i 127.0.0.1 >"$out/camera.log" 2>&1 &
camera=$!
trap 'kill $camera 2>/dev/null || true' EXIT
sleep 1
for format in $formats; do
  rm -rf "$out/rec-$format"
  "$cli" record aravis:127.0.0.1 --out "$out/rec-$format" --roi 0,0,1280,1024 --pixel-format Mono8 --fps "$fps" \
    --seconds "$seconds" --format "$format" --packet-size "${TIRSTRAIN_BENCH_PACKET:-16404}" --quiet >"$out/record-$format.log" 2>&1 || true
  json="$out/rec-$format/recording.json"
  get() { sed -n "s/.*\"$1\": \\([0-9.e+-]*\\).*/\\1/p" "$json"; }
  received=$(get frames_received); saved=$(get frames_saved); lost=$(get frames_lost_device)
  incomplete=$(get frames_incomplete); dropped=$(get frames_dropped_host); bytes=$(get bytes_written)
  elapsed=$(get elapsed_s)
  awk -v f="$format" -v fps="$fps" -v r="$received" -v s="$saved" -v l="$lost" -v i="$incomplete" -v d="$dropped" \
      -v b="$bytes" -v e="$elapsed" 'BEGIN {
    printf "%-5s requested %4d fps: received %6d  saved %6d  incomplete %4d  lost(device) %5d  dropped(host) %5d  -> %6.1f frames/s saved, %6.1f MB/s (raw %6.1f MB/s)\n",
      f, fps, r, s, i, l, d, s / e, b / e / 1e6, s * 1280 * 1024 / e / 1e6 }'
  rm -rf "$out/rec-$format/frames"
done
