"""Bad input ends in one clear line on stderr and a non-zero exit, never a crash or a
traceback: decks, meshes, checkpoints and the command line.

Usage: check_errors.py EXE WORKDIR DATA_DIR"""
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks

exe, work, data = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
c = Checks()


def expect_error(args, fragments, what):
    proc = subprocess.run([exe, *args], capture_output=True, text=True, cwd=work)
    lines = proc.stderr.strip().splitlines()
    c.check(proc.returncode != 0, f"{what}: non-zero exit (got {proc.returncode})")
    c.check(len(lines) == 1 and lines[0].startswith("ricochet: error: "), f"{what}: one error line, got {lines}")
    for fragment in fragments:
        c.check(fragment in proc.stderr, f"{what}: message names '{fragment}': {proc.stderr.strip()}")


def deck(name, text):
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text)
    return path


good_run = "&run t_end = 1.0, dt_max = 0.1 /\n"
expect_error([], ["no deck"], "no arguments")
expect_error(["--frobnicate", "x.nml"], ["--frobnicate"], "unknown option")
expect_error(["missing.nml"], ["missing.nml"], "missing deck")
expect_error([deck("typo.nml", good_run + "&body name = 'ball', shape = 'sphere', radus = 1.0, mass = 1.0 /\n")],
             ["typo.nml:2", "&body #1 'ball'", "radus"], "unknown variable")
expect_error([deck("nan.nml", "&run t_end = nan, dt_max = 0.1 /\n&body shape = 'sphere', radius = 1, mass = 1 /\n")],
             ["nan.nml:1", "&run", "t_end"], "NaN")
expect_error([deck("events.nml", good_run + "&integrator events = 'sometimes' /\n"
                   "&body shape = 'sphere', radius = 1, mass = 1 /\n")],
             ["events.nml:2", "&integrator", "events", "'sometimes'", "'auto', 'local', 'global'"], "unknown events")
expect_error([deck("erule.nml", good_run + "&contact restitution = 0.5,\n  restitution_rule = 'product' /\n"
                   "&body shape = 'sphere', radius = 1, mass = 1 /\n")],
             ["erule.nml:3", "&contact", "restitution_rule", "'product'", "'min', 'max', 'mean'"],
             "unknown restitution_rule")
expect_error([deck("murule.nml", good_run + "&contact friction_rule = 'harmonic' /\n"
                   "&body shape = 'sphere', radius = 1, mass = 1 /\n")],
             ["murule.nml:2", "&contact", "friction_rule", "'harmonic'", "'geometric', 'min', 'max', 'mean'"],
             "unknown friction_rule")
expect_error([deck("open.nml", good_run + f"&body name = 'bunny', shape = 'mesh', mesh_file = '{data}/meshes/stanford-bunny.obj', mass = 1.0 /\n")],
             ["stanford-bunny.obj", "open", "223 boundary edge", "&body #1 'bunny'"], "open mesh")
expect_error([deck("suzanne.nml", good_run + f"&body name = 'monkey', shape = 'mesh', mesh_file = '{data}/meshes/suzanne.obj', mass = 1.0 /\n")],
             ["suzanne.obj", "non-manifold"], "non-manifold mesh")
ok_deck = deck("ok.nml", good_run + "&body name = 'ball', shape = 'sphere', radius = 1.0, mass = 1.0 /\n")
with open(os.path.join(work, "truncated.h5"), "wb") as f:
    f.write(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
expect_error([ok_deck, "--restart", "truncated.h5"], ["truncated.h5"], "truncated checkpoint")
expect_error([ok_deck, "--restart", "nowhere.h5"], ["nowhere.h5"], "missing checkpoint")
expect_error([ok_deck, "--restart"], ["--restart needs"], "--restart without a file")
# A minimum separation as large as the smallest moving body leaves no room to move: refused,
# naming the deck, the group and the variable, with the largest value that would do.
expect_error([deck("separation.nml", good_run + "&contact min_separation = 0.1 /\n"
                   "&body name = 'ball', shape = 'sphere', radius = 0.1, mass = 1.0 /\n")],
             ["separation.nml", "&contact", "min_separation", "too large", "below"], "min_separation of a body size")
# Bodies overlapping at the start are refused, naming both (closest-point overlap test).
expect_error([deck("spheres.nml", good_run + "&body name = 'a', shape = 'sphere', radius = 1.0, mass = 1.0 /\n"
                   "&body name = 'b', shape = 'sphere', radius = 1.0, mass = 1.0, position = 1.5, 0, 0 /\n")],
             ["'a' (body 1", "'b' (body 2", "overlap"], "overlapping spheres")
expect_error([deck("boxes.nml", good_run + "&body name = 'crates', shape = 'box', size = 1, 1, 1, density = 1, "
                   "copies = 3, 1, 1, spacing = 2, 0, 0 /\n"
                   "&body name = 'wedge', shape = 'box', size = 0.2, 0.2, 3, density = 1, position = 4.5, 0, 0, "
                   "orientation = 0.9238795325112867, 0.3826834323650898, 0, 0 /\n")],
             ["'crates' (body 3", "'wedge' (body 4", "&body #2"], "crossing boxes (third copy of a lattice)")
expect_error([deck("nested.nml", good_run + "&body name = 'shell', shape = 'mesh', "
                   f"mesh_file = '{data}/meshes/spot.obj', scale = 4.0, mass = 1.0 /\n"
                   "&body name = 'pea', shape = 'box', size = 0.01, 0.01, 0.01, mass = 1.0, position = 0, 0, 0 /\n")],
             ["'shell'", "'pea'", "overlap"], "a box inside a mesh")
ok_touching = deck("touching.nml", good_run + "&body name = 'a', shape = 'sphere', radius = 1.0, mass = 1.0 /\n"
                   "&body name = 'b', shape = 'sphere', radius = 1.0, mass = 1.0, position = 2.0, 0, 0 /\n")
proc = subprocess.run([exe, ok_touching, "--output-dir", "touching_out"], capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0, f"touching spheres are a valid start (Newton's cradle): {proc.stderr.strip()}")

# --check prints the effective deck, and that deck is itself valid.
proc = subprocess.run([exe, "--check", ok_deck], capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0 and "&integrator" in proc.stdout and "newmark_beta" in proc.stdout,
        "--check prints the effective deck with defaults filled in")
c.check(re.search(r"^\s*events\s*= 'auto'$", proc.stdout, re.M) is not None,
        "--check prints &integrator events (default 'auto')")
c.check(re.search(r"^\s*restitution_rule\s*= 'min'$", proc.stdout, re.M) is not None and
        re.search(r"^\s*friction_rule\s*= 'geometric'$", proc.stdout, re.M) is not None,
        "--check prints &contact restitution_rule 'min' and friction_rule 'geometric' (the defaults)")
effective = deck("effective.nml", proc.stdout)
proc = subprocess.run([exe, "--check", effective], capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0, f"the effective deck is itself a valid deck: {proc.stderr.strip()}")
c.finish()
