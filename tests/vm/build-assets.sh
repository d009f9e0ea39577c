#!/usr/bin/env bash
# Builds (once, then cached) what the VM harness boots: a busybox initramfs with the virtio/9p modules of the
# pinned Debian kernel, v4l2loopback built with kbuild against linux-headers-<abi> from the Debian
# v4l2loopback-dkms source, and vimc built out of tree from linux-source-<ver> (Debian's kernel does not build
# it). Usage: build-assets.sh CACHE_DIR. Prints nothing but errors on a cache hit. Exit 77 when a
# prerequisite is missing (scripts/install-deps installs them), so CTest reports a skip.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=vm.env
. "$here/vm.env"
abi=$TIRSTRAIN_VM_KERNEL_ABI
cache=${1:?usage: build-assets.sh CACHE_DIR}/$abi
mkdir -p "$cache"

missing=()
[ -r "/boot/vmlinuz-$abi" ] || missing+=("/boot/vmlinuz-$abi (linux-image-$abi)")
[ -d "/lib/modules/$abi/kernel" ] || missing+=("/lib/modules/$abi (linux-image-$abi)")
[ -d "/lib/modules/$abi/build" ] || missing+=("/lib/modules/$abi/build (linux-headers-$abi)")
[ -r "/usr/src/linux-source-$TIRSTRAIN_VM_KERNEL_SOURCE.tar.xz" ] ||
  missing+=("/usr/src/linux-source-$TIRSTRAIN_VM_KERNEL_SOURCE.tar.xz (linux-source-$TIRSTRAIN_VM_KERNEL_SOURCE)")
loopback_src=$(ls -d /usr/src/v4l2loopback-* 2>/dev/null | sort -V | tail -1 || true)
[ -n "$loopback_src" ] || missing+=("/usr/src/v4l2loopback-* (v4l2loopback-dkms)")
[ -x /bin/busybox ] || missing+=("/bin/busybox (busybox-static)")
command -v qemu-system-x86_64 >/dev/null || missing+=("qemu-system-x86_64 (qemu-system-x86)")
command -v cpio >/dev/null || missing+=("cpio")
if [ "${#missing[@]}" -gt 0 ]; then
  echo "VM prerequisites missing (run scripts/install-deps): ${missing[*]}" >&2
  exit 77
fi
if ldd /bin/busybox >/dev/null 2>&1; then
  echo "VM prerequisites missing: /bin/busybox is not static (install busybox-static)" >&2
  exit 77
fi

jobs=${TIRSTRAIN_VM_JOBS:-2}

# v4l2loopback, kbuild against the headers of the pinned kernel.
if [ ! -f "$cache/v4l2loopback.ko" ]; then
  rm -rf "$cache/v4l2loopback-src" && cp -r "$loopback_src" "$cache/v4l2loopback-src"
  make -s -C "/lib/modules/$abi/build" M="$cache/v4l2loopback-src" -j"$jobs" modules >"$cache/v4l2loopback.log" 2>&1 ||
    { cat "$cache/v4l2loopback.log" >&2; exit 1; }
  cp "$cache/v4l2loopback-src/v4l2loopback.ko" "$cache/v4l2loopback.ko"
fi

# vimc, out of tree from the kernel source of the same version.
if [ ! -f "$cache/vimc.ko" ]; then
  rm -rf "$cache/vimc-src" && mkdir -p "$cache/vimc-src"
  tar -xJf "/usr/src/linux-source-$TIRSTRAIN_VM_KERNEL_SOURCE.tar.xz" -C "$cache/vimc-src" --strip-components=5 \
    "linux-source-$TIRSTRAIN_VM_KERNEL_SOURCE/drivers/media/test-drivers/vimc"
  make -s -C "/lib/modules/$abi/build" M="$cache/vimc-src" CONFIG_VIDEO_VIMC=m -j"$jobs" modules \
    >"$cache/vimc.log" 2>&1 || { cat "$cache/vimc.log" >&2; exit 1; }
  cp "$cache/vimc-src/vimc.ko" "$cache/vimc.ko"
fi

# initramfs: busybox, the modules needed to mount the host over virtio-9p, and the init script.
init_src="$here/init.sh"
stamp="$(sha256sum "$init_src" "$here/host-paths.sh" "$here/vm.env" | sha256sum | cut -c1-16)"
if [ ! -f "$cache/initramfs.cpio.gz" ] || [ "$(cat "$cache/initramfs.stamp" 2>/dev/null)" != "$stamp" ]; then
  root="$cache/initramfs-root"
  rm -rf "$root" && mkdir -p "$root"/{bin,dev,proc,sys,host,modules,tmp}
  cp /bin/busybox "$root/bin/busybox"
  for m in virtio_pci 9pnet_virtio 9p; do
    /sbin/modprobe -S "$abi" --show-depends "$m" | awk '$1 == "insmod" {print $2}'
  done | awk '!seen[$0]++' >"$root/modules/order"
  while read -r ko; do cp "$ko" "$root/modules/"; done <"$root/modules/order"
  sed -i 's|.*/||' "$root/modules/order"
  cp "$init_src" "$root/init" && chmod +x "$root/init"
  cp "$here/host-paths.sh" "$root/host-paths.sh"
  (cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) >"$cache/initramfs.cpio.gz.tmp"
  mv "$cache/initramfs.cpio.gz.tmp" "$cache/initramfs.cpio.gz"
  echo "$stamp" >"$cache/initramfs.stamp"
fi
