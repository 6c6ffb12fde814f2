#!/usr/bin/env bash
# Installs what is missing, builds ricochet (Release) and runs the whole test suite.
# Extra arguments go to ctest, e.g. `tools/run_tests.sh -L unit` or `-LE slow`.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$here"
bash tools/install_deps.sh
build=${RICOCHET_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=${RICOCHET_BUILD_TYPE:-Release} >/dev/null
cmake --build "$build"
cd "$build"
ctest --output-on-failure --timeout 900 -j "$(nproc)" "$@"
