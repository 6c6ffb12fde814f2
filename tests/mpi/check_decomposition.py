"""The domain decomposition of a scene whose bodies cannot interact: the same deck on 1, 2 and
4 ranks (bricks of 2 x 1 x 1 and 2 x 2 x 1, bodies migrating between them) writes the same
files, restarts continue across rank counts as the uninterrupted run, and free flight is
exact.

Usage: check_decomposition.py EXE DECK WORKDIR MPIEXEC [MPIEXEC FLAGS...]

What "the same" means, and why:
- frames: cmp-identical files (HDF5 with no creation times and early allocation, bodies in
  global-id blocks whoever owned them);
- checkpoints: every dataset and attribute bit for bit except the attributes n_ranks and
  wall_time_before (what they say differs by design) and the counters pair_tests and
  min_separation: these sample the closest-point queries of the rank that certifies a pair,
  and a decomposed run (no ghosts yet) does not see a pair across a brick face, and
  certifies again the pairs of bodies that arrive in a migration (the pairs of staying
  bodies keep their certificates: docs/architecture.md, "The loop through a migration");
- history: every column except wall_time and min_separation (the same sampling).
Free flight: every centre of mass of every frame is x0 + v0 t + g t^2/2 computed here in
doubles, to 1e-12 m (|x| < 20 m: a few ulps of round-off, while any wrong anchor after a
migration moves a body by far more)."""
import filecmp
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks, frames
from run_compare import same_checkpoint, same_frames, same_history

exe, deck, work, mpiexec = sys.argv[1:5]
flags = sys.argv[5:]
os.makedirs(work, exist_ok=True)
c = Checks()


def run(ranks, out, *extra):
    if not extra:
        shutil.rmtree(out, ignore_errors=True)
    cmd = [mpiexec, "-n", str(ranks), *flags, exe, deck, "--output-dir", out, *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    c.check(proc.returncode == 0, f"{ranks} rank(s) {' '.join(extra)}: exit {proc.returncode} "
            f"{proc.stdout.strip()[-300:]} {proc.stderr.strip()[-500:]}")
    return proc


outs = {}
for ranks in (1, 2, 4):
    out = os.path.join(work, f"ranks{ranks}")
    proc = run(ranks, out)
    outs[ranks] = out
    if ranks > 1:
        c.check("domain decomposition" in proc.stdout and "ended by a migration" in proc.stdout,
                f"{ranks} ranks: the run was decomposed and migrated ({proc.stdout[-400:]})")
        migrated = [l for l in proc.stdout.splitlines() if "ended by a migration" in l]
        c.check(bool(migrated) and " 0 bodies changed rank" not in migrated[0],
                f"{ranks} ranks: bodies changed rank ({migrated})")
for ranks in (2, 4):
    what = f"1 vs {ranks} ranks"
    same_frames(c, outs[1], outs[ranks], what)
    same_history(c, outs[1], outs[ranks], what)
    for name in sorted(os.listdir(outs[1])):
        if name.startswith("checkpoint_") and name.endswith(".h5"):
            same_checkpoint(c, os.path.join(outs[1], name), os.path.join(outs[ranks], name), f"{what}, {name}")

# The bricks the deck asks for (&parallel dims = 4, 1, 1: more crossings along x) give the
# same frames and history again; dims that do not divide the ranks are an error naming them.
with open(deck) as f:
    text = f.read()
for dims, expect in (("4, 1, 1", True), ("3, 0, 0", False)):
    copy = os.path.join(work, f"dims_{dims.replace(', ', '')}.nml")
    with open(copy, "w") as f:
        f.write(text + f"\n&parallel dims = {dims} /\n")
    out = os.path.join(work, f"dims_{dims.replace(', ', '')}")
    shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.run([mpiexec, "-n", "4", *flags, exe, copy, "--output-dir", out], capture_output=True, text=True)
    if expect:
        c.check(proc.returncode == 0 and "decomposition 4 x 1 x 1" in proc.stdout,
                f"&parallel dims = {dims}: 4 x 1 x 1 bricks ({proc.stdout[-300:]} {proc.stderr[-300:]})")
        same_frames(c, outs[1], out, f"1 rank vs dims = {dims}")
        same_history(c, outs[1], out, f"1 rank vs dims = {dims}")
    else:
        c.check(proc.returncode != 0 and "&parallel: dims = 3, 0, 0 on 4 ranks" in proc.stderr,
                f"&parallel dims = {dims} on 4 ranks: an error naming the group ({proc.stderr[-300:]})")

# The global loop (Newmark rotation, global steps) migrates at step ends: 1 rank against
# 4 x 1 x 1 bricks.
newmark = {}
for ranks, extra in ((1, ""), (4, "&parallel dims = 4, 1, 1 /\n")):
    copy = os.path.join(work, f"newmark_{ranks}.nml")
    with open(copy, "w") as f:
        f.write(text + "\n&integrator rotation = 'newmark', events = 'global' /\n" + extra)
    out = os.path.join(work, f"newmark_{ranks}")
    shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.run([mpiexec, "-n", str(ranks), *flags, exe, copy, "--output-dir", out], capture_output=True,
                          text=True)
    c.check(proc.returncode == 0, f"newmark on {ranks} rank(s): {proc.stderr[-300:]}")
    newmark[ranks] = (out, proc.stdout)
moved = [l for l in newmark[4][1].splitlines() if "ended by a migration" in l]
c.check(bool(moved) and " 0 bodies changed rank" not in moved[0], f"newmark on 4 ranks: bodies changed rank ({moved})")
same_frames(c, newmark[1][0], newmark[4][0], "newmark, 1 vs 4 ranks")
same_history(c, newmark[1][0], newmark[4][0], "newmark, 1 vs 4 ranks")

# Restarts across rank counts: 4 -> 2, 4 -> 1 and 1 -> 4 from the first checkpoint.
for written, continued in ((4, 2), (4, 1), (1, 4)):
    what = f"checkpoint written on {written}, continued on {continued}"
    out = os.path.join(work, f"restart_{written}_{continued}")
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(outs[written], out)
    for name in os.listdir(out):
        if name.startswith("checkpoint_") and name not in ("checkpoint_000001.h5",):
            os.remove(os.path.join(out, name))
    run(continued, out, "--restart", os.path.join(out, "checkpoint_000001.h5"))
    same_checkpoint(c, os.path.join(outs[1], "checkpoint_final.h5"), os.path.join(out, "checkpoint_final.h5"),
                    what + ", checkpoint_final")
    same_frames(c, outs[1], out, what)
    same_history(c, outs[1], out, what)

# Free flight is exact on every rank count (the anchors travel with the bodies).
g = np.array([0.0, 0.0, -9.81])
fr = frames(outs[4])
x0, v0 = fr[0][1]["position"], fr[0][1]["velocity"]
worst = max(np.abs(d["position"] - (x0 + v0 * t + 0.5 * g * t * t)).max() for t, d in fr)
c.check(worst <= 1e-12, f"4 ranks: every centre on x0 + v0 t + g t^2/2 (largest deviation {worst:.2e} m)")
c.finish()
