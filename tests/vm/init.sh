#!/bin/busybox sh
# PID 1 of the test VM (tests/vm/run-vm.sh). Mounts the host's root read-only over virtio-9p at /host, the
# writable share at the same path it has on the host, and runs TIRSTRAIN_RUN (a script on the host) chrooted
# into the host root with the share path as its argument. Kernel parameters without a dot arrive here as
# environment variables: TIRSTRAIN_SHARE, TIRSTRAIN_RUN, TIRSTRAIN_HOST_PATHS (colon-separated host folders
# the run reads: the test binary's, the CLI's, the asset cache, the sources).
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $(cat /modules/order); do insmod "/modules/$m" || echo "vm-init: insmod $m failed"; done
opts=trans=virtio,version=9p2000.L,msize=262144
if ! mount -t 9p -o "$opts,ro,cache=loose" hostroot /host; then
  echo "vm-init: could not mount the host root over 9p"
  poweroff -f
fi
# An unshadowed view of the host root, taken before the guest's own /tmp, /run and /dev/shm hide the host's.
mkdir -p /hostview && mount --bind /host /hostview
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
mount -t devtmpfs dev /host/dev
mkdir -p /host/dev/shm /host/dev/pts 2>/dev/null
mount -t tmpfs shm /host/dev/shm
mount -t tmpfs tmp /host/tmp
mount -t tmpfs run /host/run
# Host folders the run needs that those tmpfs mounts hide (a build folder under the host's /tmp) are bound
# back read-only, and the share is mounted last so that nothing is mounted over it.
. /host-paths.sh
for p in $(shadowed_paths "/tmp /run /dev/shm" $(echo "$TIRSTRAIN_HOST_PATHS" | tr ':' ' ')); do
  mkdir -p "/host$p" && mount --bind "/hostview$p" "/host$p" || echo "vm-init: could not bind $p"
done
mkdir -p "/host$TIRSTRAIN_SHARE" 2>/dev/null
mount -t 9p -o "$opts,cache=none" share "/host$TIRSTRAIN_SHARE" || echo "vm-init: could not mount the share"
echo "vm-init: up after $(cut -d' ' -f1 /proc/uptime) s"
chroot /host /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/tmp /bin/sh "$TIRSTRAIN_RUN" "$TIRSTRAIN_SHARE"
echo "vm-init: guest script exited with $? after $(cut -d' ' -f1 /proc/uptime) s"
sync
poweroff -f
