#!/usr/bin/env bash
# Installs the visco build tree into a temporary prefix, then configures, builds and runs a small consumer project
# that uses find_package(visco) and every exported visco::<library> target.
set -euo pipefail
build_dir="$1"; consumer_src="$2"; cxx="$3"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build_dir" --prefix "$work/prefix" >"$work/install.log"
targets=$(sed -n 's/^add_library(visco::\([a-z_]*\) .*/\1/p' "$work/prefix/lib/cmake/visco/viscoTargets.cmake" | sort | tr '\n' ' ')
echo "exported: $targets"
cmake -S "$consumer_src" -B "$work/consumer" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_CXX_COMPILER="$cxx" -DVISCO_TARGETS="$targets" >"$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/consumer" >"$work/build.log" || { cat "$work/build.log"; exit 1; }
"$work/consumer/consumer"
test -x "$work/prefix/bin/visco"
"$work/prefix/bin/visco" --version
test -f "$work/prefix/share/java/visco_lcmtypes.jar"
