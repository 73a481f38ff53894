#!/usr/bin/env bash
# The README's test command: install what is missing, build, run every test with ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
./scripts/build.sh
cd "${HLT_BUILD_DIR:-build}"
ctest --output-on-failure "$@"
