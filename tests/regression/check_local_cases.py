"""Two scenes that only the local event loop can get wrong (&integrator events = 'local').

1. A chain A -> B -> C of equal spheres on a line, e = 1, no gravity. A flies at B (1 m/s);
   C drifts towards B slowly (1 mm/s), so the pair B-C holds a certificate far in the future
   (its gap of 0.1 m closes in 100 s). A's impulse at 0.2 s sends B to C at 1 m/s, which
   reaches it 0.1 s later: B's new trajectory must make the old B-C bound stale, or B
   tunnels into C. Equal masses at e = 1 swap velocities: A stops, B takes 1 m/s and gives
   it to C, and takes C's -1 mm/s (which needs 100 s to reach A). The final velocities are
   the analytic ones to 1e-12 m/s (round-off of the swaps) and no gap ever falls below
   min_separation/2.
2. Two clusters far apart: a gas of 60 spheres in a walled box, and 8 spinning spheres in
   free flight (parallel velocities, never touching). The free cluster is never stepped:
   the summary's "bodies never changed trajectory" (moving bodies) counts all eight, and
   fewer than half the gas, and each free sphere's frames are the exact flow,
   x0 + v t and q(t) = exp(w t / 2) q0, to 1e-12 (round-off of the evaluation from the
   anchor, which is exactly the start state: no accumulated steps).

Usage: check_local_cases.py EXE WORKDIR"""
import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, box_walls, run, check_separation_floor, frames, checkpoint

exe, work = sys.argv[1], sys.argv[2]
os.makedirs(work, exist_ok=True)
c = Checks()
R = 0.05


def sphere(name, pos, vel, omega=(0.0, 0.0, 0.0), fixed=False):
    extra = ", fixed = .true." if fixed else ""
    return (f"&body name = '{name}', shape = 'sphere', radius = {R}, density = 1000.0, "
            "position = %r, %r, %r, velocity = %r, %r, %r, angular_velocity = %r, %r, %r%s /"
            % (*map(float, pos), *map(float, vel), *map(float, omega), extra))


def never_changed(proc):
    m = re.search(r"(\d+) bodies never changed trajectory", proc.stdout)
    return int(m.group(1)) if m else -1


# ---- 1. the chain
lines = ["&run title = 'chain A B C', t_end = 0.6, dt_max = 1.0e-2 /",
         "&contact restitution = 1.0 /",
         "&integrator events = 'local' /",
         "&output write_frames = .false., event_log = .true. /",
         sphere("A", (0.0, 0, 0), (1.0, 0, 0)),
         sphere("B", (0.3, 0, 0), (0.0, 0, 0)),
         sphere("C", (0.5, 0, 0), (-1.0e-3, 0, 0))]
deck = os.path.join(work, "chain.nml")
with open(deck, "w") as f:
    f.write("\n".join(lines) + "\n")
out = os.path.join(work, "chain")
proc = run(exe, deck, out)
check_separation_floor(c, proc)
_, state = checkpoint(os.path.join(out, "checkpoint_final.h5"))
v = state["v"]                 # (bodies, 3), gid order: A, B, C
log = np.loadtxt(os.path.join(out, "events.csv"), delimiter=",", skiprows=1, ndmin=2)
impacts = sorted(set(log[:, 0]))
print(f"chain: impacts at {', '.join(f'{t:.6f}' for t in impacts)} s; final vx {v[:, 0]}")
# A-B at 0.2 s (gap 0.2 m at 1 m/s), B-C 0.0998 m later at 1.001 m/s closing
c.check(len(impacts) == 2, f"chain: two impacts, A-B and B-C ({len(impacts)})")
c.check(abs(impacts[0] - 0.2) < 1e-3, f"chain: A meets B at 0.2 s ({impacts[0]:.6f})")
c.check(len(impacts) > 1 and abs(impacts[1] - (0.2 + 0.0998 / 1.001)) < 1e-4,
        f"chain: B meets C 0.1 s later, long before C's old bound")
c.check(np.allclose(v[:, 0], [0.0, -1.0e-3, 1.0], atol=1e-12, rtol=0),
        f"chain: final velocities (0, -1 mm/s, 1 m/s) to 1e-12 ({v[:, 0]})")

# ---- 2. two clusters
rng = np.random.default_rng(5)
gas, box, wall = 60, 0.8, 0.2
lines = ["&run title = 'two clusters', t_end = 0.5, dt_max = 1.0e-2 /",
         "&contact restitution = 1.0 /",
         "&integrator events = 'local' /",
         "&output interval = 0.05 /"]
lines += box_walls(box, wall)
pos = []
while len(pos) < gas:
    p = rng.uniform(R + 0.01, box - R - 0.01, 3)
    if all(np.sum((p - q) ** 2) >= (2 * R + 0.01) ** 2 for q in pos):
        pos.append(p)
for k, p in enumerate(pos):
    lines.append(sphere(f"gas{k}", p, rng.normal(size=3)))
free = []
for k in range(8):
    x0 = np.array([5.0 + 0.3 * (k % 4), 0.3 * (k // 4), 0.0])
    v0 = np.array([0.5, 0.2, -0.1])
    w0 = rng.normal(size=3) * 20.0
    free.append((x0, v0, w0))
    lines.append(sphere(f"free{k}", x0, v0, w0))
deck = os.path.join(work, "clusters.nml")
with open(deck, "w") as f:
    f.write("\n".join(lines) + "\n")
out = os.path.join(work, "clusters")
proc = run(exe, deck, out)
check_separation_floor(c, proc)
unchanged = never_changed(proc)
print(f"clusters: {unchanged} moving bodies never changed trajectory (8 free spheres, {gas} in the gas)")
c.check(unchanged >= 8, f"clusters: the free spheres never change trajectory ({unchanged})")
c.check(unchanged < 8 + gas // 2, "clusters: most of the gas collides")


def quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


worst_x = worst_q = 0.0
series = frames(out)
first_free = 6 + gas          # gids in deck order from 1: walls, gas, free
for t, data in series:
    gids = data["gid"]
    for k, (x0, v0, w0) in enumerate(free):
        row = int(np.nonzero(gids == first_free + k + 1)[0][0])
        x = data["position"][row]          # frames: (bodies, 3) and (bodies, 4)
        q = data["orientation"][row]
        angle = np.linalg.norm(w0) * t
        axis = w0 / np.linalg.norm(w0)
        q_exact = quat_mul(np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis]), [1.0, 0, 0, 0])
        worst_x = max(worst_x, float(np.max(np.abs(x - (x0 + v0 * t)))))
        worst_q = max(worst_q, float(min(np.max(np.abs(q - q_exact)), np.max(np.abs(q + q_exact)))))
print(f"clusters: {len(series)} frames; free spheres off the exact flow by {worst_x:.2e} m, {worst_q:.2e} in q")
c.check(len(series) >= 10, f"clusters: frames written ({len(series)})")
c.check(worst_x <= 1e-12, f"clusters: free positions are x0 + v t to 1e-12 m ({worst_x:.2e})")
# (20 rad/s for 0.5 s: 10 rad; the flow's quaternion exponential is exact to ~1e-15 per rad)
c.check(worst_q <= 1e-12, f"clusters: free orientations are exp(w t / 2) q0 to 1e-12 ({worst_q:.2e})")
c.finish()
