#!/usr/bin/env bash
# Builds the Debian packages with cpack and checks their contents (dpkg-deb -c) and metadata (dpkg-deb -I).
# Usage: check_deb.sh BUILD_DIR WORK_DIR WITH_PYTHON(0|1)
set -euo pipefail
build=$1 work=$2 with_python=$3
rm -rf "$work"
mkdir -p "$work"
cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work" > "$work/cpack.log" || { cat "$work/cpack.log"; exit 1; }
fail=0
# expect DEB WHAT PATTERN: the listing or the metadata of DEB must match PATTERN (extended regex).
expect() {
  local deb=$work/$1 what=$2 pattern=$3 text
  if [ "$what" = contents ]; then text=$(dpkg-deb -c "$deb"); else text=$(dpkg-deb -I "$deb"); fi
  if ! grep -Eq -- "$pattern" <<< "$text"; then
    echo "$1: $what lacks /$pattern/"
    fail=1
  fi
}
version=$(sed -n 's/^set(CPACK_PACKAGE_VERSION "\(.*\)")$/\1/p' "$build/CPackConfig.cmake")
cli=tirstrain_${version}_amd64.deb dev=tirstrain-dev_${version}_amd64.deb py=python3-tirstrain_${version}_amd64.deb
expect "$cli" contents ' \./usr/bin/tirstrain$'
expect "$cli" info '^ Package: tirstrain$'
expect "$cli" info "^ Version: $version\$"
expect "$cli" info '^ Depends: .*libopencv-core[0-9.a-z]* \(>= '
expect "$cli" info '^ Depends: .*libhdf5-103'
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainConfig\.cmake$'
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainConfigVersion\.cmake$'
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainTargets\.cmake$'
expect "$dev" contents ' \./usr/lib/libtirstrain_(core|model|contact|flow|strain|signals|capture|pipeline)\.a$'
expect "$dev" contents ' \./usr/include/tirstrain/flow/tracker\.hpp$'
expect "$dev" info '^ Depends: .*libopencv-dev.*libceres-dev'
if [ "$with_python" = 1 ]; then
  expect "$py" contents ' \./usr/lib/python3/dist-packages/tirstrain\.cpython-[0-9]+-[a-z0-9_]+-linux-gnu\.so$'
  expect "$py" info '^ Depends: .*python3-numpy'
fi
for lib in core model contact flow strain signals capture pipeline; do
  expect "$dev" contents " \./usr/lib/libtirstrain_$lib\.a\$"
done
[ "$fail" = 0 ] && echo "check_deb: $(ls "$work"/*.deb | wc -l) packages checked"
exit $fail
