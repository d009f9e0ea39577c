#!/usr/bin/env bash
# Boots the pinned Debian kernel under qemu (TCG: no KVM needed) with the host root read-only over 9p and
# SHARE_DIR writable at its own path, and runs GUEST_SCRIPT (a host path) chrooted into the host root.
# Usage: run-vm.sh CACHE_DIR SHARE_DIR GUEST_SCRIPT [TIMEOUT_S]
# The console goes to SHARE_DIR/console.log. Exit code: 77 if prerequisites are missing, 1 if the VM did not
# finish in time, otherwise 0 (the guest's own result is in SHARE_DIR, written by GUEST_SCRIPT).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=vm.env
. "$here/vm.env"
abi=$TIRSTRAIN_VM_KERNEL_ABI
cache_root=${1:?usage: run-vm.sh CACHE_DIR SHARE_DIR GUEST_SCRIPT [TIMEOUT_S]}
share=$(realpath "${2:?share dir}")
guest_script=$(realpath "${3:?guest script}")
timeout_s=${4:-600}
"$here/build-assets.sh" "$cache_root"
cache=$cache_root/$abi
mkdir -p "$share"
# Host folders the guest run reads (ctest-vm.sh lists them in the share's vm-test.env; init.sh binds back
# those that lie under the guest's own /tmp, /run or /dev/shm).
host_paths=$(sed -n 's/^HOST_PATHS=//p' "$share/vm-test.env" 2>/dev/null || true)
host_paths="$host_paths:$(dirname "$guest_script")"
case "$share$guest_script$host_paths" in *" "*)
  echo "run-vm.sh: paths with spaces cannot go on the kernel command line: $share $guest_script $host_paths" >&2
  exit 2 ;;
esac

start=$(date +%s.%N)
status=0
timeout --kill-after=10 "$timeout_s" qemu-system-x86_64 -accel tcg -machine q35 -cpu max -smp "${TIRSTRAIN_VM_CPUS:-2}" \
  -m "${TIRSTRAIN_VM_MEM_MB:-1536}" -nographic -no-reboot -nic none \
  -kernel "/boot/vmlinuz-$abi" -initrd "$cache/initramfs.cpio.gz" \
  -append "console=ttyS0 quiet loglevel=4 panic=-1 TIRSTRAIN_SHARE=$share TIRSTRAIN_RUN=$guest_script TIRSTRAIN_HOST_PATHS=$host_paths" \
  -virtfs local,path=/,mount_tag=hostroot,readonly=on,security_model=none,multidevs=remap \
  -virtfs "local,path=$share,mount_tag=share,security_model=none" \
  </dev/null >"$share/console.log" 2>&1 || status=$?
end=$(date +%s.%N)
awk -v a="$start" -v b="$end" -v s="$status" 'BEGIN { printf "run-vm.sh: VM ran %.1f s (qemu exit %d)\n", b - a, s }'
if [ "$status" -ne 0 ]; then
  echo "run-vm.sh: qemu failed or timed out after ${timeout_s}s; console:" >&2
  tail -n 40 "$share/console.log" >&2
  exit 1
fi
