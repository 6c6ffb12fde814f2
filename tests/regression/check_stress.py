"""Stress cases (CTest label `stress`): the method at its extremes, each deck written here.

  mass_ratio  a 1e6 kg sphere at 1 m/s into a 1 kg one at rest (radius 0.1 m, no gravity,
              e = 1): the 1D elastic result v_heavy = (M - m)/(M + m) v, v_light = 2M/(M + m) v,
              energy and momentum kept; then a 1 kg box resting on a 1e6 kg box on a floor,
              and the 1e6 kg box on the 1 kg one (g = 9.81, e = 0, 2 s): nothing sinks, nothing
              moves.
  spinning    a 0.1 m cube spinning at 1e4 rad/s about a tilted axis dropped on a floor, e = 1
              and e = 0.5: never closer than min_separation/2, the energy never above its start,
              finished within the CTest timeout.
  scales      a 1e-6 m sphere dropped on a fixed 1e4 m sphere (top at z = 0), e = 0.5, and a
              1 m sphere beside it (the auto min_separation comes from the smallest body): contact
              found, no gap below min_separation/2, the tiny ball ends at rest on the huge one;
              then the 1e-6 m sphere on a fixed 2e4 m box floor (top at z = 0): contact found,
              never inside the floor.

Every case also checks the separation guarantee from the summary and that no value is NaN.

Fixed bug (scales, local event loop): the local loop's grid (cell_grid) computed box
coordinates with a default-kind floor(), which overflows past 2^31 boxes: the 1e4 m body in
2e-6 m boxes (5e9 boxes) got an empty box range, was listed nowhere, and the 1e-6 m sphere
fell through it (0 contact events, 0 pair certificates). Both loops must find the contact:
the case runs with LOOP = global and LOOP = local.

Usage: check_stress.py CASE EXE WORKDIR [LOOP]"""
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, check_separation_floor, frames, history, run, smallest_separation

case, exe, work = sys.argv[1:4]
loop = sys.argv[4] if len(sys.argv) > 4 else "auto"
os.makedirs(work, exist_ok=True)
c = Checks()


def write(name, text):
    path = os.path.join(work, name + ".nml")
    with open(path, "w") as f:
        f.write(text)
    return path


def run_case(name, text):
    start = time.time()
    out = os.path.join(work, "out_" + name)
    proc = run(exe, write(name, text), out)
    wall = time.time() - start
    print(f"{name}: {wall:.1f} s wall")
    check_separation_floor(c, proc)
    h = history(out)
    c.check(all(np.all(np.isfinite(v)) for v in h.values()), f"{name}: history has no NaN or Inf")
    return proc, out, h, wall


if case == "mass_ratio":
    big, small, v = 1.0e6, 1.0, 1.0
    proc, out, h, _ = run_case("head_on", (
        "&run title = 'mass ratio 1e6', t_end = 0.5, dt_max = 1.0e-2 /\n"
        "&contact restitution = 1.0, min_separation = 1.0e-6 /\n&output interval = 0.05 /\n"
        f"&body name = 'heavy', shape = 'sphere', radius = 0.1, mass = {big!r}, position = -0.3, 0, 0, velocity = {v!r}, 0, 0 /\n"
        f"&body name = 'light', shape = 'sphere', radius = 0.1, mass = {small!r}, position = 0.0, 0, 0 /\n"))
    fr = frames(out)
    vel = fr[-1][1]["velocity"].reshape(-1, 3)
    want_heavy, want_light = (big - small) / (big + small) * v, 2 * big / (big + small) * v
    # The impulse is a few flops of exact arithmetic (one contact: lambda = 2 m_red v); the
    # scaled velocities sqrt(M) v make the light body's share 1e-3 of the heavy one's, so a
    # relative 1e-12 leaves ~1e3 ulps of the 1e6 range. The heavy body's loss, 2e-6 of v,
    # must come out to 1e-6 relative of itself (a solver that dropped it would be off by 1).
    c.check(abs(vel[1, 0] - want_light) < 1e-12 * want_light, f"light sphere leaves at 2M/(M+m) v: {vel[1, 0]!r}, want {want_light!r}")
    c.check(abs((v - vel[0, 0]) - (v - want_heavy)) < 1e-6 * (v - want_heavy),
            f"heavy sphere loses (v - v') = 2m/(M+m) v = {v - want_heavy:.6e}: got {v - vel[0, 0]:.6e}")
    c.check(int(h["events"][-1]) == 1, f"one impact: {int(h['events'][-1])}")
    e0, e1 = h["energy_total"][0], h["energy_total"]
    # e = 1: energy conserved to round-off of 5e5 J (1e-12 relative)
    drift = float(np.max(np.abs(e1 - e0)) / e0)
    c.check(drift < 1e-12, f"energy at e = 1 kept to 1e-12 relative: {drift:.2e}")
    p0 = big * v
    pdrift = float(np.max(np.abs(h["momentum_x"] - p0)) / p0)
    c.check(pdrift < 1e-12, f"momentum kept to 1e-12 relative: {pdrift:.2e}")
    print(f"head-on: v_light {vel[1, 0]!r}, v_heavy {vel[0, 0]!r}, energy drift {drift:.2e}, momentum drift {pdrift:.2e}")

    for name, lower, upper in (("light_on_heavy", big, small), ("heavy_on_light", small, big)):
        gap = 1.05e-5   # resting: 1.05 min_separation above what is below
        proc, out, h, _ = run_case(name, (
            f"&run title = '{name}', t_end = 2.0, dt_max = 1.0e-3, gravity = 0, 0, -9.81 /\n"
            "&contact restitution = 0.0, friction = 0.5, min_separation = 1.0e-5 /\n&output interval = 0.1 /\n"
            "&body name = 'floor', shape = 'box', size = 2, 2, 0.2, position = 0, 0, -0.1, fixed = .true. /\n"
            f"&body name = 'lower', shape = 'box', size = 0.2, 0.2, 0.2, mass = {lower!r}, position = 0, 0, {0.1 + gap!r} /\n"
            f"&body name = 'upper', shape = 'box', size = 0.1, 0.1, 0.1, mass = {upper!r}, "
            f"position = 0, 0, {0.2 + 2 * gap + 0.05!r} /\n"))
        fr = frames(out)
        pos = np.array([b["position"].reshape(-1, 3) for _, b in fr])
        bottom_lower = pos[:, 1, 2] - 0.1
        bottom_upper = pos[:, 2, 2] - 0.05
        sink = min(float(np.min(bottom_lower)), float(np.min(bottom_upper - (pos[:, 1, 2] + 0.1))))
        drift = float(np.max(np.abs(pos - pos[0])))
        # the contact pass holds resting bodies in the band [min_separation/2, ...]: no gap
        # below 5e-6 m, and a stack at rest moves by less than 1e-6 m in 2 s (the stack
        # case's 1e-3 m over 10 s is for ten levels; two levels settle to round-off)
        c.check(sink >= 0.5e-5 * (1 - 1e-9), f"{name}: no gap below min_separation/2 (smallest {sink:.3e} m)")
        c.check(drift < 1e-6, f"{name}: the stack stays put (largest displacement {drift:.2e} m)")
        print(f"{name}: smallest gap {sink:.3e} m, largest displacement {drift:.2e} m")

elif case == "spinning":
    edge, omega = 0.1, 1.0e4
    axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    w = [float(x) for x in omega * axis]
    for e in (1.0, 0.5):
        name = f"spin_e{e}"
        proc, out, h, wall = run_case(name, (
            f"&run title = 'spinning cube', t_end = 0.5, dt_max = 1.0e-2, gravity = 0, 0, -9.81 /\n"
            f"&contact restitution = {e!r}, min_separation = 1.0e-6 /\n&output interval = 0.05 /\n"
            "&body name = 'floor', shape = 'box', size = 4, 4, 0.2, position = 0, 0, -0.1, fixed = .true. /\n"
            f"&body name = 'cube', shape = 'box', size = {edge!r}, {edge!r}, {edge!r}, density = 1000, "
            f"position = 0, 0, 0.2, angular_velocity = {w[0]!r}, {w[1]!r}, {w[2]!r} /\n"))
        energy = h["energy_total"]
        rise = float(np.max(energy - energy[0]) / abs(energy[0]))
        # 1e-12 of the 8e4 J of spin: the exact rotation keeps the energy to round-off, an
        # impulse never adds any (impulse_solver); 1e-12 is ~1e4 ulps over the run
        c.check(rise <= 1e-12, f"{name}: energy never above its start (largest rise {rise:.2e} relative)")
        fr = frames(out)
        z = np.array([b["position"].reshape(-1, 3)[1, 2] for _, b in fr])
        # the centre can never be nearer the floor than half the cube's edge
        c.check(float(np.min(z)) > 0.5 * edge, f"{name}: centre never below edge/2 ({np.min(z):.4f} m)")
        c.check(int(h["events"][-1]) > 0, f"{name}: it hit the floor ({int(h['events'][-1])} events)")
        c.check(wall < 60, f"{name}: finished in {wall:.1f} s (< 60 s)")
        print(f"{name}: {int(h['events'][-1])} events, energy rise {rise:.2e}, energy at end "
              f"{energy[-1] / energy[0]:.6f} of start, min centre height {np.min(z):.4f} m")

elif case == "scales":
    r_tiny, r_huge = 1.0e-6, 1.0e4
    proc, out, h, wall = run_case("scales", (
        "&run title = 'scales 1e-6 m to 1e4 m', t_end = 0.05, dt_max = 1.0e-3, gravity = 0, 0, -9.81 /\n"
        f"&integrator events = '{loop}' /\n"
        "&contact restitution = 0.5 /\n&output interval = 0.005 /\n"
        f"&body name = 'planet', shape = 'sphere', radius = {r_huge!r}, density = 1000, position = 0, 0, {-r_huge!r}, "
        "fixed = .true. /\n"
        f"&body name = 'dust', shape = 'sphere', radius = {r_tiny!r}, density = 1000, position = 0, 0, {r_tiny + 1.0e-3!r} /\n"
        "&body name = 'ball', shape = 'sphere', radius = 1.0, density = 1000, position = 5, 0, 1.5 /\n"))
    found = smallest_separation(proc)
    c.check(found is not None, "the summary reports a smallest separation (contact found)")
    if found is not None:
        # auto: 1e-4 of the smallest moving body's size 2 r_tiny
        c.check(abs(found[1] - 2e-4 * r_tiny) < 1e-6 * 2e-4 * r_tiny, f"auto min_separation 1e-4 of 2 r_tiny: {found[1]:.3e} m")
    fr = frames(out)
    pos = np.array([b["position"].reshape(-1, 3) for _, b in fr])
    vel = np.array([b["velocity"].reshape(-1, 3) for _, b in fr])
    gaps_dust = np.linalg.norm(pos[:, 1] - [0, 0, -r_huge], axis=1) - r_huge - r_tiny
    gaps_ball = np.linalg.norm(pos[:, 2] - [0, 0, -r_huge], axis=1) - r_huge - 1.0
    c.check(float(np.min(gaps_dust)) > 0, f"dust never inside the planet (smallest gap {np.min(gaps_dust):.3e} m)")
    c.check(float(np.min(gaps_ball)) > 0, f"ball never inside the planet (smallest gap {np.min(gaps_ball):.3e} m)")
    # falling 1e-3 m takes 14 ms; by 50 ms the dust has bounced to rest (e = 0.5, rest_speed
    # auto 2 g dt_max = 0.02 m/s) and sits within the contact band (a few min_separation)
    c.check(int(h["events"][-1]) > 0, f"contact found: {int(h['events'][-1])} events")
    c.check(float(gaps_dust[-1]) < 10 * 2e-4 * r_tiny, f"dust at rest on the planet: final gap {gaps_dust[-1]:.3e} m")
    c.check(float(np.linalg.norm(vel[-1, 1])) < 1e-6, f"dust at rest: |v| {np.linalg.norm(vel[-1, 1]):.2e} m/s")
    c.check(wall < 60, f"finished in {wall:.1f} s (< 60 s)")
    proc_b, out_b, h_b, wall_b = run_case("scales_box", (
        "&run title = 'scales 1e-6 m on a 2e4 m box', t_end = 0.05, dt_max = 1.0e-3, gravity = 0, 0, -9.81 /\n"
        f"&integrator events = '{loop}' /\n"
        "&contact restitution = 0.5 /\n&output interval = 0.005 /\n"
        f"&body name = 'floor', shape = 'box', size = {2 * r_huge!r}, {2 * r_huge!r}, {2 * r_huge!r}, "
        f"position = 0, 0, {-r_huge!r}, fixed = .true. /\n"
        f"&body name = 'dust', shape = 'sphere', radius = {r_tiny!r}, density = 1000, position = 0, 0, {r_tiny + 1.0e-3!r} /\n"))
    c.check(smallest_separation(proc_b) is not None, "box floor: the summary reports a smallest separation (contact found)")
    pos_b = np.array([b["position"].reshape(-1, 3)[1] for _, b in frames(out_b)])
    # the floor's top is z = 0: the dust's bottom never below it
    c.check(float(np.min(pos_b[:, 2] - r_tiny)) > 0, f"box floor: dust never inside the floor (smallest gap {np.min(pos_b[:, 2] - r_tiny):.3e} m)")
    c.check(int(h_b["events"][-1]) > 0, f"box floor: contact found: {int(h_b['events'][-1])} events")
    print(f"scales_box: events {int(h_b['events'][-1])}, dust final gap {pos_b[-1, 2] - r_tiny:.3e} m")
    print(f"scales: events {int(h['events'][-1])}, dust final gap {gaps_dust[-1]:.3e} m, ball final gap {gaps_ball[-1]:.3e} m")
else:
    sys.exit(f"unknown case {case}")
c.finish()
