#!/bin/sh
# Sustained record rate from a fake GigE Vision camera at 1280x1024 Mono8 into a folder, per image format.
# All camera traffic stays in a private network namespace with only loopback (never run a fake camera on the
# host network). Needs root (unshare). Usage:
#   bench/capture_record_bench.sh TIRSTRAIN_BINARY OUT_DIR [FPS] [SECONDS] [FORMATS...]
# Environment:
#   TIRSTRAIN_BENCH_CAMERA  fast (default): tirstrain_fake_camera next to TIRSTRAIN_BINARY (Aravis'
#                           ArvGvFakeCamera serving pre-rendered frames by memcpy);
#                           aravis: arv-fake-gv-camera-0.8 (renders every pixel; ~180 frames/s at most here)
#   TIRSTRAIN_BENCH_WRITERS writer threads (default 2); TIRSTRAIN_BENCH_PACKET packet size (default 16404)
#   TIRSTRAIN_BENCH_ROI     X,Y,W,H (default 0,0,1280,1024)
#   TIRSTRAIN_BENCH_CAMERA_PRIO  how to run the camera process: "" (default, normal priority), "nice" (nice -10) or
#                           "fifo" (chrt -f 10): the fake camera stands in for separate hardware, and on a busy
#                           2-core host it misses its frame slots when other work preempts it
# OUT_DIR on a tmpfs (/dev/shm/...) takes the disk out of the measurement. Prints one line per format:
# frames received/saved/incomplete/lost/dropped, frames/s and MB/s saved, CPU seconds used by the camera
# process and by the recorder; the frames are deleted after each run (recording.json and frames.csv stay).
set -eu
. "$(dirname "$0")/loopback_netns.sh"
cli=$1; out=$2; fps=${3:-500}; seconds=${4:-10}; shift 2; [ $# -gt 0 ] && shift; [ $# -gt 0 ] && shift
formats=${*:-"pgm tiff png"}
kind=${TIRSTRAIN_BENCH_CAMERA:-fast}
writers=${TIRSTRAIN_BENCH_WRITERS:-2}
roi=${TIRSTRAIN_BENCH_ROI:-0,0,1280,1024}
pixels=$(echo "$roi" | awk -F, '{ print $3 * $4 }')
case $kind in
  fast) camera_cmd="$(dirname "$cli")/tirstrain_fake_camera" ;;
  aravis) camera_cmd="arv-fake-gv-camera-0.8 -i 127.0.0.1" ;;
  *) echo "TIRSTRAIN_BENCH_CAMERA must be fast or aravis" >&2; exit 2 ;;
esac
case ${TIRSTRAIN_BENCH_CAMERA_PRIO:-} in
  "") prio= ;;
  nice) prio="nice -n -10" ;;
  fifo) prio="chrt -f 10" ;;
  *) echo "TIRSTRAIN_BENCH_CAMERA_PRIO must be empty, nice or fifo" >&2; exit 2 ;;
esac
mkdir -p "$out"
camera=
trap '[ -n "$camera" ] && kill $camera 2>/dev/null || true' EXIT
cpu_s() {  # user+system CPU seconds of a process (and its waited-for children)
  awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' "/proc/$1/stat"
}
echo "camera: $kind ($prio $camera_cmd), $roi Mono8, $fps fps requested, $seconds s, $writers writers, out $out"
for format in $formats; do
  rm -rf "$out/rec-$format"
  $prio $camera_cmd >"$out/camera-$format.log" 2>&1 &
  camera=$!
  sleep 1
  /usr/bin/time -f "%U %S" -o "$out/record-$format.time" \
    "$cli" record aravis:127.0.0.1 --out "$out/rec-$format" --roi "$roi" --pixel-format Mono8 --fps "$fps" \
    --seconds "$seconds" --format "$format" --writers "$writers" --packet-size "${TIRSTRAIN_BENCH_PACKET:-16404}" \
    --quiet >"$out/record-$format.log" 2>&1 || true
  camera_cpu=$(cpu_s "$camera")
  kill "$camera" 2>/dev/null || true
  wait "$camera" 2>/dev/null || true
  camera=
  json="$out/rec-$format/recording.json"
  if [ ! -f "$json" ]; then
    echo "$format: no recording.json; see $out/record-$format.log" >&2
    cat "$out/record-$format.log" >&2
    continue
  fi
  get() { sed -n "s/.*\"$1\": \\([0-9.e+-]*\\).*/\\1/p" "$json"; }
  received=$(get frames_received); saved=$(get frames_saved); lost=$(get frames_lost_device)
  incomplete=$(get frames_incomplete); dropped=$(get frames_dropped_host); bytes=$(get bytes_written)
  elapsed=$(get elapsed_s); maxq=$(get max_queue_frames)
  record_cpu=$(awk '{ print $1 + $2 }' "$out/record-$format.time")
  awk -v f="$format" -v fps="$fps" -v r="$received" -v s="$saved" -v l="$lost" -v i="$incomplete" -v d="$dropped" \
      -v b="$bytes" -v e="$elapsed" -v q="$maxq" -v px="$pixels" -v cc="$camera_cpu" -v rc="$record_cpu" 'BEGIN {
    printf "%-5s %4d fps asked: received %6d saved %6d incomplete %4d lost(device) %5d dropped(host) %5d max queue %4d -> %6.1f frames/s, %6.1f MB/s written (raw %6.1f MB/s); CPU s: camera %.1f, recorder %.1f (of %.1f s x 2 cores)\n",
      f, fps, r, s, i, l, d, q, s / e, b / e / 1e6, s * px / e / 1e6, cc, rc, e }'
  rm -rf "$out/rec-$format/frames"
done
