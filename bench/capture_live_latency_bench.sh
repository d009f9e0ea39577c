#!/bin/sh
# Capture -> display latency of `tirstrain live --no-window` against a fake GigE Vision camera, per
# configuration (frame size, frame rate, analysis stages). All camera traffic stays in a private network
# namespace with only loopback. Needs root (unshare). Usage:
#   bench/capture_live_latency_bench.sh TIRSTRAIN_BINARY OUT_DIR [SECONDS]
# Environment: TIRSTRAIN_BENCH_CAMERA fast (default: tirstrain_fake_camera next to TIRSTRAIN_BINARY, serving
# pre-rendered TIR-like frames, or a synthesised trial's frames for the analysis rows) | aravis
# (arv-fake-gv-camera-0.8 and its ramp for every row).
# Camera settings come from scene files written into OUT_DIR (their camera: section), analysis stages from
# their compute list. Per configuration it prints frames received/shown/lost, the stages run, and the latency
# line of `live`: median / p95 / max from the frame's host receive time to the overlay being ready (headless:
# after the analysis stages drew), and from the camera's timestamp (Aravis' fake camera stamps a frame with
# the host's wall clock when it starts generating it) to the same point.
set -eu
. "$(dirname "$0")/loopback_netns.sh"
cli=$1; out=$2; seconds=${3:-10}
fake="$(dirname "$cli")/tirstrain_fake_camera"
mkdir -p "$out"
camera=
trap '[ -n "$camera" ] && kill $camera 2>/dev/null || true' EXIT

# A synthesised trial (samples/scenes/default.yaml: 640x512, a Cattaneo-Mindlin contact) for the analysis
# rows: the fake camera serves its frames, `live` analyses them with the trial's own scene.
trial="$out/trial"
if [ ! -f "$trial/scene.yaml" ]; then
  "$cli" synth --scene "$(dirname "$0")/../samples/scenes/default.yaml" --out "$trial" --quiet >"$out/synth.log" 2>&1
fi

# name | frames (tir: pre-rendered TIR-like frames, trial: the synthesised trial) | compute | roi | frame rate
configs="display-640x512-100Hz|tir|[]|[320, 256, 640, 512]|100
display-1280x1024-100Hz|tir|[]|[0, 0, 1280, 1024]|100
display-1280x1024-500Hz|tir|[]|[0, 0, 1280, 1024]|500
contact-640x512-30Hz|trial|[contact]|[0, 0, 640, 512]|30
contact-tracking-strain-640x512-30Hz|trial|[contact, tracking, strain]|[0, 0, 640, 512]|30"

echo "$configs" | while IFS='|' read -r name frames compute roi fps; do
  scene="$out/$name.yaml"
  if [ "$frames" = trial ]; then
    sed "s/^compute: .*/compute: $compute/" "$trial/scene.yaml" >"$scene"
    camera_cmd="$fake --images $trial/frames"
  else
    echo "compute: $compute" >"$scene"
    camera_cmd="$fake"
  fi
  [ "${TIRSTRAIN_BENCH_CAMERA:-fast}" = aravis ] && camera_cmd="arv-fake-gv-camera-0.8 -i 127.0.0.1"
  printf 'camera:\n  pixel_format: Mono8\n  roi_px: %s\n  frame_rate_hz: %s\n  packet_size_bytes: 16404\n' \
    "$roi" "$fps" >>"$scene"
  $camera_cmd >"$out/camera-$name.log" 2>&1 &
  camera=$!
  sleep 1
  "$cli" live aravis:127.0.0.1 --scene "$scene" --no-window --seconds "$seconds" >"$out/live-$name.log" 2>&1 || true
  kill "$camera" 2>/dev/null || true
  wait "$camera" 2>/dev/null || true
  camera=
  counts=$(grep -E '^live: [0-9]+ frames received' "$out/live-$name.log" || echo "live: (no summary; see $out/live-$name.log)")
  stages=$(grep '^live: analysis stages' "$out/live-$name.log" | sed 's/^live: analysis stages: //' || true)
  latency=$(grep '^live: latency' "$out/live-$name.log" | sed 's|^live: latency median / p95 / max: ||' || true)
  echo "$name: ${counts#live: }; stages: $stages"
  echo "    $latency"
done
