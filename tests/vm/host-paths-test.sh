#!/bin/sh
# Unit test of host-paths.sh (CTest vm.host_paths): which host folders the guest's init binds back.
set -eu
. "$(dirname "$0")/host-paths.sh"
out=$(shadowed_paths "/tmp /run /dev/shm" /tmp/build/bin /home/u/build /run/user/1/cache /tmpx /dev/shm/a | tr '\n' ' ')
expected="/tmp/build/bin /run/user/1/cache /dev/shm/a "
if [ "$out" != "$expected" ]; then
  echo "host-paths: got '$out', expected '$expected'" >&2
  exit 1
fi
echo "host-paths: $out"
