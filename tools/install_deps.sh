#!/usr/bin/env bash
# Installs what ricochet needs on Debian 12 and is missing: the Fortran/MPI/HDF5/LAPACK
# toolchain from Debian's archive, and a Python venv (.venv) with numpy, h5py, matplotlib
# and vtk for tools/. Idempotent: a second call installs nothing and takes about a second.
#   --bench  also the engines docs/benchmarks.md compares against (PyBullet, MuJoCo, coal:
#            tools/requirements-engines.txt)
set -euo pipefail
bench=0
for arg in "$@"; do
  case "$arg" in
    --bench) bench=1 ;;
    *) echo "install_deps: unknown option '$arg' (only --bench)" >&2; exit 2 ;;
  esac
done
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

debs=(gfortran cmake ninja-build libopenmpi-dev openmpi-bin libhdf5-openmpi-dev
      liblapack-dev libblas-dev python3-venv pkg-config)
missing=()
for p in "${debs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install_deps: installing from Debian: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Python for tools/ only. /usr/bin/python3 is Debian's; a pyenv python3 on PATH may lack venv.
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
  echo "install_deps: creating $venv"
  /usr/bin/python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import numpy, h5py, matplotlib, vtk" 2>/dev/null; then
  echo "install_deps: installing numpy h5py matplotlib vtk into $venv"
  "$venv/bin/pip" install -q --disable-pip-version-check numpy h5py matplotlib vtk
fi
# The other engines of docs/benchmarks.md (tools/bench_engines.py, tools/bench_resting.py,
# tools/bench_closest_points.py), on request.
if [ "$bench" -eq 1 ] && ! "$venv/bin/python" -c "import pybullet, mujoco, coal" 2>/dev/null; then
  echo "install_deps: installing the benchmark engines (tools/requirements-engines.txt) into $venv"
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$here/tools/requirements-engines.txt"
fi
