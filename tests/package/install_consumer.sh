#!/usr/bin/env bash
# Installs the build tree into a fresh prefix, builds tests/package/consumer against it with
# find_package(tirstrain) and runs it, then imports the installed Python module from the prefix.
# Usage: install_consumer.sh BUILD_DIR WORK_DIR GENERATOR CXX_COMPILER [PYTHON]
set -euo pipefail
build=$1 work=$2 generator=$3 cxx=$4 python=${5:-}
here=$(cd "$(dirname "$0")" && pwd)
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" > "$work/install.log"
for f in lib/cmake/tirstrain/tirstrainConfig.cmake lib/cmake/tirstrain/tirstrainConfigVersion.cmake \
         lib/libtirstrain_pipeline.a include/tirstrain/core/version.hpp include/tirstrain/model/cattaneo_mindlin.hpp \
         bin/tirstrain; do
  [ -e "$prefix/$f" ] || { echo "install: $f missing under $prefix"; exit 1; }
done
cmake -S "$here/consumer" -B "$work/consumer" -G "$generator" -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" > "$work/configure.log" ||
  { cat "$work/configure.log"; exit 1; }
cmake --build "$work/consumer" > "$work/build.log" || { cat "$work/build.log"; exit 1; }
"$work/consumer/consumer"
"$work/consumer/consumer_pipeline"
# A component that is not one of the libraries is refused by its name.
mkdir -p "$work/unknown"
printf 'cmake_minimum_required(VERSION 3.22)\nproject(u LANGUAGES CXX)\nfind_package(tirstrain 0.1 REQUIRED CONFIG COMPONENTS flow nosuchlib)\n' \
  > "$work/unknown/CMakeLists.txt"
if cmake -S "$work/unknown" -B "$work/unknown/build" -DCMAKE_PREFIX_PATH="$prefix" > "$work/unknown.log" 2>&1; then
  echo "find_package accepted an unknown component"; exit 1
fi
grep -q "nosuchlib" "$work/unknown.log" || { cat "$work/unknown.log"; exit 1; }
if [ -n "$python" ]; then
  # A sanitizer build's module needs the ASan runtime loaded into the (uninstrumented) interpreter first.
  PYTHONPATH=$(echo "$prefix"/lib/python3*/dist-packages) LD_PRELOAD="${TIRSTRAIN_PYTHON_PRELOAD:-}" \
    ASAN_OPTIONS=detect_leaks=0 "$python" -c "
import sys, tirstrain
assert tirstrain.__file__.startswith(sys.argv[1]), tirstrain.__file__
print('python: imported', tirstrain.__file__, tirstrain.__version__)" "$prefix"
fi
