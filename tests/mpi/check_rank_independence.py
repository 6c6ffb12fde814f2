"""Reproducible cluster runs: the same deck on 1 and on 2 ranks ends with bitwise identical
bodies (every double compared by its bit pattern), the same steps and the same frames.

Usage: check_rank_independence.py [--rotation ROTATION] EXE DECK WORKDIR MPIEXEC [MPIEXEC FLAGS...]
--rotation newmark runs a copy of the deck with that &integrator rotation: Newmark's answer
depends on the steps taken, so it holds only if every rank takes the steps one rank would
(the step is the smallest over all ranks' bodies)."""
import os
import re
import shutil
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks, checkpoint, frames

args = sys.argv[1:]
rotation = None
if args[0] == "--rotation":
    rotation, args = args[1], args[2:]
exe, deck, work, mpiexec = args[:4]
flags = args[4:]
os.makedirs(work, exist_ok=True)
if rotation:
    with open(deck) as f:
        text = re.sub(r"mesh_file = '([^']+)'", lambda m: "mesh_file = '" + os.path.normpath(
            os.path.join(os.path.dirname(os.path.abspath(deck)), m.group(1))) + "'", f.read())
    deck = os.path.join(work, "deck.nml")
    with open(deck, "w") as f:
        f.write(text + f"\n&integrator rotation = '{rotation}' /\n")
c = Checks()
outs = {}
for ranks in (1, 2):
    out = os.path.join(work, f"ranks{ranks}")
    shutil.rmtree(out, ignore_errors=True)
    cmd = [mpiexec, "-n", str(ranks), *flags, exe, deck, "--output-dir", out]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    c.check(proc.returncode == 0, f"{ranks} rank(s) run: {proc.stderr.strip()[-500:]}")
    outs[ranks] = out
a_attrs, a = checkpoint(os.path.join(outs[1], "checkpoint_final.h5"))
b_attrs, b = checkpoint(os.path.join(outs[2], "checkpoint_final.h5"))
c.check(int(b_attrs["n_ranks"]) == 2, "the second run really used 2 ranks")
c.check(int(a_attrs["step"]) == int(b_attrs["step"]), f"1 vs 2 ranks: the same steps ({a_attrs['step']}, {b_attrs['step']})")
for key in sorted(a):
    same = a[key].shape == b[key].shape and (
        (a[key].view(np.uint8) == b[key].view(np.uint8)).all() if a[key].dtype.kind in "fiu" else (a[key] == b[key]).all())
    c.check(bool(same), f"1 vs 2 ranks: bitwise identical final '{key}'")
fa, fb = frames(outs[1]), frames(outs[2])
c.check(len(fa) == len(fb) and all((x[1]["position"] == y[1]["position"]).all() for x, y in zip(fa, fb)),
        "1 vs 2 ranks: identical frames (bodies sorted by global id)")
c.finish()
