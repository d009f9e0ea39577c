#!/usr/bin/env bash
# CTest fixture `vm.run`: renders a synthetic trial on the host, boots the test VM once and runs the
# capture_vm_test binary (built on the host) inside it against vivid, v4l2loopback and vimc.
# Usage: ctest-vm.sh CACHE_DIR SHARE_DIR TEST_BINARY TIRSTRAIN_CLI
# Exit 77 (a CTest skip) when the VM prerequisites are missing; the vm.<case> tests then skip as well.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=$1 share=$2 test_binary=$3 cli=$4
rm -rf "$share" && mkdir -p "$share"

assets_log=$share/assets.log
status=0
"$here/build-assets.sh" "$cache" 2>"$assets_log" || status=$?
if [ "$status" -ne 0 ]; then
  cat "$assets_log" >&2
  if [ "$status" -eq 77 ]; then
    { echo -n "VM prerequisites missing: "; cat "$assets_log"; } >"$share/skipped.txt"
    echo "vm.run: skipped: $(cat "$assets_log")"
    exit 77
  fi
  exit "$status"
fi

# The trial v4l2loopback replays (rendered here: the VM emulates its CPU and would take far longer).
"$cli" synth --scene "$here/../../samples/scenes/default.yaml" --out "$share/trial" --quiet >"$share/synth.log" 2>&1 ||
  { cat "$share/synth.log" >&2; exit 1; }

. "$here/vm.env"
cat >"$share/vm-test.env" <<ENV
TEST_BINARY=$test_binary
CACHE=$cache/$TIRSTRAIN_VM_KERNEL_ABI
HOST_PATHS=$(dirname "$test_binary"):$(dirname "$cli"):$cache:$(cd "$here/../.." && pwd)
ENV

"$here/run-vm.sh" "$cache" "$share" "$here/guest-run.sh" "${TIRSTRAIN_VM_TIMEOUT_S:-600}"
grep -E "^vm-(init|guest):" "$share/console.log" || true
echo "---- capture_vm_test inside the VM ----"
cat "$share/gtest.log" 2>/dev/null || echo "(no gtest output: see $share/console.log)"
if [ ! -s "$share/results.xml" ]; then
  echo "vm.run: the guest wrote no results.xml; console:" >&2
  tail -n 60 "$share/console.log" >&2
  exit 1
fi
# Failing tests are reported by their own vm.<Suite>.<Test> entries; a non-zero exit with every test passed
# means the binary failed after them (a sanitizer's leak report, a crash at exit): that fails here.
for run in "" -unplug; do
  rc=$(cat "$share/exit-code$run" 2>/dev/null || echo '?')
  echo "vm.run: guest test run${run:- main} exit code $rc (per-test results: vm.<Suite>.<Test>)"
  if [ "$rc" != 0 ] && ! grep -qs "<failure" "$share/results$run.xml"; then
    echo "vm.run: capture_vm_test${run} exited with $rc and no test failure explains it (see above)" >&2
    exit 1
  fi
done
