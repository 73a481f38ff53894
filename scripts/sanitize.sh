#!/usr/bin/env bash
# Builds everything with AddressSanitizer and UndefinedBehaviorSanitizer into build-sanitize/ (or
# $HLT_BUILD_DIR) and runs the whole test suite under them, the bad-input catalogue (test_bad_inputs)
# included. Takes about twice as long as a normal build and test; not part of CI.
#   ./scripts/sanitize.sh [ctest arguments, e.g. -R test_util]
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
export HLT_BUILD_DIR=${HLT_BUILD_DIR:-build-sanitize} HLT_BUILD_TYPE=RelWithDebInfo
if [ ! -f "$HLT_BUILD_DIR/build.ninja" ]; then
  cmake -S . -B "$HLT_BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHLT_SANITIZE=address,undefined \
    -DHLT_BUILD_BENCH=OFF
fi
./scripts/build.sh
# LibTorch is not built with ASan: its own allocations are not checked, only ours. The leak inside
# OpenCV's libgphoto2 camera back-end (loaded by videoio) is not ours either: suppressed.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:detect_odr_violation=0
export LSAN_OPTIONS=suppressions=$PWD/scripts/sanitize.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cd "$HLT_BUILD_DIR"
# OpenCV's videoio loads libgphoto2 when it opens a capture; LSan attributes that library's start-up leak
# to it (and so suppresses it) only with complete allocation stacks, which the fast unwinder cannot walk
# through libgphoto2 and libusb. Complete stacks cost about 7x in time, so only test_perception (the one
# binary that opens captures) gets them, unless ctest arguments choose the tests: then all of those do.
slow=fast_unwind_on_malloc=0
if [ $# -gt 0 ]; then
  ASAN_OPTIONS=$ASAN_OPTIONS:$slow ctest --output-on-failure "$@"
else
  status=0
  ctest --output-on-failure -E '^test_perception$' || status=$?
  ASAN_OPTIONS=$ASAN_OPTIONS:$slow ctest --output-on-failure -R '^test_perception$' || status=$?
  exit $status
fi
