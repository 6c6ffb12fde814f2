#!/usr/bin/env bash
# Installs what is missing, builds ricochet (Release) and runs the demo deck.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$here"
bash tools/install_deps.sh
build=${RICOCHET_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build"
deck=${1:-input/demo.nml}
"$build/app/ricochet" "$deck"
out=$(realpath -m "$("$build/app/ricochet" --print-output-dir "$deck")")
cat <<TXT

Output is in $out:
  surfaces.xmf  the moving surfaces: paraview $out/surfaces.xmf
                (choose the XDMF Reader, press Apply, then Play; colour by body_id)
  bodies.xmf    body centres with velocity, angular velocity, orientation (Glyph filter for arrows)
  history.csv   energies, momentum, step sizes; plot with
                .venv/bin/python tools/plot_history.py $out/history.csv
TXT
