"""A restart continues the run that wrote the checkpoint, or refuses with one clear line
naming the checkpoint and what differs, before any output is touched (issue: nothing
silently wrong, nothing lost):
  - other geometry: a cube replaced by a sphere of the same mass, a mesh file swapped, a
    mesh scale changed (0.2 -> 0.4 used to hang);
  - changed physics: gravity, dt_max, restitution, friction, min_separation (each named,
    old -> new); t_end and &output may change (a notice says the continuation is then not
    bitwise), initial conditions are ignored with a notice;
  - a checkpoint at or past t_end: an error, checkpoint_final.h5 left as it was;
  - a damaged checkpoint (one flipped bit in bodies/x, a NaN in bodies/v): refused as
    damage, history.csv and the frames untouched.
Decks and damaged files are made here. Usage: check_restart_refusals.py EXE WORKDIR MESH_DIR"""
import hashlib
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, history

exe, work, mesh_dir = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
c = Checks()

# Two bodies falling onto a floor: a box and a mesh (spot), checkpoints every 0.1 s.
RUN = "&run title = 'refusals', t_end = {t_end}, dt_max = {dt_max}, gravity = {gravity} /\n"
CONTACT = "&contact restitution = {e}, friction = {mu}{min_sep} /\n"
OUTPUT = "&output interval = 0.05, checkpoint_interval = 0.1 /\n"
FLOOR = "&body name = 'floor', shape = 'box', size = 4.0, 4.0, 0.2, position = 0.0, 0.0, -0.1, fixed = .true. /\n"
CUBE = "&body name = 'crate', {shape}, mass = 2.0, position = -1.0, 0.0, {z} /\n"
MESH = ("&body name = 'cow', shape = 'mesh', mesh_file = '{mesh}', scale = {scale}, mass = 1.0, "
        "position = 1.0, 0.0, 0.6 /\n")
BASE = dict(t_end=0.3, dt_max=0.01, gravity="0.0, 0.0, -9.81", e=0.5, mu=0.3, min_sep="",
            shape="shape = 'box', size = 0.2, 0.2, 0.2", z=0.5, mesh=os.path.join(mesh_dir, "spot.obj"),
            scale=0.2)


def deck(name, **changes):
    values = dict(BASE, **changes)
    text = (RUN.format(**values) + CONTACT.format(**values) + OUTPUT + FLOOR + CUBE.format(**values) +
            MESH.format(**values))
    path = os.path.join(work, name + ".nml")
    with open(path, "w") as f:
        f.write(text)
    return path


def ricochet(*args):
    return subprocess.run([exe, *args], capture_output=True, text=True, cwd=work)


def digest(folder):
    """Hashes of every file under folder (what a refused restart must leave alone)."""
    result = {}
    for root, _, files in os.walk(folder):
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as f:
                result[os.path.relpath(path, folder)] = hashlib.sha256(f.read()).hexdigest()
    return result


def expect_refused(args, fragments, what, out):
    before = digest(out)
    proc = ricochet(*args, "--output-dir", out)
    lines = proc.stderr.strip().splitlines()
    c.check(proc.returncode != 0, f"{what}: non-zero exit (got {proc.returncode})")
    c.check(len(lines) == 1 and lines[0].startswith("ricochet: error: "), f"{what}: one error line, got {lines}")
    for fragment in fragments:
        c.check(fragment in proc.stderr, f"{what}: message names '{fragment}': {proc.stderr.strip()}")
    c.check(digest(out) == before, f"{what}: every output file left as it was")


# The run every restart below starts from.
first = os.path.join(work, "first")
shutil.rmtree(first, ignore_errors=True)
proc = ricochet(deck("base"), "--output-dir", first)
c.check(proc.returncode == 0, f"first run: {proc.stderr.strip()}")
ckpt = os.path.join(first, "checkpoint_000001.h5")
c.check(os.path.exists(ckpt), "first run wrote checkpoint_000001.h5")


def restart_copy(name):
    """A fresh copy of the first run's output folder, to restart into."""
    out = os.path.join(work, "out_" + name)
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(first, out)
    return out, os.path.join(out, "checkpoint_000001.h5")


# Unchanged deck: accepted, and said to be bitwise.
out, path = restart_copy("same")
proc = ricochet(deck("base"), "--restart", path, "--output-dir", out)
c.check(proc.returncode == 0, f"unchanged deck restarts: {proc.stderr.strip()}")
c.check("continues bitwise" in proc.stdout, "unchanged deck: the restart says it is bitwise")

# Other geometry.
out, path = restart_copy("sphere")
expect_refused([deck("sphere", shape="shape = 'sphere', radius = 0.124"), "--restart", path],
               [path, "&body #2 'crate' shape 'box' -> 'sphere'"], "cube replaced by a sphere of the same mass", out)
out, path = restart_copy("swapped")
expect_refused([deck("swapped", mesh=os.path.join(mesh_dir, "cheburashka.obj")), "--restart", path],
               [path, "body 3", "'cow'", "geometry differs"], "mesh file swapped", out)
out, path = restart_copy("scale")
expect_refused([deck("scale", scale=0.4), "--restart", path],
               [path, "scale 0.2 -> 0.4"], "mesh scale 0.2 -> 0.4", out)
# A copy of the same mesh under another name is the same geometry: accepted.
copy = os.path.join(work, "spot_copy.obj")
shutil.copyfile(os.path.join(mesh_dir, "spot.obj"), copy)
out, path = restart_copy("copied_mesh")
proc = ricochet(deck("copied", mesh=copy), "--restart", path, "--output-dir", out)
c.check(proc.returncode == 0 and "mesh_file changed" in proc.stdout,
        f"the same mesh from another file: accepted with a notice: {proc.stderr.strip()} {proc.stdout[-400:]}")

# Changed physics: each named with its old and new value.
for name, change, fragment in [
        ("gravity", dict(gravity="0.0, 0.0, -1.62"), "&run gravity 0.0, 0.0, -9.81 -> 0.0, 0.0, -1.62"),
        ("dt_max", dict(dt_max=0.02), "&run dt_max 0.01 -> 0.02"),
        ("restitution", dict(e=0.9), "&contact restitution 0.5 -> 0.9"),
        ("friction", dict(mu=0.6), "&contact friction 0.3 -> 0.6"),
        ("min_separation", dict(min_sep=", min_separation = 1e-5"), "&contact min_separation -1.0 -> 1.0e-5")]:
    out, path = restart_copy(name)
    expect_refused([deck(name, **change), "--restart", path], [path, fragment, "physics"], f"changed {name}", out)
out, path = restart_copy("two")
expect_refused([deck("two", e=0.9, mu=0.6), "--restart", path],
               ["&contact restitution 0.5 -> 0.9", "&contact friction 0.3 -> 0.6"], "two changes, both named", out)

# Allowed: t_end (a notice says the continuation is not bitwise); ignored: initial conditions.
out, path = restart_copy("t_end")
proc = ricochet(deck("t_end", t_end=0.4), "--restart", path, "--output-dir", out)
c.check(proc.returncode == 0, f"t_end 0.3 -> 0.4 restarts: {proc.stderr.strip()}")
c.check("&run t_end changed from 0.3 to 0.4 (allowed)" in proc.stdout and "not bitwise" in proc.stdout,
        f"t_end change: notice and no bitwise claim: {proc.stdout[:600]}")
out, path = restart_copy("moved")
proc = ricochet(deck("moved", z=0.7), "--restart", path, "--output-dir", out)
c.check(proc.returncode == 0 and "position changed" in proc.stdout and "ignored" in proc.stdout,
        f"a changed initial position is ignored with a notice: {proc.stderr.strip()}")

# A checkpoint at t_end: nothing to run, an error, checkpoint_final.h5 untouched.
out, _ = restart_copy("final")
expect_refused([deck("base"), "--restart", os.path.join(out, "checkpoint_final.h5")],
               ["checkpoint_final.h5", "t_end", "nothing left to run"], "checkpoint at t_end", out)
out, path = restart_copy("past")
expect_refused([deck("past", t_end=0.05), "--restart", path], [path, "t = 1.000E-01 s, not before &run t_end = 5.000E-02 s"],
               "checkpoint past t_end", out)

# Damage: one flipped bit in x, a NaN in v. Refused as damage, nothing touched.
rows_before = len(history(first)["time"])
for name, edit in [("flipped_bit", "x"), ("nan_velocity", "v")]:
    out, path = restart_copy(name)
    with h5py.File(path, "r+") as f:
        data = np.array(f["bodies"][edit])
        if edit == "x":
            bits = data.view(np.uint64)
            bits[0, 1] ^= np.uint64(1) << np.uint64(40)
        else:
            data[1, 2] = np.nan
        f["bodies"][edit][...] = data
    expect_refused([deck("base"), "--restart", path], [path, "damaged", "digest"], f"checkpoint with a {name}", out)
    c.check(len(history(out)["time"]) == rows_before, f"{name}: history.csv keeps its {rows_before} rows")

c.finish()
