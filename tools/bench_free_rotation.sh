#!/usr/bin/env bash
# Times the exact free-rotation propagator (ns per call over 1e6 calls) against the
# Release core library: bash tools/bench_free_rotation.sh [build-dir, default build-rel]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build-rel}
if [ ! -f "$build/src/libricochet_core.a" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j2 --target ricochet_core
out=$(mktemp -d)
gfortran -O3 -funroll-loops -ffree-line-length-none -std=f2018 -I"$build/modules" -J"$out" \
  "$root/tools/bench/bench_free_rotation.f90" "$build/src/libricochet_core.a" -o "$out/bench_free_rotation"
"$out/bench_free_rotation"
rm -rf "$out"
