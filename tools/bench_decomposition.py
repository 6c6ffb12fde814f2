#!/usr/bin/env python3
"""What the domain decomposition costs per window, measured on a scene it decomposes today:
a lattice of spinning spheres and boxes all translating with one velocity under gravity
(no two bodies can meet, so every rank runs its own bricks; docs/architecture.md, "Domain
decomposition in a run"). The lattice crosses brick faces all the time, so every window
ends with a migration.

For each body count and rank count: wall time of the whole process, of the run and of its
start-up (both from the summary; the start-up is the slowest rank's), windows, bodies
migrated, migration messages and bytes, and the cost of a window's end from the summary's
`window ends` line: the slowest rank's wall time in window ends per window (the migration
with its waits, and the local loop brought up to date: `loop` is that part alone) and the
pair certificates computed at window ends per window (all ranks), against the run's
certificates (the summary's `pair certificates` line: rank 0's). Frames are off (outputs
only at the end).

    .venv/bin/python tools/bench_decomposition.py                    # 10^4 and 10^5 bodies, np 1 2 4
    .venv/bin/python tools/bench_decomposition.py --n 20000 --ranks 1 2
    .venv/bin/python tools/bench_decomposition.py --weak --n 50000 --ranks 1 2 4   # n per rank

Writes docs/bench/decomposition_windows.md (and prints it). np = 4 on this 2-core machine is
oversubscribed: reported, not a scaling figure.
"""
import argparse
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def deck_text(n, t_end, speed, stretch=1):
    # about n bodies: two lattices of 4k x 2k x k (spacing 0.3 m, x the longest axis, so
    # bricks are cut across x first), spheres and boxes interleaved; stretch: the lattice
    # that many times longer along x (weak scaling: n bodies per rank, stretch = ranks, so
    # every rank gets the same slab of the lattice)
    k = max(1, round((n / 16) ** (1 / 3)))
    nx, ny, nz = 4 * k * stretch, 2 * k, k
    return f"""&run
  title = 'decomposition windows, {2 * nx * ny * nz} bodies'
  t_end = {t_end}
  dt_max = 0.01
  gravity = 0.0, 0.0, -9.81
/
&output
  interval = {t_end}
  write_frames = .false.
/
&body
  name = 'balls', shape = 'sphere', radius = 0.05, density = 1000.0
  copies = {nx}, {ny}, {nz}, spacing = 0.3, 0.3, 0.3, position = 0.0, 0.0, 0.0
  velocity = {3.0 * speed}, {1.0 * speed}, {0.5 * speed}, angular_velocity = 1.0, 2.0, 3.0
/
&body
  name = 'boxes', shape = 'box', size = 0.1, 0.06, 0.04, density = 1000.0
  copies = {nx}, {ny}, {nz}, spacing = 0.3, 0.3, 0.3, position = 0.15, 0.15, 0.15
  velocity = {3.0 * speed}, {1.0 * speed}, {0.5 * speed}, angular_velocity = 4.0, 0.5, 2.0
  seed = 5, jitter_angle = 1.0
/
""", 2 * nx * ny * nz


def run(exe, deck, ranks, out):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpiexec", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), exe, deck, "--output-dir", out]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(cmd)}\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    text = proc.stdout
    get = lambda pattern, cast=float: cast(re.search(pattern, text).group(1)) if re.search(pattern, text) else None
    row = {
        "ranks": ranks,
        "process": wall,
        "wall": get(r"wall time\s+([0-9.eE+-]+) s"),
        "startup": get(r"start-up\s+([0-9.eE+-]+) s"),
        "windows": get(r"windows\s+(\d+) ended", int) or 0,
        "migrated": get(r"(\d+) bodies changed rank", int) or 0,
        "messages": get(r"(\d+) messages", int) or 0,
        "bytes": get(r"(\d+) bytes", int) or 0,
        "decomposed": "domain decomposition" in text,
        "dims": get(r"decomposition (\d+ x \d+ x \d+)", str),
        "window_wall": get(r"window ends\s+([0-9.eE+-]+) s"),
        "window_loop": get(r"brought up to date ([0-9.eE+-]+) s"),
        "window_certs": get(r"(\d+) pair certificates computed there", int),
        "certs": get(r"pair certificates\s+(\d+) \(", int),
    }
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, nargs="+", default=[10000, 100000])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--t-end", type=float, default=0.5)
    ap.add_argument("--speed", type=float, default=1.0, help="velocity (3, 1, 0.5) m/s times this")
    ap.add_argument("--weak", action="store_true",
                    help="weak scaling: --n bodies per rank, the lattice stretched along x by the rank count")
    ap.add_argument("--exe", default=os.path.join(ROOT, "build", "app", "ricochet"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "bench", "decomposition_windows.md"))
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="ricochet_decomp_")
    lines = ["# Domain decomposition: cost per window (tools/bench_decomposition.py)", "",
             ("Weak scaling: --n bodies per rank, the lattice stretched along x by the rank count. " if args.weak else "") +
             f"Machine: {platform.node()} ({os.cpu_count()} cores), {time.strftime('%Y-%m-%d')}; "
             f"t_end = {args.t_end} s, lattice velocity ({3 * args.speed:g}, {args.speed:g}, {0.5 * args.speed:g}) m/s, no frames. Stepping wall from the end-of-run summary.", "",
             "| bodies | ranks | bricks | process [s] | run wall [s] | start-up [s] | windows | bodies migrated | messages | bytes "
             "| per window [ms] | of it the loop [ms] | certificates per window | certificates in the run (rank 0) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n in args.n:
        for ranks in args.ranks:
            text, n_bodies = deck_text(n, args.t_end, args.speed, ranks if args.weak else 1)
            deck = os.path.join(work, f"free_{n}_{ranks}.nml")
            with open(deck, "w") as f:
                f.write(text)
            out = os.path.join(work, f"out_{n}_{ranks}")
            r = run(args.exe, deck, ranks, out)
            w = r["windows"]
            per = f"{1e3 * r['window_wall'] / w:.1f}" if w and r["window_wall"] is not None else "-"
            loop = f"{1e3 * r['window_loop'] / w:.1f}" if w and r["window_loop"] is not None else "-"
            certs = f"{r['window_certs'] / w:.0f}" if w and r["window_certs"] is not None else "-"
            startup = f"{r['startup']:.3f}" if r["startup"] is not None else "-"
            lines.append(f"| {n_bodies} | {ranks} | {r['dims'] or '1 (not split)'} | {r['process']:.2f} | {r['wall']:.3f} | {startup} | "
                         f"{w} | {r['migrated']} | {r['messages']} | {r['bytes']} | {per} | {loop} | {certs} | "
                         f"{r['certs'] if r['certs'] is not None else '-'} |")
            print(lines[-1], flush=True)
            shutil.rmtree(out, ignore_errors=True)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
