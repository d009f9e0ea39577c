#!/bin/sh
# Runs inside the test VM, chrooted into the host's root (read-only) with SHARE writable. Loads the media
# drivers, starts udevd for libcamera, runs capture_vm_test and leaves its results in SHARE.
share=$1
. "$share/vm-test.env"
log() { echo "vm-guest: $*"; }
t0=$(cut -d' ' -f1 /proc/uptime)

# vivid: two instances with only a video capture node each (the second one is disconnected by a test).
modprobe vivid n_devs=2 node_types=0x1,0x1 || log "modprobe vivid failed"
# Out-of-tree modules built by build-assets.sh: their in-kernel dependencies first.
for ko in "$CACHE/vimc.ko" "$CACHE/v4l2loopback.ko"; do
  deps=$(modinfo -F depends "$ko" | tr ',' ' ')
  # shellcheck disable=SC2086 # a list of module names
  [ -n "$deps" ] && modprobe -a $deps
done
insmod "$CACHE/v4l2loopback.ko" video_nr=20 card_label=tirstrain-loopback exclusive_caps=0 max_buffers=4 ||
  log "insmod v4l2loopback failed"
insmod "$CACHE/vimc.ko" || log "insmod vimc failed"
log "modules loaded after $(cut -d' ' -f1 /proc/uptime) s"

# libcamera enumerates media devices through udev.
export SYSTEMD_IGNORE_CHROOT=1
/lib/systemd/systemd-udevd --daemon >/dev/null 2>&1 || log "systemd-udevd did not start"
udevadm trigger --action=add --subsystem-match=media --subsystem-match=video4linux >/dev/null 2>&1
udevadm settle --timeout=30 || log "udevadm settle timed out"
log "drivers loaded after $(cut -d' ' -f1 /proc/uptime) s (started at $t0 s): $(ls /dev/video* /dev/media* 2>/dev/null | tr '\n' ' ')"
cam -l >"$share/cam-l.txt" 2>&1 || true
log "cam -l: $(grep -v '^\[' "$share/cam-l.txt" | tr '\n' ' ')"

export TIRSTRAIN_VM_TRIAL="$share/trial" TIRSTRAIN_VM_OUT="$share/out" TIRSTRAIN_VM_LOOPBACK=/dev/video20
mkdir -p "$share/out"
log "starting capture_vm_test after $(cut -d' ' -f1 /proc/uptime) s"
"$TEST_BINARY" --gtest_filter=-VimcUnplug.* --gtest_output=xml:"$share/results.xml" >"$share/gtest.log" 2>&1
rc=$?
echo "$rc" >"$share/exit-code"
log "capture_vm_test exited with $rc after $(cut -d' ' -f1 /proc/uptime) s"
# Unplugging vimc is destructive (and libcamera may abort): its own process, last.
"$TEST_BINARY" --gtest_filter=VimcUnplug.* --gtest_output=xml:"$share/results-unplug.xml" >>"$share/gtest.log" 2>&1
rc_unplug=$?
echo "$rc_unplug" >"$share/exit-code-unplug"
log "capture_vm_test (unplug) exited with $rc_unplug after $(cut -d' ' -f1 /proc/uptime) s"
udevadm control --exit >/dev/null 2>&1 || true
exit "$rc"
