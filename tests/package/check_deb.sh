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
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainConfig\.cmake$'
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainConfigVersion\.cmake$'
expect "$dev" contents ' \./usr/lib/cmake/tirstrain/tirstrainTargets\.cmake$'
expect "$dev" contents ' \./usr/lib/libtirstrain_(core|model|contact|flow|strain|signals|capture|pipeline)\.a$'
expect "$dev" contents ' \./usr/include/tirstrain/flow/tracker\.hpp$'
expect "$dev" info '^ Depends: .*libopencv-dev.*libceres-dev'
if [ "$with_python" = 1 ]; then
  expect "$py" contents ' \./usr/lib/python3\.[0-9]+/dist-packages/tirstrain\.cpython-[0-9]+-[a-z0-9_]+-linux-gnu\.so$'
  expect "$py" info '^ Depends: .*python3-numpy'
fi
for lib in core model contact flow strain signals capture pipeline; do
  expect "$dev" contents " \./usr/lib/libtirstrain_$lib\.a\$"
done
# Every shared library the CLI and the module need must come from a package their Depends name: the
# NEEDED entries resolved by ldconfig, their owners asked of dpkg in one query (usrmerge: dpkg may know a
# library under /lib or under /usr/lib). needs DEB FILE: checks FILE inside DEB.
needs() {
  local deb=$work/$1 file=$2 root=$work/extracted_${1%.deb} depends owners so path owner
  dpkg-deb -x "$deb" "$root"
  depends=$(dpkg-deb -f "$deb" Depends | tr ',|' '\n\n' | sed 's/(.*//; s/ //g')
  local paths=()
  for so in $(readelf -d "$root/$file" | sed -n 's/.*Shared library: \[\(.*\)\]/\1/p'); do
    path=$(ldconfig -p | awk -v s="$so" '$1 == s && /x86-64/ && !found {print $NF; found = 1}')
    [ -n "$path" ] || { echo "$1: $so is not on this system"; fail=1; continue; }
    paths+=("$(readlink -f "$path")")
  done
  owners=$(dpkg-query -S "${paths[@]}" "${paths[@]#/usr}" 2>/dev/null || true)
  for path in "${paths[@]}"; do
    owner=$(awk -F': ' -v a="$path" -v b="${path#/usr}" '($2 == a || $2 == b) && !f {sub(/[:,].*/, "", $1); print $1; f = 1}' <<< "$owners")
    if [ -z "$owner" ]; then
      echo "$1: no package owns $path (for $file)"
      fail=1
    elif ! grep -qx -- "$owner" <<< "$depends"; then
      echo "$1: Depends lacks $owner (for $path, needed by $file)"
      fail=1
    fi
  done
}
needs "$cli" usr/bin/tirstrain
if [ "$with_python" = 1 ]; then
  needs "$py" "$(dpkg-deb -c "$work/$py" | sed -n 's|.* \./\(usr/lib/python3.*\.so\)$|\1|p')"
fi
[ "$fail" = 0 ] && echo "check_deb: $(ls "$work"/*.deb | wc -l) packages checked"
exit $fail
