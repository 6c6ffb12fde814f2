"""Free fall of spinning bodies through the whole program: every frame's centre of mass
and velocity equal x0 + v0 t + g t^2/2 and v0 + g t to round-off, rotation does not
disturb translation, energy/momentum errors in the summary are at round-off, and the
XDMF files open in VTK's reader (the one inside ParaView) with every frame.

Usage: check_free_fall.py EXE DECK WORKDIR"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, frames, history, run

exe, deck, work = sys.argv[1:4]
out = os.path.join(work, "out")
proc = run(exe, deck, out)
c = Checks()
g = np.array([0.0, 0.0, -9.81])
fr = frames(out)
t0, first = fr[0]
c.check(t0 == 0.0 and len(fr) == 9, f"9 frames from t=0 (interval 0.25 over 2 s): got {len(fr)} from {t0}")
x0, v0 = first["position"].reshape(-1, 3), first["velocity"].reshape(-1, 3)
worst_x = worst_v = 0.0
for t, b in fr:
    x, v = b["position"].reshape(-1, 3), b["velocity"].reshape(-1, 3)
    exact_x = x0 + v0 * t + 0.5 * g * t * t
    exact_v = v0 + g * t
    worst_x = max(worst_x, float(np.max(np.abs(x - exact_x) / (np.abs(exact_x) + 1.0))))
    worst_v = max(worst_v, float(np.max(np.abs(v - exact_v) / (np.abs(exact_v) + 1.0))))
# ~170 Newmark steps of a few flops each: accumulated round-off ~ steps * eps ~ 4e-14
# relative; 1e-12 leaves a margin of 25 and is still 1e10 below any modelling error.
c.check(worst_x < 1e-12, f"positions follow the parabola to 1e-12 relative (worst {worst_x:.2e})")
c.check(worst_v < 1e-12, f"velocities follow v0 + g t to 1e-12 relative (worst {worst_v:.2e})")
# Frames land exactly on multiples of the interval although dt_max does not divide it.
times = [t for t, _ in fr]
c.check(times == [k * 0.25 for k in range(9)], f"frame times are k*0.25 exactly: {times}")
# The summary reports conservation at round-off (energy, momentum, angular momentum about
# the centre of mass are exact invariants of free flight under uniform gravity).
for line in proc.stdout.splitlines():
    for key in ("energy error (max)", "momentum error (max)", "ang. momentum error"):
        if line.strip().startswith(key):
            value = float(line.split(key)[1].split()[0])
            # Newmark's rotation with beta = gamma/2 conserves energy and |L| to round-off
            # per step (docs/integrators.md); 1e-11 allows 170 steps of ~50 ulps.
            c.check(value < 1e-11, f"summary: {key} {value:.2e} < 1e-11")
h = history(out)
c.check(h["time"][0] == 0.0 and abs(h["time"][-1] - 2.0) < 1e-15, "history spans 0..t_end")
c.check(len(h["time"]) >= 80, f"history every interval/10 = 0.025 s: {len(h['time'])} rows")
e = h["energy_total"]
c.check(float(np.max(np.abs(e - e[0]))) < 1e-11 * float(np.max(np.abs(h["potential"]))),
        "history: total energy constant to 1e-11 of the potential energy scale")

# The XDMF files as ParaView's reader sees them.
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
from vtkmodules.vtkIOXdmf2 import vtkXdmfReader
for name, n_cells_expected in (("surfaces.xmf", None), ("bodies.xmf", 10)):
    reader = vtkXdmfReader()
    reader.SetFileName(os.path.join(out, name))
    reader.UpdateInformation()
    steps = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    c.check(steps is not None and len(steps) == 9, f"{name}: 9 time steps in VTK's XDMF reader")
    reader.UpdateTimeStep(2.0)
    data = reader.GetOutputDataObject(0)
    if n_cells_expected:
        c.check(data.GetNumberOfPoints() == n_cells_expected, f"{name}: 10 body centres")
    else:
        # spot 5856 + sphere drawn with 320 + box 12 + cylinder 4*48 + six boxes 72
        c.check(data.GetNumberOfCells() == 6452, f"{name}: surfaces of all bodies: {data.GetNumberOfCells()} == 6452 triangles")
c.finish()
