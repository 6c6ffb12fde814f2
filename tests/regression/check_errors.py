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
expect_error([deck("wall_limit.nml", "&run t_end = 1.0,\n dt_max = 0.1, wall_limit = -5 /\n"
                   "&body shape = 'sphere', radius = 1, mass = 1 /\n")],
             ["wall_limit.nml:2", "&run", "wall_limit", ">= 0 s", "-5"], "negative wall_limit")
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


# Closed, consistently oriented meshes whose surface crosses itself bound no solid (issue 19):
# refused naming the file, the group and the first two faces that cross (file triangles and
# lines) with a point of the crossing.
CUBE_FACES = [(1, 3, 2), (1, 4, 3), (5, 6, 7), (5, 7, 8), (1, 2, 6), (1, 6, 5),
              (2, 3, 7), (2, 7, 6), (3, 4, 8), (3, 8, 7), (4, 1, 5), (4, 5, 8)]


def cube_corners(lo, side):
    x, y, z = lo
    return [(x, y, z), (x + side, y, z), (x + side, y + side, z), (x, y + side, z),
            (x, y, z + side), (x + side, y, z + side), (x + side, y + side, z + side), (x, y + side, z + side)]


def cubes_obj(name, shells):
    """OBJ of cube shells (corners, inward?): 8 'v' lines then 12 'f' lines per shell."""
    path = os.path.join(work, name)
    with open(path, "w") as f:
        for k, (corners, inward) in enumerate(shells):
            f.writelines("v %r %r %r\n" % c for c in corners)
            for a, b, c3 in CUBE_FACES:
                if inward:
                    b, c3 = c3, b
                f.write(f"f {a + 8 * k} {b + 8 * k} {c3 + 8 * k}\n")
    return path


# Two cubes of side 10, the second shifted by 5 along each axis: 2000 kg instead of 1875 if
# accepted. Cube 1's top (triangle 3, line 11) meets cube 2's y = 5 side (triangle 18, line 34)
# along y = 5, z = 10, x in [5, 10].
two = cubes_obj("two_cubes.obj", [(cube_corners((0, 0, 0), 10.0), False), (cube_corners((5, 5, 5), 10.0), False)])
expect_error([deck("two_cubes.nml", good_run + f"&body name = 'pair', shape = 'mesh', mesh_file = '{two}', density = 1.0 /\n")],
             ["two_cubes.obj", "&body #1 'pair'", "intersects itself", "6 pair(s) of faces cross",
              "triangle 3 (line 11) and triangle 18 (line 34) cross at (7.50000000, 5.00000000, 10.0000000)"],
             "two overlapping cubes in one mesh")
# A cube with its corner (10, 10, 10) pushed through the bottom face to (5, 5, -5): negative
# principal moments if accepted. The fan around the moved corner crosses the bottom.
corners = cube_corners((0, 0, 0), 10.0)
corners[6] = (5.0, 5.0, -5.0)
pushed = cubes_obj("pushed_cube.obj", [(corners, False)])
expect_error([deck("pushed.nml", good_run + f"&body name = 'dented', shape = 'mesh', mesh_file = '{pushed}', density = 1.0 /\n")],
             ["pushed_cube.obj", "&body #1 'dented'", "intersects itself", "4 pair(s) of faces cross",
              "triangle 1 (line 9) and triangle 3 (line 11)"], "a cube with a vertex pushed through")
# Inertia: an inward-facing (cavity) cube shell far outside the body counts negative mass
# there: volume 1 - 0.125 > 0 and no crossing, but principal moments no body has.
cavity = cubes_obj("far_cavity.obj", [(cube_corners((0, 0, 0), 1.0), False), (cube_corners((10, 0, 0), 0.5), True)])
expect_error([deck("far_cavity.nml", good_run + f"&body name = 'ghost', shape = 'mesh', mesh_file = '{cavity}', density = 1.0 /\n")],
             ["far_cavity.nml:2", "&body #1 'ghost'", "far_cavity.obj", "principal moments", "not positive definite"],
             "a mesh whose inertia is not physical")
# User moments breaking the triangle inequality (I3 > I1 + I2): the deck's inertia is named.
expect_error([deck("inertia.nml", good_run + "&body name = 'odd', shape = 'box', size = 1, 1, 1, mass = 1.0, "
                   "inertia = 1.0, 1.0, 2.5 /\n")],
             ["inertia.nml:2", "&body #1 'odd'", "inertia", "larger than the sum of the other two"],
             "user moments violating the triangle inequality")
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
# A minimum separation finer than doubles resolve where the bodies are (resolution_check:
# 4 spacings of the largest coordinate) is refused, naming both bodies and the size ratio:
# a 1e-8 m grain on a 1e4 m planet (auto 2e-12 m < 4 spacing(2e4 m) = 1.46e-11 m; it broke
# the min_separation/2 floor in both loops), and an explicit 1e-7 m at |x| = 1e9 m
# (spacing 1.2e-7 m); also under --check. 1e-7 m on 1e4 m (5.5 spacings) runs:
# check_stress.py scales covers 1e-6 m.
scale_text = (good_run + "&body name = 'planet', shape = 'sphere', radius = 1.0e4, density = 1000, "
              "position = 0, 0, -1.0e4, fixed = .true. /\n"
              "&body name = 'grain', shape = 'sphere', radius = 1.0e-8, density = 1000, position = 0, 0, 1.0e-3 /\n")
for args in ([deck("scales.nml", scale_text)], [deck("scales_check.nml", scale_text), "--check"]):
    expect_error(args, ["&contact", "min_separation", "2.000E-12 m (auto", "&body #1 'planet'", "&body #2 'grain'",
                        "size ratio 1.0E+12", "3.638E-12 m apart", "at least 1.455E-11 m"],
                 f"min_separation below position resolution ({' '.join(os.path.basename(a) for a in args)})")
expect_error([deck("far.nml", good_run + "&contact min_separation = 1.0e-7 /\n"
                   "&body name = 'far', shape = 'sphere', radius = 1.0e-3, mass = 1.0, position = 1.0e9, 0, 0 /\n")],
             ["far.nml", "min_separation = 1.000E-07 m (&contact min_separation)", "&body #1 'far'", "1.000E+09 m"],
             "explicit min_separation below position resolution far from the origin")
proc = subprocess.run([exe, deck("scales_ok.nml", scale_text.replace("1.0e-8", "1.0e-7")), "--check"],
                      capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0, f"a 1e-7 m grain on the 1e4 m planet passes the checks: {proc.stderr.strip()}")
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
# (a sphere deep inside: its surface is far from the mesh's, only the winding number of
# its centre, inside the mesh's root box, finds it)
expect_error([deck("nested_sphere.nml", good_run + "&body name = 'shell', shape = 'mesh', "
                   f"mesh_file = '{data}/meshes/spot.obj', scale = 4.0, mass = 1.0 /\n"
                   "&body name = 'pea', shape = 'sphere', radius = 0.01, mass = 1.0, position = 0, 0, 0 /\n")],
             ["'shell'", "'pea'", "overlap"], "a sphere inside a mesh")
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
c.check(re.search(r"^\s*turning_term\s*= \.true\.$", proc.stdout, re.M) is not None,
        "--check prints &contact turning_term (default .true.)")
off = deck("turning_off.nml", good_run + "&contact turning_term = .false. /\n" + "&body name = 'ball', shape = 'sphere', radius = 1.0, mass = 1.0 /\n")
proc_off = subprocess.run([exe, "--check", off], capture_output=True, text=True, cwd=work)
c.check(re.search(r"^\s*turning_term\s*= \.false\.$", proc_off.stdout, re.M) is not None,
        "&contact turning_term = .false. is read and written back")
expect_error([deck("turning_bad.nml", good_run + "&contact turning_term = 0.5 /\n" + "&body name = 'ball', shape = 'sphere', radius = 1.0, mass = 1.0 /\n")],
             ["turning_bad.nml:2", "&contact", "turning_term"], "&contact turning_term not a logical")
# &parallel skin [m]: -1 (auto) by default, read and written back, negative or NaN refused
c.check(re.search(r"^\s*skin\s*= -1\.0\s", proc.stdout, re.M) is not None,
        "--check prints &parallel skin (default -1: auto)")
ball = "&body name = 'ball', shape = 'sphere', radius = 1.0, mass = 1.0 /\n"
skin = deck("skin.nml", good_run + "&parallel skin = 0.025 /\n" + ball)
proc_skin = subprocess.run([exe, "--check", skin], capture_output=True, text=True, cwd=work)
c.check(re.search(r"^\s*skin\s*= 0\.025\s", proc_skin.stdout, re.M) is not None,
        "&parallel skin = 0.025 is read and written back")
expect_error([deck("skin_negative.nml", good_run + "&parallel skin = -0.5 /\n" + ball)],
             ["skin_negative.nml:2", "&parallel", "skin", ">= 0 m, or -1 for auto"], "&parallel skin negative")
expect_error([deck("skin_nan.nml", good_run + "&parallel skin = NaN /\n" + ball)],
             ["skin_nan.nml:2", "&parallel", "skin"], "&parallel skin not finite")
# &parallel window_events [-]: -1 (auto) by default, read and written back, below 1 or NaN refused
c.check(re.search(r"^\s*window_events\s*= -1\.0\s", proc.stdout, re.M) is not None,
        "--check prints &parallel window_events (default -1: auto)")
aim = deck("window_events.nml", good_run + "&parallel window_events = 400 /\n" + ball)
proc_aim = subprocess.run([exe, "--check", aim], capture_output=True, text=True, cwd=work)
c.check(re.search(r"^\s*window_events\s*= 400\.0\s", proc_aim.stdout, re.M) is not None,
        "&parallel window_events = 400 is read and written back")
expect_error([deck("window_events_small.nml", good_run + "&parallel window_events = 0.5 /\n" + ball)],
             ["window_events_small.nml:2", "&parallel", "window_events", ">= 1 event, or -1 for auto"],
             "&parallel window_events below one event")
expect_error([deck("window_events_nan.nml", good_run + "&parallel window_events = NaN /\n" + ball)],
             ["window_events_nan.nml:2", "&parallel", "window_events"], "&parallel window_events not finite")
effective = deck("effective.nml", proc.stdout)
proc = subprocess.run([exe, "--check", effective], capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0, f"the effective deck is itself a valid deck: {proc.stderr.strip()}")
# --check runs every start-up check of a run (issue: it used to say "valid" for an open
# mesh, a truncated STL and overlapping bodies).
open_deck = deck("open.nml", good_run + f"&body name = 'bunny', shape = 'mesh', mesh_file = '{data}/meshes/stanford-bunny.obj', mass = 1.0 /\n")
expect_error(["--check", open_deck], ["stanford-bunny.obj", "open", "&body #1 'bunny'"], "--check: open mesh")
import struct
with open(os.path.join(work, "truncated.stl"), "wb") as f:
    f.write(b"\0" * 80 + struct.pack("<I", 12) + b"\0" * (50 * 5))   # 12 triangles announced, 5 present
expect_error(["--check", deck("stl.nml", good_run + "&body name = 'part', shape = 'mesh', mesh_file = 'truncated.stl', mass = 1.0 /\n")],
             ["truncated.stl", "&body #1 'part'"], "--check: truncated STL")
expect_error(["--check", deck("overlap.nml", good_run + "&body name = 'a', shape = 'sphere', radius = 1.0, mass = 1.0 /\n"
                              "&body name = 'b', shape = 'box', size = 1.0, 1.0, 1.0, mass = 1.0, position = 1.2, 0.0, 0.0 /\n")],
             ["'a'", "'b'", "overlap at the start"], "--check: overlapping bodies")
proc = subprocess.run([exe, "--check", deck("report.nml", good_run +
                       "&body name = 'ball', shape = 'sphere', radius = 0.5, mass = 2.0 /\n"
                       "&body name = 'crate', shape = 'box', size = 1.0, 2.0, 3.0, mass = 6.0, position = 2.0, 0.0, 0.0 /\n")],
                      capture_output=True, text=True, cwd=work)
c.check(proc.returncode == 0, f"--check report deck: {proc.stderr}")
out = proc.stdout
c.check("start-up checks passed" in out and "valid" in out, "--check says which checks passed")
# ball: mass 2, I = 2/5 m r^2 = 0.2; crate 1 x 2 x 3 of mass 6: I = m (b^2 + c^2)/12 = 6.5, 5, 2.5 (ascending 2.5, 5, 6.5)
c.check("mass 2.00000E+00 kg" in out and "principal moments 2.0000E-01 2.0000E-01 2.0000E-01" in out,
        f"--check: the ball's mass and moments: {out[-1500:]}")
c.check("principal moments 2.5000E+00 5.0000E+00 6.5000E+00" in out, "--check: the crate's principal moments (ascending)")
c.check("volume 6.00000E+00 m^3" in out, "--check: the crate's volume")
# gap: centre distance 2 minus radius 0.5 minus half width 0.5 = 1.0 m, between the two
c.check("smallest initial gap 1.000E+00 m, between body 1 'ball' (&body #1) and body 2 'crate' (&body #2)" in out,
        "--check: the smallest initial gap and its pair")

c.finish()
