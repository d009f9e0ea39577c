# Sourced by the capture benchmarks: re-runs the calling script in a fresh network namespace with only the
# loopback interface up, and refuses to go on if any other interface is visible (the fake camera also
# answers and broadcasts on external interfaces, which a benchmark must never touch).
if [ "${TIRSTRAIN_BENCH_NETNS:-}" != 1 ]; then
  export TIRSTRAIN_BENCH_NETNS=1
  exec unshare -n sh -c 'PATH=$PATH:/usr/sbin:/sbin; ip link set lo up && exec "$0" "$@"' "$0" "$@"
fi
# /sys/class/net shows the namespace that mounted /sys, so ask the kernel through ip instead.
for ifc in $(ip -o link show | awk -F': ' '{print $2}'); do
  [ "$ifc" = lo ] || { echo "refusing: interface $ifc visible" >&2; exit 2; }
done
