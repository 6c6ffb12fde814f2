#!/usr/bin/env python3
"""How often a decomposed gas must synchronise its ranks, measured on a real run, and what
that does to parallel efficiency at 2 to 1024 ranks (docs/benchmarks.md section 8, "A model
of the windows"; docs/architecture.md, "Cross-rank contacts").

1. Runs ricochet on one rank on the sphere gas of tools/bench_engines.py (5%, 1 m/s rms,
   e = 1, closed static box) with the event log on, and rebuilds every sphere's centre at
   every impact exactly from the initial state and the logged impulses (no gravity, spheres:
   a centre moves on a straight line between impacts).
2. Cuts the gas box into P bricks (slabs P x 1 x 1, and the 3-d dims MPI_Dims_create would
   choose) and counts, per simulated second:
   - cross impacts: two spheres whose centres lie in different bricks (the events that need
     two ranks: the only ones an exact optimistic window must stop at);
   - frontier impacts: impacts changing a body whose centre is within one grid box of a
     brick face (each makes the certificates other ranks hold with it stale: a window rule
     built only from certified bounds of pairs with a ghost ends at each of these).
3. Projects, for N bodies per rank (weak scaling) with the measured per-event cost, the
   efficiency of windows synchronised globally (one MPI_Allreduce per window, the issue's
   rule) and of windows synchronised with face neighbours only, each window costing the
   latencies given (defaults: this machine's measured allreduce and an InfiniBand-class
   cluster's, stated in the output).

    .venv/bin/python tools/window_model.py                       # 10,000 spheres, 0.5 s
    .venv/bin/python tools/window_model.py --n 2000 --t-end 0.5  # quick

Writes docs/bench/window_model.md (and prints it).
"""
import argparse
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_engines import gas_setup, SPHERE_R, RHO, WALL_T  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def run_gas(exe, n, t_end, work):
    s = gas_setup(n, 'sphere')
    L = s['L']
    lines = ["&run title='window model gas %d', t_end=%r, dt_max=1e-2 /" % (n, t_end),
             "&contact restitution=1.0 /",
             "&output write_frames=.false., event_log=.true., history_interval=%r /" % (t_end / 10)]
    # the spheres first, so that sphere k has global id k + 1; then the six walls
    for k in range(n):
        lines.append("&body name='b%d', shape='sphere', radius=%r, density=%r, position=%r,%r,%r, velocity=%r,%r,%r /"
                     % (k, SPHERE_R, RHO, *map(float, s['pos'][k]), *map(float, s['vel'][k])))
    for axis in range(3):
        for side in (-1, 1):
            size = [L + 2 * WALL_T] * 3
            size[axis] = WALL_T
            c = [L / 2] * 3
            c[axis] = L / 2 + side * (L / 2 + WALL_T / 2)
            lines.append("&body name='wall%d%+d', shape='box', size=%r,%r,%r, position=%r,%r,%r, fixed=.true. /"
                         % (axis, side, *map(float, size), *map(float, c)))
    deck = os.path.join(work, 'gas.nml')
    with open(deck, 'w') as f:
        f.write('\n'.join(lines) + '\n')
    out = os.path.join(work, 'out')
    t0 = time.perf_counter()
    proc = subprocess.run([exe, deck, '--output-dir', out], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(proc.stdout[-2000:] + proc.stderr[-2000:])
    text = proc.stdout
    # the grid box, from the start-up checks of `ricochet --check`
    check = subprocess.run([exe, '--check', deck], capture_output=True, text=True)
    found = re.search(r'grid box\s+([0-9.eE+-]+) m', check.stdout + check.stderr)
    if not found:
        sys.exit('no grid box in ricochet --check\'s output')
    box = float(found.group(1))
    hist_names = None
    with open(os.path.join(out, 'history.csv')) as f:
        hist_names = [c.strip().split(' [')[0] for c in f.readline().split(',')]
    hist = np.loadtxt(os.path.join(out, 'history.csv'), delimiter=',', skiprows=1, ndmin=2)
    col = {k: hist[:, hist_names.index(k)] for k in hist_names}
    events = np.loadtxt(os.path.join(out, 'events.csv'), delimiter=',', skiprows=1, ndmin=2)
    return s, box, events, col, wall


def centres_at_impacts(s, events, n):
    """Every impact as (time, centre of each body it changed): spheres move on straight lines
    between impacts, so the centre at an impact is x + v (t - t_last), then v += J / m."""
    x = s['pos'].copy()
    v = s['vel'].copy()
    t_last = np.zeros(n)
    m = s['mass']
    impacts = []          # (time, [gids], [centres])
    k = 0
    rows = len(events)
    while k < rows:
        t = events[k, 0]
        j = k
        while j < rows and events[j, 0] == t:
            j += 1
        gids = events[k:j, 1].astype(int)
        centres = []
        for r in range(k, j):
            i = int(events[r, 1]) - 1
            if i >= n:
                continue
            x[i] += v[i] * (t - t_last[i])
            t_last[i] = t
            centres.append(x[i].copy())
        for r in range(k, j):
            i = int(events[r, 1]) - 1
            if i < n:
                v[i] += events[r, 2:5] / m
        impacts.append((t, gids[gids <= n], np.array(centres)))
        k = j
    return impacts


def dims_create(p):
    """MPI_Dims_create's balanced 3-d factorisation (non-increasing)."""
    best = None
    for a in range(1, p + 1):
        if p % a:
            continue
        for b in range(1, p // a + 1):
            if (p // a) % b:
                continue
            c = p // a // b
            d = sorted((a, b, c), reverse=True)
            if best is None or (d[0], -d[2]) < (best[0], -best[2]):
                best = d
    return best


def count(impacts, L, dims, box, t_from, t_to):
    dims = np.array(dims)
    width = L / dims
    cross = frontier = total = 0
    for t, gids, centres in impacts:
        if t < t_from or t > t_to or len(centres) == 0:
            continue
        total += 1
        brick = np.minimum((centres // width).astype(int), dims - 1)
        if len(centres) > 1 and np.any(brick != brick[0]):
            cross += 1
        # distance to the nearest interior brick face, per axis
        near = False
        for a in range(3):
            if dims[a] == 1:
                continue
            f = centres[:, a] / width[a]
            d = np.abs(f - np.round(f)) * width[a]
            interior = (np.round(f) > 0) & (np.round(f) < dims[a])
            if np.any(interior & (d < box)):
                near = True
        frontier += near
    span = t_to - t_from
    return total / span, cross / span, frontier / span


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--t-end", type=float, default=0.5)
    ap.add_argument("--per-rank", type=int, default=50000, help="bodies per rank of the projection (weak scaling)")
    ap.add_argument("--event-cost", type=float, default=4.0e-5,
                    help="wall per event [s] (docs/benchmarks.md section 7: 100,000 spheres, second half)")
    ap.add_argument("--allreduce", type=float, default=1.5e-6,
                    help="allreduce latency per log2(P) [s] (cluster assumption)")
    ap.add_argument("--neighbour", type=float, default=2.0e-6, help="one neighbour message's latency [s] (cluster assumption)")
    ap.add_argument("--window-local", type=float, default=2.0e-5,
                    help="a window end's local work beyond messages (the cross event, ghost updates) [s]")
    ap.add_argument("--halo-full", type=float, default=1.5e-3,
                    help="a full two-ring halo exchange of 50,000 bodies per rank [s] (measured here: bench_window_cost, 2 ranks)")
    ap.add_argument("--exe", default=os.path.join(ROOT, "build", "app", "ricochet"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "bench", "window_model.md"))
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as work:
        s, box, events, col, wall = run_gas(args.exe, args.n, args.t_end, work)
    n = args.n
    L = s['L']
    impacts = centres_at_impacts(s, events, n)
    t_from = 0.5 * args.t_end   # the second half: the gas starts with every gap >= 5 mm
    lines = ["# How often a decomposed gas must synchronise (tools/window_model.py)", "",
             f"Machine: {platform.node()} ({os.cpu_count()} cores), {time.strftime('%Y-%m-%d')}. "
             f"Sphere gas of tools/bench_engines.py: {n} spheres (r = {SPHERE_R} m), box {L:.3f} m, 5%, 1 m/s rms, "
             f"e = 1, {args.t_end} s on one rank ({wall:.1f} s of process), grid box {box:.4g} m; "
             f"counted over the second half (t >= {t_from:g} s). Brick faces cut the gas box evenly.", "",
             "| ranks | bricks | impacts per s | cross impacts per s | share | frontier impacts per s | share | "
             "bodies per brick | box faces per brick face |",
             "|---|---|---|---|---|---|---|---|---|"]
    measured = []
    for p in (2, 4, 8, 16, 27, 64):
        for dims in ([p, 1, 1], dims_create(p)):
            if L / max(dims) < 2 * box:
                continue
            rate, cross, front = count(impacts, L, dims, box, t_from, args.t_end)
            area = (L / dims[1]) * (L / dims[2]) / box ** 2
            measured.append((p, tuple(dims), rate, cross, front))
            lines.append(f"| {p} | {dims[0]} x {dims[1]} x {dims[2]} | {rate:.0f} | {cross:.0f} | {cross / rate:.3%} | "
                         f"{front:.0f} | {front / rate:.1%} | {n // p} | {area:.0f} |")
            if dims == dims_create(p):
                break
    # per face of brick: cross and frontier impacts per second per unit face area (m^2),
    # from the slab cuts (each has p - 1 interior faces of area L^2)
    per_area_cross = np.mean([c / ((p - 1) * L * L) for p, d, r, c, f in measured if d == (p, 1, 1)])
    per_area_front = np.mean([f / ((p - 1) * L * L) for p, d, r, c, f in measured if d == (p, 1, 1)])
    rate_per_body = np.mean([r for p, d, r, c, f in measured]) / n

    lines += ["", f"Per square metre of brick face and simulated second: {per_area_cross:.0f} cross impacts, "
              f"{per_area_front:.0f} frontier impacts; {rate_per_body:.2f} impacts per body per second "
              "(the gas's density and speed fix these; a denser or faster gas scales them alike).", ""]

    # projection: weak scaling, cubic bricks of per_rank bodies at this gas's density
    nb = args.per_rank
    vol_per_body = L ** 3 / n
    edge = (nb * vol_per_body) ** (1.0 / 3.0)
    lines += [f"## Projection: {nb} bodies per rank (weak scaling), cubic bricks of {edge:.2f} m",
              "",
              f"Work per rank per simulated second: {rate_per_body * nb:.0f} impacts x {args.event_cost:.1e} s = "
              f"{rate_per_body * nb * args.event_cost:.2f} s. A window end costs its messages (global: an allreduce of "
              f"{args.allreduce * 1e6:.1f} us x log2 P; local: one message to each of 6 face neighbours, "
              f"{args.neighbour * 1e6:.1f} us each, overlapped 2 at a time) and {args.window_local * 1e6:.0f} us of "
              "local work (the cross event itself and the ghosts it changes). Windows end at every cross impact "
              "of the whole machine (global) or of the rank and its face neighbours (local); a rank waits at a "
              "window end for the slowest, which this model leaves out (it only lowers the figures). The column with a full "
              f"halo exchange adds {args.halo_full * 1e3:.1f} ms per window (two rings of 50,000 bodies per rank, measured "
              "on 2 ranks here): what windows cost if every window end sent every ghost again instead of the changed ones.", "",
              "| ranks | cross impacts per s, machine | global windows: per rank-second of work | events per window per rank | efficiency | "
              "the same with a full halo exchange per window | "
              "local windows: per rank-second | events per window per rank | efficiency |",
              "|---|---|---|---|---|---|---|---|---|"]
    work_rank = rate_per_body * nb * args.event_cost
    for p in (1, 2, 8, 64, 1024, 10 ** 5):
        dims = dims_create(p) if p <= 4096 else [round(p ** (1 / 3))] * 3
        interior_faces = sum((dims[a] - 1) * (dims[(a + 1) % 3] * dims[(a + 2) % 3]) for a in range(3))
        x_machine = interior_faces * edge * edge * per_area_cross
        faces_rank = min(6, 2 * interior_faces / max(p, 1)) if p > 1 else 0
        # a rank's window ends at cross impacts on its own faces and on its face neighbours'
        # (a neighbour's window end bounds what can reach this rank): at most 6 + 6 x 5 faces
        x_local = min(x_machine, min(faces_rank * 6, 36) * edge * edge * per_area_cross) if p > 1 else 0
        c_global = args.allreduce * max(1.0, math.log2(max(p, 2))) + args.window_local
        c_local = 3 * args.neighbour + args.window_local
        eff_g = work_rank / (work_rank + x_machine * c_global) if p > 1 else 1.0
        eff_l = work_rank / (work_rank + x_local * c_local) if p > 1 else 1.0
        ev_g = rate_per_body * nb / x_machine if x_machine else float('inf')
        ev_l = rate_per_body * nb / x_local if x_local else float('inf')
        eff_h = work_rank / (work_rank + x_machine * (c_global + args.halo_full)) if p > 1 else 1.0
        lines.append(f"| {p} | {x_machine:.3g} | {x_machine / work_rank if work_rank else 0:.3g} | {ev_g:.3g} | {eff_g:.2f} | {eff_h:.2f} | "
                     f"{x_local / work_rank if work_rank else 0:.3g} | {ev_l:.3g} | {eff_l:.2f} |")
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
