#!/usr/bin/env bash
# Configures (once) and builds hlt in build/ (Release). Arguments name targets to build (default: all).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${HLT_BUILD_DIR:-build}
jobs=${HLT_JOBS:-$(nproc)}
if [ ! -f "$build_dir/build.ninja" ]; then
  cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=${HLT_BUILD_TYPE:-Release}
fi
if [ $# -gt 0 ]; then
  cmake --build "$build_dir" -j "$jobs" --target "$@"
else
  cmake --build "$build_dir" -j "$jobs"
fi
