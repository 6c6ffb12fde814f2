"""Restart is bitwise: a run from 0 to T, and a run restarted from its checkpoint at T/2,
end with identical body states (every double compared as its bit pattern), identical
step counts and identical frames after T/2. The restarted run continues in a copy of the
first run's folder cut back to what a crash just after T/2 would leave (frames and
history beyond T/2 removed or left half-written). A checkpoint of another deck is refused.

Usage: check_restart.py EXE DECK WORKDIR [ROTATION]
ROTATION ('exact' or 'newmark') runs a copy of the deck with that &integrator rotation."""
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, checkpoint, frames, history, run


def frames_time(path):
    import h5py
    with h5py.File(path, "r") as f:
        return float(f.attrs["time"])

import re


def absolute_meshes(text, deck):
    return re.sub(r"mesh_file = '([^']+)'",
                  lambda m: "mesh_file = '" + os.path.normpath(
                      os.path.join(os.path.dirname(os.path.abspath(deck)), m.group(1))) + "'", text)


exe, deck, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
if len(sys.argv) > 4:
    with open(deck) as f:
        text = absolute_meshes(f.read(), deck)
    deck = os.path.join(work, "deck.nml")
    with open(deck, "w") as f:
        f.write(text + f"\n&integrator rotation = '{sys.argv[4]}' /\n")
c = Checks()
straight, restarted = os.path.join(work, "straight"), os.path.join(work, "restarted")
for d in (straight, restarted):
    shutil.rmtree(d, ignore_errors=True)
run(exe, deck, straight)
c.check(os.path.exists(os.path.join(straight, "checkpoint_000001.h5")), "the straight run wrote a checkpoint at T/2")
# What a crash just after T/2 leaves: frames up to T/2, history rows up to a bit beyond
# it (the last one cut in half), the checkpoint at T/2, no final checkpoint.
shutil.copytree(straight, restarted)
middle = os.path.join(restarted, "checkpoint_000001.h5")
half = float(checkpoint(middle)[0]["time"])
for name in os.listdir(os.path.join(restarted, "frames")):
    if name.endswith(".h5") and frames_time(os.path.join(restarted, "frames", name)) > half:
        os.remove(os.path.join(restarted, "frames", name))
os.remove(os.path.join(restarted, "checkpoint_final.h5"))
later = sorted(n for n in os.listdir(straight) if n.startswith("checkpoint_0") and n != "checkpoint_000001.h5")
c.check(len(later) >= 2, f"the straight run has several checkpoints after the first: {later}")
for name in later:
    os.remove(os.path.join(restarted, name))
with open(os.path.join(restarted, "history.csv")) as f:
    lines = f.readlines()
keep = [l for l in lines[1:] if float(l.split(",")[0]) <= half + 0.1]
with open(os.path.join(restarted, "history.csv"), "w") as f:
    f.writelines(lines[:1] + keep[:-1] + [keep[-1][: len(keep[-1]) // 2]])
proc = run(exe, deck, restarted, "--restart", middle)
a_attrs, a = checkpoint(os.path.join(straight, "checkpoint_final.h5"))
b_attrs, b = checkpoint(os.path.join(restarted, "checkpoint_final.h5"))
c.check(a_attrs["time"] == b_attrs["time"] and a_attrs["step"] == b_attrs["step"],
        f"same final time and step: {a_attrs['time']} {a_attrs['step']} vs {b_attrs['time']} {b_attrs['step']}")
for key in sorted(a):
    same = a[key].shape == b[key].shape and (a[key].view(np.uint8) == b[key].view(np.uint8)).all() \
        if a[key].dtype.kind in "fiu" else bool((a[key] == b[key]).all())
    c.check(same, f"bitwise identical final '{key}'")
# Every later checkpoint is written again, under the same name, bitwise equal.
for name in later:
    path_b = os.path.join(restarted, name)
    c.check(os.path.exists(path_b), f"the restarted run wrote {name} again")
    if os.path.exists(path_b):
        ca, cb = checkpoint(os.path.join(straight, name))[1], checkpoint(path_b)[1]
        c.check(all(ca[k].tobytes() == cb[k].tobytes() for k in ca), f"{name}: bitwise identical")
fa = {t: d for t, d in frames(straight)}
fb = {t: d for t, d in frames(restarted)}
late = [t for t in fa if t > a_attrs["time"] / 2]
c.check(all(t in fb for t in late), "the restarted run wrote every frame after T/2")
c.check(all((fa[t]["position"] == fb[t]["position"]).all() for t in late if t in fb),
        "frames after T/2 identical")
# The XDMF indexes as ParaView's reader sees them: the same time steps, the frames before
# the checkpoint included from block files the restarted run wrote again.
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
from vtkmodules.vtkIOXdmf2 import vtkXdmfReader


def xdmf_times(path):
    reader = vtkXdmfReader()
    reader.SetFileName(path)
    reader.UpdateInformation()
    steps = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    return list(steps) if steps else []


for name in ("surfaces.xmf", "bodies.xmf"):
    ta, tb = xdmf_times(os.path.join(straight, name)), xdmf_times(os.path.join(restarted, name))
    c.check(ta == sorted(fa) and tb == ta, f"{name}: every frame's time in VTK's XDMF reader after the restart "
            f"({len(tb)} against {len(fa)} frames)")
ha, hb = history(straight), history(restarted)
c.check(len(ha["time"]) == len(hb["time"]) and (ha["time"] == hb["time"]).all()
        and (ha["energy_total"] == hb["energy_total"]).all() and (ha["steps"] == hb["steps"]).all(),
        "history after the restart: the same rows as the straight run's (half-written row dropped)")
# A checkpoint from another deck (other title and bodies) is refused, naming the file.
other = os.path.join(work, "other.nml")
with open(deck) as f:
    text = absolute_meshes(f.read().replace("title = '", "title = 'another "), deck)
with open(other, "w") as f:
    f.write(text.replace("density = 7800.0", "density = 7700.0"))
proc = run(exe, other, os.path.join(work, "other"), "--restart", middle, expect_ok=False)
c.check(proc.returncode != 0, "a checkpoint of another deck is refused (non-zero exit)")
c.check("checkpoint_000001.h5" in proc.stderr and "title" in proc.stderr,
        f"the refusal names the file and what differs: {proc.stderr.strip()}")
c.check(len(proc.stderr.strip().splitlines()) == 1, "one error line")
c.finish()
