# Sourced by the VM's init (tests/vm/init.sh) and by its unit test (CMakeLists.txt: vm.host_paths).
# shadowed_paths ROOTS PATH...: prints, one per line, each PATH that lies under one of ROOTS (a
# space-separated list of the folders the guest mounts its own tmpfs on), so that init can bind it back from
# an unshadowed view of the host root: a build folder in the host's /tmp is otherwise hidden in the guest.
shadowed_paths() {
  roots=$1
  shift
  for p in "$@"; do
    for r in $roots; do
      case "$p/" in
        "$r"/*)
          echo "$p"
          break
          ;;
      esac
    done
  done
}
