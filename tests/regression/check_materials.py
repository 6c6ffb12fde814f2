"""Materials per pair through the whole program: two analytic spheres (radius 0.1 m) of
different restitution dropped together (same height, same time, 1 m apart: they never touch
each other) on one fixed floor, g = 9.81 m/s^2, once per &contact restitution_rule:
  - 'min'  (floor e = 1.0): the pairs' e are the balls' own, 0.9 and 0.5;
  - 'max'  (floor e = 0.2): again 0.9 and 0.5;
  - 'mean' (floor e = 0.7): (0.9 + 0.7)/2 = 0.8 and (0.5 + 0.7)/2 = 0.6.
Both balls land in the same event, and each must then follow its own pair's e: flight k
(after the k-th impact) has apex height H0 e^(2k) above the contact height z_c (the ratio of
successive apexes is e^2), impacts at t1 = sqrt(2 H0/g), t_(k+1) = t_k + 2 e^k v0/g.

Tolerance 1e-8 relative on the apex heights of the first 3 flights, as in
check_bouncing_ball.py and for the same reason: between impacts the motion is the exact
parabola (exact free flight, gravity only), the contact height is the conservative
advancement target z_c = r + min_separation + tolerance/2 (the bound is exact for
translation) and the impulse is exact, so the error is round-off (1e-13 after 10 impacts);
a wrong e (a shared e of the smaller, 0.5, say) misses by tens of per cent, and a contact at
the wrong height by one tolerance (1e-7 m) by ~1e-6. The impact speeds stay above the auto
rest_speed (2 g dt_max = 0.196 m/s): the 4th impact of the e = 0.5 ball is at 0.55 m/s.

Friction, per &contact friction_rule: two 0.1 m cubes (mu 0.1 and 0.9) set sliding at
v0 = 1 m/s side by side (0.6 m apart) on one floor of mu 0.4, e = 0, each must stop after
v0^2/(2 mu g) with its own pair's mu: 'geometric' (default) sqrt(0.04) = 0.2 and
sqrt(0.36) = 0.6, 'min' 0.1 and 0.4, 'mean' 0.25 and 0.65. To v0 dt_max = 1e-3 m: the
resting-contact solve gives the exact constant deceleration mu g over each step (as in the
sliding_stop case, check_resting.py), so the error is the step in which the cube stops,
at most one step of travel (we see 5e-4 m, half of it, for every mu). The nearest wrong
value, another rule's mu (0.6 against 0.65), moves the stop by 6.5e-3 m.

Usage: check_materials.py EXE WORKDIR"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, frames, run

exe, work = sys.argv[1:3]
os.makedirs(work, exist_ok=True)
c = Checks()
g, r, delta, tol = 9.81, 0.1, 1.0e-6, 1.0e-7
z_c = r + delta + 0.5 * tol
h0 = 1.1 - z_c
v0 = math.sqrt(2 * g * h0)
flights = 3


def impact_times(e):
    times = [math.sqrt(2 * h0 / g)]
    for k in range(1, flights + 2):
        times.append(times[-1] + 2 * e ** k * v0 / g)
    return times


for rule, floor_e, expected in (("min", 1.0, (0.9, 0.5)), ("max", 0.2, (0.9, 0.5)), ("mean", 0.7, (0.8, 0.6))):
    path = os.path.join(work, f"two_balls_{rule}.nml")
    t_end = impact_times(expected[0])[flights] - 0.01   # in flight `flights` of the bouncier ball
    with open(path, "w") as f:
        f.write(f"&run title = 'two materials', t_end = {t_end!r}, dt_max = 1.0e-2, gravity = 0, 0, -9.81 /\n"
                f"&contact restitution_rule = '{rule}', min_separation = {delta!r} /\n"
                "&output interval = 1.0e-2 /\n"
                f"&body name = 'floor', shape = 'box', size = 3.0, 1.0, 0.2, position = 0, 0, -0.1, fixed = .true., "
                f"restitution = {floor_e!r} /\n"
                "&body name = 'bouncy', shape = 'sphere', radius = 0.1, density = 1000, position = -0.5, 0, 1.1, "
                "restitution = 0.9 /\n"
                "&body name = 'dull', shape = 'sphere', radius = 0.1, density = 1000, position = 0.5, 0, 1.1, "
                "restitution = 0.5 /\n")
    out = os.path.join(work, f"out_{rule}")
    run(exe, path, out)
    history = frames(out)
    for body, e in ((1, expected[0]), (2, expected[1])):
        times = impact_times(e)
        worst, seen = 0.0, set()
        for t, b in history:
            k = sum(1 for ti in times if ti < t)
            if k == 0 or k > flights or min(abs(t - times[k - 1]), abs(t - times[k])) < 1e-6:
                continue
            z = float(b["position"].reshape(-1, 3)[body, 2])
            vz = float(b["velocity"].reshape(-1, 3)[body, 2])
            apex = z - z_c + vz * vz / (2 * g)
            worst = max(worst, abs(apex - h0 * e ** (2 * k)) / (h0 * e ** (2 * k)))
            seen.add(k)
        c.check(seen == set(range(1, flights + 1)), f"{rule}, e = {e}: frames in flights 1..{flights}: {sorted(seen)}")
        c.check(worst < 1e-8, f"{rule}, e = {e}: apex heights H0 e^(2k) to 1e-8 relative (worst {worst:.2e})")
        print(f"restitution_rule {rule}: ball {body} pair e {e}: worst apex error {worst:.2e}")

v0 = 1.0
for rule, mus in (("geometric", (0.2, 0.6)), ("min", (0.1, 0.4)), ("mean", (0.25, 0.65))):
    path = os.path.join(work, f"two_cubes_{rule}.nml")
    t_end = 1.1 * v0 / (min(mus) * g)   # both at rest by then
    with open(path, "w") as f:
        f.write(f"&run title = 'two frictions', t_end = {t_end!r}, dt_max = 1.0e-3, gravity = 0, 0, -9.81 /\n"
                f"&contact restitution = 0.0, friction_rule = '{rule}', min_separation = 1.0e-5 /\n"
                "&output interval = 0.05 /\n"
                "&body name = 'floor', shape = 'box', size = 4.0, 1.0, 0.2, position = 0, 0, -0.1, fixed = .true., "
                "friction = 0.4 /\n"
                # resting on the floor: bottom face 1.05 min_separation above it (sliding_stop.nml)
                "&body name = 'slick', shape = 'box', size = 0.1, 0.1, 0.1, density = 1000, "
                f"position = -1.0, -0.3, 0.0500105, velocity = {v0!r}, 0, 0, friction = 0.1 /\n"
                "&body name = 'rough', shape = 'box', size = 0.1, 0.1, 0.1, density = 1000, "
                f"position = -1.0, 0.3, 0.0500105, velocity = {v0!r}, 0, 0, friction = 0.9 /\n")
    out = os.path.join(work, f"out_friction_{rule}")
    run(exe, path, out)
    fr = frames(out)
    for body, mu in ((1, mus[0]), (2, mus[1])):
        x0 = float(fr[0][1]["position"].reshape(-1, 3)[body, 0])
        x1 = float(fr[-1][1]["position"].reshape(-1, 3)[body, 0])
        want = v0 * v0 / (2 * mu * g)
        err = abs((x1 - x0) - want) / want
        print(f"friction_rule {rule}: cube {body} pair mu {mu}: travel {x1 - x0:.6f} m, analytic {want:.6f} m "
              f"(relative error {err:.2e})")
        c.check(abs((x1 - x0) - want) < v0 * 1.0e-3,
                f"{rule}, mu = {mu}: stopping distance v0^2/(2 mu g) to v0 dt_max ({x1 - x0:.6f}, want {want:.6f})")
c.finish()
