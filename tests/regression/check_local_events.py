"""The local event loop against the global one (&integrator events = 'local' / 'global'):
gases of 200 spheres and of 200 cubes in a closed box, random start (seeded), e = 1, no
gravity, run by both loops with the event log on. Every impact must be the same in both:
the same bodies at the same time to 1e-12 relative, the same linear and angular impulses to
1e-12 of the largest impulse of the run, and the same final state to 1e-9.

Why these tolerances hold and can fail: a time of contact is the crossing of the aim
(target + tol/2) refined to round-off and then looked for again on a fixed grid of absolute
times (time_of_contact's canonical_crossing), so it is a function of the two trajectories
alone, which both loops evaluate from the same anchors by the same arithmetic; the global
loop's steps only change where each advancement starts. The sphere gas comes out bitwise
identical; the cube gas within 1e-14 (2026-12-05), which the gas amplifies by about 10 per
collision per body. Before the canonical times, one slow approach of a cube to a wall was
uncertain by 1e-13 s and its impulse came within 1.4-1.7e-12 of the largest: that is the
margin these checks guard. A pair resolved at another time (a missed or an extra impact, a group
merged or split) shows as a different event list or an error of order 1e-3 and more. The
local loop's cost per event must also not grow with the scene: the script prints both
loops' wall times (measured in benchmarks, not asserted here).

Usage: check_local_events.py EXE WORKDIR"""
import math
import os
import re
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, box_walls, checkpoint, check_separation_floor

exe, work = sys.argv[1], sys.argv[2]
os.makedirs(work, exist_ok=True)
c = Checks()

RADIUS, EDGE, GAP, PHI = 0.05, 0.1, 0.005, 0.05


def gas_deck(path, shape, n, seed, events, t_end):
    """A gas of n bodies at volume fraction PHI in a box of six static walls."""
    rng = np.random.default_rng(seed)
    vol = 4.0 / 3.0 * math.pi * RADIUS ** 3 if shape == "sphere" else EDGE ** 3
    box = (n * vol / PHI) ** (1.0 / 3.0)
    rex = RADIUS if shape == "sphere" else EDGE * math.sqrt(3.0) / 2.0
    pos = []
    while len(pos) < n:
        p = rng.uniform(rex + GAP, box - rex - GAP, 3)
        if all(np.sum((p - q) ** 2) >= (2 * rex + GAP) ** 2 for q in pos):
            pos.append(p)
    vel = rng.normal(size=(n, 3))
    vel -= vel.mean(axis=0)
    vel *= 1.0 / math.sqrt(np.mean(np.sum(vel ** 2, axis=1)))
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1)[:, None]
    wall = 0.2
    lines = [f"&run title = 'gas {shape} {n}', t_end = {t_end!r}, dt_max = 1.0e-2 /",
             "&contact restitution = 1.0 /",
             f"&integrator events = '{events}' /",
             f"&output write_frames = .false., event_log = .true., history_interval = {t_end / 5!r} /"]
    lines += box_walls(box, wall)
    body = f"shape = 'sphere', radius = {RADIUS}" if shape == "sphere" else f"shape = 'box', size = {EDGE}, {EDGE}, {EDGE}"
    for k in range(n):
        lines.append("&body name = 'b%d', %s, density = 1000.0, position = %r, %r, %r, orientation = %r, %r, %r, %r, "
                     "velocity = %r, %r, %r /" % (k, body, *map(float, pos[k]), *map(float, quat[k]), *map(float, vel[k])))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def run(deck, out):
    proc = subprocess.run([exe, deck, "--output-dir", out], capture_output=True, text=True)
    c.check(proc.returncode == 0, f"{deck}: runs ({proc.stderr.strip()[-300:]})")
    return proc


def check_startup_line(proc, what):
    """The summary's start-up line: its phases in order, none negative, their sum within
    the start-up time (the slowest rank's; one rank here, so the same rank: the phases
    split it without a gap), which lies within the wall time (that counts from the
    program's start, reading the deck included)."""
    names = ["deck", "effective deck", "bodies", "checks", "owners", "first outputs", "loop set-up"]
    line = next((l for l in proc.stdout.splitlines() if l.strip().startswith("start-up")), "")
    m = re.match(r"\s*start-up\s+(\S+) s \(slowest rank\), of which (.*) s$", line)
    c.check(m is not None, f"{what}: a start-up line with its phases ({line!r})")
    if not m:
        return
    parts = [p.strip() for p in m.group(2).split(",")]
    got = [p.rsplit(" ", 1)[0] for p in parts]
    times = [float(p.rsplit(" ", 1)[1]) for p in parts]
    startup = float(m.group(1))
    c.check(got == names, f"{what}: the start-up's phases in order ({got})")
    # (each printed to 4 significant digits, '(es9.3)': a relative rounding of 5e-4 each)
    tolerance = 5e-4 * (sum(times) + startup) + 1e-9
    c.check(min(times) >= 0.0 and abs(sum(times) - startup) <= tolerance,
            f"{what}: the phases add up to the start-up ({times}, sum {sum(times):.4g} s, start-up {startup:.4g} s)")
    c.check(startup <= wall_time(proc), f"{what}: the start-up within the wall time ({startup} s, {wall_time(proc)} s)")


def wall_time(proc):
    for line in proc.stdout.splitlines():
        if line.strip().startswith("wall time"):
            return float(line.split()[2])
    return float("nan")


for shape, seed, t_end in (("sphere", 11, 0.5), ("cube", 12, 0.3)):
    runs = {}
    for events in ("global", "local"):
        deck = os.path.join(work, f"{shape}_{events}.nml")
        gas_deck(deck, shape, 200, seed, events, t_end)
        out = os.path.join(work, f"{shape}_{events}")
        proc = run(deck, out)
        check_separation_floor(c, proc)
        check_startup_line(proc, f"{shape} gas, {events} loop")
        log = np.loadtxt(os.path.join(out, "events.csv"), delimiter=",", skiprows=1, ndmin=2)
        runs[events] = (log, checkpoint(os.path.join(out, "checkpoint_final.h5"))[1], wall_time(proc))
    (lg, sg, wg), (ll, sl, wl) = runs["global"], runs["local"]
    n_impacts = len(np.unique(lg[:, 0]))
    print(f"{shape}: {len(lg)} body impulses in {n_impacts} impacts (global), {len(ll)} (local); "
          f"wall {wg:.3f} s global, {wl:.3f} s local")
    c.check(n_impacts >= 100, f"{shape}: the gas has impacts to compare ({n_impacts})")
    same_rows = lg.shape == ll.shape and np.array_equal(lg[:, 1], ll[:, 1])
    c.check(same_rows, f"{shape}: the same bodies get impulses in the same order ({len(lg)} vs {len(ll)} rows)")
    if same_rows:
        dt = np.max(np.abs(lg[:, 0] - ll[:, 0]) / np.maximum(np.abs(lg[:, 0]), 1e-300))
        scale = np.max(np.abs(lg[:, 2:5]))
        # (a sphere's impulses act through its centre: its angular impulses are round-off,
        # measured against the largest impulse times the body's size instead)
        scale_l = max(np.max(np.abs(lg[:, 5:8])), scale * RADIUS)
        dp = np.max(np.abs(lg[:, 2:5] - ll[:, 2:5])) / scale
        dl = np.max(np.abs(lg[:, 5:8] - ll[:, 5:8])) / scale_l
        print(f"{shape}: largest differences: time {dt:.2e} relative, impulse {dp:.2e}, angular impulse {dl:.2e} "
              f"(relative to the largest)")
        c.check(dt <= 1e-12, f"{shape}: event times agree to 1e-12 relative ({dt:.2e})")
        c.check(dp <= 1e-12, f"{shape}: impulses agree to 1e-12 of the largest ({dp:.2e})")
        c.check(dl <= 1e-12, f"{shape}: angular impulses agree to 1e-12 of the largest ({dl:.2e})")
    for key in ("x", "v", "w", "q"):
        d = float(np.max(np.abs(sg[key] - sl[key])))
        print(f"{shape}: final {key} differs by {d:.2e}")
        c.check(d <= 1e-9, f"{shape}: final {key} agrees to 1e-9 ({d:.2e})")
c.finish()
