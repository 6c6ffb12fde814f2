#!/usr/bin/env python3
"""Cross-rank windows (docs/architecture.md, "Cross-rank contacts: windows with ghosts") on
the scene they are built for: a gas of spheres (radius 0.05 m, 5% by volume, e = 1, no
gravity, rms speed 1 m/s) in a closed box of six static walls, the sites of a jittered
lattice taken at random (seeded). For each body count and rank count: the whole process's
wall time, the run's (summary) with its start-up (reading the deck, start-up checks, the
loop's set-up) and what follows it (the windows and the final checkpoint), the windows,
how many were run again to an earlier time and how many ended in a cross phase, the
ghosts sent back, the slowest rank's wall in window starts and in repeated runs, and
whether the final bodies are bit for bit those of one rank (checkpoint_final.h5, every
body dataset).

    .venv/bin/python tools/bench_cross_windows.py                       # 1000 and 8000, np 1 2
    .venv/bin/python tools/bench_cross_windows.py --n 27000 --ranks 1 2 4 --t-end 0.1
    .venv/bin/python tools/bench_cross_windows.py --n 27000 --skin 0 --out /tmp/skin0.md   # &parallel skin = 0

Writes docs/bench/cross_windows.md (and prints it). np = 4 on a 2-core machine is
oversubscribed: reported, not a scaling figure.
"""
import argparse
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "regression"))
from ricochet_run import box_walls  # noqa: E402

RADIUS, GAP, PHI, WALL = 0.05, 0.005, 0.05, 0.2


def deck_text(n, t_end, seed, skin=None):
    rng = np.random.default_rng(seed)
    box = (n * 4.0 / 3.0 * math.pi * RADIUS ** 3 / PHI) ** (1.0 / 3.0)
    m = int(box / (2 * RADIUS + 2 * GAP))
    sites = np.array([[i, j, k] for i in range(m) for j in range(m) for k in range(m)], float)
    sites = sites[np.sort(rng.choice(len(sites), n, replace=False))]
    pos = (sites + 0.5) * (box / m) + rng.uniform(-GAP / 2, GAP / 2, (n, 3))
    vel = rng.normal(size=(n, 3))
    vel -= vel.mean(axis=0)
    vel *= 1.0 / math.sqrt(np.mean(np.sum(vel ** 2, axis=1)))
    lines = [f"&run title = 'sphere gas {n}', t_end = {t_end!r}, dt_max = 1.0e-2 /",
             "&contact restitution = 1.0 /", f"&output write_frames = .false., interval = {t_end!r} /"]
    if skin is not None:
        lines.append(f"&parallel skin = {skin!r} /")
    lines += box_walls(box, WALL)
    for k in range(n):
        lines.append("&body name = 'b%d', shape = 'sphere', radius = %r, density = 1000.0, position = %r, %r, %r, "
                     "velocity = %r, %r, %r /" % (k, RADIUS, *map(float, pos[k]), *map(float, vel[k])))
    return "\n".join(lines) + "\n"


def run(exe, deck, ranks, out):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpiexec", "-n", str(ranks), "--oversubscribe", exe, deck, "--output-dir", out]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"{ranks} ranks failed: {proc.stderr[-800:]}")
    text = proc.stdout
    row = {"process": wall}
    m = re.search(r"wall time\s+([0-9.E+-]+) s", text)
    row["run"] = float(m.group(1)) if m else float("nan")
    m = re.search(r"start-up\s+([0-9.E+-]+) s", text)
    row["startup"] = float(m.group(1)) if m else float("nan")
    m = re.search(r"cross-rank windows\s+(\d+) \((\d+) run again.*?, (\d+) of them ending in a cross phase \([^)]*\), "
                  r"(\d+) ghosts sent back", text)
    row["windows"] = tuple(int(x) for x in m.groups()) if m else None
    m = re.search(r"window costs\s+([0-9.E+-]+) s starting windows.*?, ([0-9.E+-]+) s in runs repeated", text)
    row["costs"] = (float(m.group(1)), float(m.group(2))) if m else None
    m = re.search(r"contact events\s+(\d+)", text)
    row["events"] = int(m.group(1)) if m else 0
    return row


def same_bodies(a, b):
    with h5py.File(a, "r") as x, h5py.File(b, "r") as y:
        return all(np.array_equal(x["bodies"][k][()], y["bodies"][k][()]) for k in x["bodies"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[1000, 8000])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--t-end", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--skin", type=float, default=None, help="&parallel skin [m] (default: the deck's auto)")
    ap.add_argument("--exe", default=os.path.join(ROOT, "build", "app", "ricochet"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "bench", "cross_windows.md"))
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="cross_windows_")
    lines = ["# Cross-rank windows: a sphere gas on 1 and more ranks", "",
             f"Generated by tools/bench_cross_windows.py on {platform.node()} ({os.cpu_count()} cores), "
             f"{time.strftime('%Y-%m-%d')}: radius 0.05 m, 5% by volume, e = 1, no gravity, t_end = {args.t_end} s, "
             f"&parallel skin {'auto' if args.skin is None else repr(args.skin) + ' m'}, one run each.", "",
             "| bodies | ranks | process [s] | run [s] | start-up [s] | run after start-up [s] | events | windows | "
             "run again | ending in a cross phase | ghosts sent back | window starts [s] | repeated runs [s] | "
             "final bodies = 1 rank |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n in args.n:
        deck = os.path.join(work, f"gas_{n}.nml")
        with open(deck, "w") as f:
            f.write(deck_text(n, args.t_end, args.seed, args.skin))
        one = None
        for ranks in args.ranks:
            out = os.path.join(work, f"out_{n}_{ranks}")
            shutil.rmtree(out, ignore_errors=True)
            row = run(args.exe, deck, ranks, out)
            final = os.path.join(out, "checkpoint_final.h5")
            if one is None:
                one = final
            same = "yes" if same_bodies(one, final) else "NO"
            w = row["windows"] or ("-",) * 4
            c = row["costs"] or (float("nan"),) * 2
            lines.append(f"| {n} | {ranks} | {row['process']:.2f} | {row['run']:.2f} | {row['startup']:.2f} | "
                         f"{row['run'] - row['startup']:.2f} | {row['events']} | {w[0]} | "
                         f"{w[1]} | {w[2]} | {w[3]} | {c[0]:.3f} | {c[1]:.3f} | {same} |")
            print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write(text)
    print(text)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
