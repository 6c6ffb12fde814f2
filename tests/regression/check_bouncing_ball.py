"""Bouncing ball through the whole program: an analytic sphere (radius 0.1 m, centre at
1.1 m) dropped on a static box (top at z = 0), e = 0.8, g = 9.81 m/s^2.

Analytic solution with the contact distance the method really uses: conservative
advancement stops at the gap target + tolerance/2 (min_separation 1e-6 m plus half the
advancement tolerance, 0.1 min_separation), and with gravity only, the bound is exact for
translation, so every impact happens with the centre at z_c = 0.1 + 1.05e-6 m. Fall height
H0 = 1.1 - z_c, v0 = sqrt(2 g H0); flight k (after the k-th impact) has apex height
H0 e^(2k) above z_c, and impacts are at t1 = sqrt(2 H0/g), t_(k+1) = t_k + 2 e^k v0/g.

From every frame between impacts, (z, v_z) gives that flight's apex height
(z - z_c + v^2/(2g)) and its impact times (the roots of the parabola through z_c): all are
compared with the analytic values for the first 10 bounces to 1e-8 relative. Why 1e-8 is
safe and still sharp: the motion between impacts is the exact parabola and the impulse is
exact, so errors are round-off (1e-15 relative per impact, 1e-13 after 10) plus the
landing gap, which the exact bound puts on target + tolerance/2 to round-off; a contact at
the wrong height by even one tolerance (1e-7 m) shifts the apex of flight 10 (0.012 m) by
~1e-5 relative and fails the test.

The same with a faceted ball (a 320-face icosphere landing on a face): give its OBJ file,
and the contact height is the distance from its centre of mass to its bottom face.

Usage: check_bouncing_ball.py EXE DECK WORKDIR [OBJ]"""
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, frames, history, run

exe, deck, work = sys.argv[1:4]
if len(sys.argv) > 4:
    nodes = np.array([[float(x) for x in line.split()[1:4]] for line in open(sys.argv[4]) if line.startswith("v ")])
    # centre of mass: the mesh is symmetric about its centre, so the node mean (1e-18 off)
    r = float(nodes[:, 2].mean() - np.sort(nodes[:, 2])[:3].mean())
else:
    r = 0.1
out = os.path.join(work, "out")
proc = run(exe, deck, out)
c = Checks()
g, e = 9.81, 0.8
delta, tol = 1.0e-6, 1.0e-7
z_c = r + delta + 0.5 * tol
h0 = 1.1 - z_c
v0 = math.sqrt(2 * g * h0)
impacts = [math.sqrt(2 * h0 / g)]
for k in range(1, 12):
    impacts.append(impacts[-1] + 2 * e ** k * v0 / g)

worst_apex = worst_time = worst_spin = 0.0
flights_seen = set()
for t, b in frames(out):
    z = float(b["position"].reshape(-1, 3)[1, 2])
    vz = float(b["velocity"].reshape(-1, 3)[1, 2])
    k = sum(1 for ti in impacts if ti < t)          # impacts before this frame
    if k == 0 or k > 10:
        continue
    if min(abs(t - impacts[k - 1]), abs(t - impacts[k])) < 1e-6:
        continue                                     # at an impact: which flight is ambiguous
    worst_spin = max(worst_spin, float(np.max(np.abs(b["angular_velocity"].reshape(-1, 3)[1]))))
    apex = z - z_c + vz * vz / (2 * g)
    worst_apex = max(worst_apex, abs(apex - h0 * e ** (2 * k)) / (h0 * e ** (2 * k)))
    # this flight's impacts: z_c = z + vz s - g s^2/2 -> s = (vz -+ sqrt(vz^2 + 2 g (z - z_c)))/g
    root = math.sqrt(vz * vz + 2 * g * (z - z_c))
    t_start, t_end = t + (vz - root) / g, t + (vz + root) / g
    worst_time = max(worst_time, abs(t_start - impacts[k - 1]) / impacts[k - 1], abs(t_end - impacts[k]) / impacts[k])
    flights_seen.add(k)
c.check(flights_seen == set(range(1, 11)), f"frames in each of the first 10 flights: {sorted(flights_seen)}")
c.check(worst_apex < 1e-8, f"apex heights h0 e^(2k), k = 1..10, to 1e-8 relative (worst {worst_apex:.2e})")
c.check(worst_time < 1e-8, f"impact times to 1e-8 relative (worst {worst_time:.2e})")
c.check(worst_spin < 1e-9, f"no spin from the landings (worst |w| {worst_spin:.1e} rad/s)")
h = history(out)
c.check(int(h["events"][-1]) == sum(1 for ti in impacts if ti <= 3.8), f"one event per impact: {int(h['events'][-1])}")
c.check(float(np.min(h["min_separation"])) >= delta, "smallest separation never below min_separation")
print(f"worst apex {worst_apex:.2e}, worst impact time {worst_time:.2e}, events {int(h['events'][-1])}")
c.finish()
