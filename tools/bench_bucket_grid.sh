#!/usr/bin/env bash
# Broad-phase benchmark: builds the Release core, compiles tools/bench/bench_bucket_grid.f90 against
# it and runs it (10^3..10^6 bodies; pass "quick" to stop at 10^5). Output: docs/broad_phase.md.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${RICOCHET_BUILD_DIR:-$root/build-rel}
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j2 --target ricochet_core >/dev/null
gfortran -O3 -funroll-loops -ffree-line-length-none -I "$build/modules" \
  "$root/tools/bench/bench_bucket_grid.f90" "$build/src/libricochet_core.a" -o "$build/bench_bucket_grid"
"$build/bench_bucket_grid" "$@"
