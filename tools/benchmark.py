#!/usr/bin/env python3
"""Run-time-against-error benchmarks for ricochet.

Runs the ricochet program on generated decks at several settings, measures each run
(CPU seconds of the child process and wall seconds, best of --repeat runs) and its error
against a reference, and writes a Markdown table and a PNG plot into docs/ (or --out-dir).

  .venv/bin/python tools/benchmark.py free-rotation   # error at T=20 s vs cost, per method and dt
  .venv/bin/python tools/benchmark.py throughput      # free-flight body updates per second, 1e3..1e6 bodies
  .venv/bin/python tools/benchmark.py bouncing-ball   # 10th apex error vs min_separation
  .venv/bin/python tools/benchmark.py cradle          # Newton's cradle velocity error vs min_separation
  .venv/bin/python tools/benchmark.py gas             # gas of spheres / cubes, cost vs number of bodies

The free-rotation case is the torque-free body with principal moments (1, 2, 3) kg m^2 and
w0 = (0.01, 5, 0.01) rad/s of tests/data/free_rotation_I123.csv (a thin plate with its
inertia set exactly through &body inertia).
"""
import argparse
import math
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_deck(exe, deck_text, workdir, repeat=1):
    """Runs a deck; returns (best cpu seconds, best wall seconds, output dir, stdout)."""
    deck = os.path.join(workdir, "bench.nml")
    with open(deck, "w") as f:
        f.write(deck_text)
    out_dir = os.path.join(workdir, "out")
    best_cpu = best_wall = float("inf")
    stdout = ""
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run([exe, deck, "--output-dir", out_dir], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode != 0:
            sys.exit(f"benchmark: ricochet failed on\n{deck_text}\n{proc.stderr}")
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best_cpu, best_wall = min(best_cpu, cpu), min(best_wall, wall)
        stdout = proc.stdout
    return best_cpu, best_wall, out_dir, stdout


def final_frame(out_dir):
    import h5py
    frames = sorted(f for f in os.listdir(os.path.join(out_dir, "frames")) if f.endswith(".h5"))
    with h5py.File(os.path.join(out_dir, "frames", frames[-1]), "r") as f:
        return {k: np.array(f["bodies"][k]) for k in f["bodies"].keys()}


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def quat_angle(a, b):
    """Angle of the rotation between two unit quaternions [rad]."""
    d = abs(float(np.dot(a, b)))
    return 2.0 * np.arccos(min(1.0, d)) if d < 1 - 1e-8 else 2.0 * np.linalg.norm(
        (a[0] * b[1:] - b[0] * a[1:] - np.cross(a[1:], b[1:])))


def machine_line():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def free_rotation(args):
    ref = np.loadtxt(os.path.join(ROOT, "tests", "data", "free_rotation_I123.csv"), delimiter=",", comments="#")
    header = open(os.path.join(ROOT, "tests", "data", "free_rotation_I123.csv")).readline()
    # columns: t, wx, wy, wz (body), qw, qx, qy, qz
    t_end = 20.0
    row = ref[np.argmin(abs(ref[:, 0] - t_end))]
    w_ref, q_ref = row[1:4], row[4:8]
    methods = args.methods.split(",")
    results = []
    for method in methods:
        dts = [float(x) for x in (args.exact_dts if method == "exact" else args.dts).split(",")]
        for dt in dts:
            deck = f"""&run title='free rotation I=(1,2,3)', t_end={t_end}, dt_max={dt!r}, gravity=0,0,0 /
&integrator rotation='{method}' /
&output interval={t_end}, checkpoint_interval=0 /
&body name='plate', shape='box', size=1.4142135623730951,1.0,0.01, mass=12.0, inertia=1.0,2.0,3.0,
      angular_velocity=0.01,5.0,0.01 /
"""
            with tempfile.TemporaryDirectory() as work:
                cpu, wall, out, stdout = run_deck(args.exe, deck, work, args.repeat)
                b = final_frame(out)
            m = re.search(r"integration time\s+([0-9.eE+-]+) s", stdout)
            t_int = float(m.group(1))
            q = b["orientation"].reshape(-1, 4)[0]
            w_world = b["angular_velocity"].reshape(-1, 3)[0]
            w_body = quat_to_matrix(q).T @ w_world
            err_w = float(np.max(np.abs(w_body - w_ref)))
            err_q = float(quat_angle(q, q_ref))
            results.append((method, dt, cpu, t_int, err_w, err_q))
            print(f"{method:8s} dt={dt:8.1e}  process cpu={cpu:8.3f}s integration={t_int:9.2e}s  "
                  f"|w-w_ref|={err_w:9.2e}  angle={err_q:9.2e}", flush=True)
    write_free_rotation_report(args, results, header)


def write_free_rotation_report(args, results, header):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for method in sorted(set(r[0] for r in results)):
        rs = [r for r in results if r[0] == method]
        ax.loglog([r[3] for r in rs], [max(r[4], r[5], 1e-16) for r in rs], "o-", label=method)
        for r in rs:
            ax.annotate(f"h={r[1]:.0e}", (r[3], max(r[4], r[5], 1e-16)), fontsize=7)
    ax.set_xlabel("integration time over 20 s of motion [s] (the run's own timer)")
    ax.set_ylabel("error at T = 20 s (max of |w - w_ref|, orientation angle)")
    ax.set_title("Free rotation, I = (1,2,3), w0 = (0.01, 5, 0.01)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    png = os.path.join(args.out_dir, "bench_free_rotation.png")
    fig.savefig(png, dpi=120, bbox_inches="tight")
    lines = ["| rotation | step h [s] | steps | integration time [s] | whole process CPU [s] | error in w at T [rad/s] | orientation error at T [rad] |",
             "|---|---|---|---|---|---|---|"]
    for m, dt, cpu, t_int, ew, eq in results:
        lines.append(f"| {m} | {dt:.0e} | {round(20.0 / dt)} | {t_int:.2e} | {cpu:.3f} | {ew:.2e} | {eq:.2e} |")
    table = "\n".join(lines)
    with open(os.path.join(args.out_dir, "bench_free_rotation.md"), "w") as f:
        f.write(f"Machine: {machine_line()}. Release build, best of {args.repeat} runs.\n"
                f"Reference: {header.strip()}\n\n{table}\n")
    print(table)
    print(f"wrote {png}")


def throughput(args):
    results = []
    for n_side in [int(x) for x in args.sides.split(",")]:
        n = n_side ** 3
        steps = max(10, int(args.updates / n))
        dt = 1.0e-3
        for method, shape, extra in [(m, s_, e) for m in args.methods.split(",")
                                     for s_, e in (("sphere", "radius=0.1"), ("box", "size=0.2,0.1,0.05"))]:
            deck = f"""&run title='throughput', t_end={steps * dt!r}, dt_max={dt!r}, gravity=0,0,-9.81 /
&integrator rotation='{method}' /
&output interval={steps * dt!r}, write_frames=.false., checkpoint_interval=0 /
&body name='gas', shape='{shape}', {extra}, density=1000, copies={n_side},{n_side},{n_side},
      spacing=1,1,1, angular_velocity=1,2,3, seed=5, jitter_velocity=1, jitter_angle=3 /
"""
            with tempfile.TemporaryDirectory() as work:
                cpu, wall, out, stdout = run_deck(args.exe, deck, work, 1)
            m = re.search(r"integration time\s+([0-9.eE+-]+) s", stdout)
            t_int = float(m.group(1)) if m else wall
            rate = n * steps / t_int
            results.append((method, shape, n, steps, t_int, wall, rate))
            print(f"{method:8s} {shape:6s} n={n:8d} steps={steps:6d} integration={t_int:8.3f}s wall={wall:8.3f}s "
                  f"-> {rate:10.3e} body updates/s", flush=True)
    lines = ["| rotation | shape | bodies | steps | integration [s] | whole run wall [s] | body updates per second |",
             "|---|---|---|---|---|---|---|"]
    for method, shape, n, steps, t_int, wall, rate in results:
        lines.append(f"| {method} | {shape} | {n} | {steps} | {t_int:.3f} | {wall:.3f} | {rate:.3e} |")
    table = "\n".join(lines)
    with open(os.path.join(args.out_dir, "bench_throughput.md"), "w") as f:
        f.write(f"Machine: {machine_line()}. Release build, one rank.\n\n{table}\n")
    print(table)


def bouncing_ball(args):
    """Apex of the 10th bounce against the ideal (contact at zero distance) as the minimum
    separation varies: the error is the price of the separation, the cost barely moves."""
    g, e, r, z0 = 9.81, 0.8, 0.1, 1.1
    h_ideal = (z0 - r) * e ** 20
    t10 = math.sqrt(2 * (z0 - r) / g) * (1 + 2 * sum(e ** k for k in range(1, 10)))
    results = []
    for delta in [float(x) for x in args.separations.split(",")]:
        deck = f"""&run title='bouncing ball', t_end={t10 + e ** 10 * math.sqrt(2 * g * (z0 - r)) / g!r}, dt_max=1e-2, gravity=0,0,-9.81 /
&contact restitution=0.8, min_separation={delta!r} /
&output interval={t10 + e ** 10 * math.sqrt(2 * g * (z0 - r)) / g!r} /
&body name='floor', shape='box', size=2,2,0.2, position=0,0,-0.1, fixed=.true. /
&body name='ball', shape='sphere', radius=0.1, density=1000, position=0,0,{z0} /
"""
        with tempfile.TemporaryDirectory() as work:
            cpu, wall, out, stdout = run_deck(args.exe, deck, work, args.repeat)
            import h5py
            names = sorted(f for f in os.listdir(os.path.join(out, "frames")) if f.endswith(".h5"))
            with h5py.File(os.path.join(out, "frames", names[-1]), "r") as f:
                z = float(np.array(f["bodies"]["position"])[1, 2])
                vz = float(np.array(f["bodies"]["velocity"])[1, 2])
        apex = z + vz * vz / (2 * g) - r
        err = abs(apex - h_ideal) / h_ideal
        events = int(re.search(r"contact events\s+(\d+)", stdout).group(1))
        results.append((delta, cpu, wall, events, err))
        print(f"min_separation={delta:8.1e} cpu={cpu:6.3f}s events={events} apex-10 error vs ideal={err:9.2e}", flush=True)
    lines = ["| min_separation [m] | whole process CPU [s] | events | relative error of the 10th apex vs contact at zero distance |",
             "|---|---|---|---|"]
    for delta, cpu, wall, events, err in results:
        lines.append(f"| {delta:.0e} | {cpu:.3f} | {events} | {err:.2e} |")
    table = "\n".join(lines)
    with open(os.path.join(args.out_dir, "bench_bouncing_ball.md"), "w") as f:
        f.write(f"Machine: {machine_line()}. Release build, best of {args.repeat} runs.\n\n{table}\n")
    print(table)


def cradle(args):
    """Newton's cradle (input/validation/newtons_cradle.nml with every gap set to the
    minimum separation): error of the final velocities against the ideal (0, 0, 0, 0, 1) m/s
    as min_separation varies, and what the run costs."""
    r, v0 = 0.1, 1.0
    ideal = np.zeros((5, 3))
    ideal[4, 0] = v0
    results = []
    for delta in [float(x) for x in args.separations.split(",")]:
        # Same layout as the validation deck: every ball delta from the next (inside the
        # contact band), the striker at 1 m/s; only the last ball moves afterwards.
        deck = f"""&run title="Newton's cradle", t_end=1.0, dt_max=1.0e-2 /
&contact restitution=1.0, min_separation={delta!r} /
&output interval=1.0, checkpoint_interval=0 /
&body name='striker', shape='sphere', radius={r!r}, density=1000.0, position={-3 * r!r},0,0, velocity={v0!r},0,0 /
&body name='row', shape='sphere', radius={r!r}, density=1000.0, position={-r + delta!r},0,0,
      copies=4,1,1, spacing={2 * r + delta!r},0,0 /
"""
        with tempfile.TemporaryDirectory() as work:
            cpu, wall, out, stdout = run_deck(args.exe, deck, work, args.repeat)
            b = final_frame(out)
        v = b["velocity"].reshape(-1, 3)
        err = float(np.max(np.abs(v - ideal)))
        m = re.search(r"contact events\s+(\d+) \((\d+) contact points, (\d+) impulse groups", stdout)
        events, points, groups = (int(m.group(k)) for k in (1, 2, 3))
        results.append((delta, cpu, wall, events, groups, err))
        print(f"min_separation={delta:8.1e} cpu={cpu:6.3f}s wall={wall:6.3f}s events={events} groups={groups} "
              f"max |v - (0,0,0,0,1)|={err:9.2e}", flush=True)
    lines = ["| min_separation [m] | whole process CPU [s] | events | impulse groups | largest error of the final velocities vs (0,0,0,0,1) [m/s] |",
             "|---|---|---|---|---|"]
    for delta, cpu, wall, events, groups, err in results:
        lines.append(f"| {delta:.0e} | {cpu:.3f} | {events} | {groups} | {err:.1e} |")
    table = "\n".join(lines)
    with open(os.path.join(args.out_dir, "bench_cradle.md"), "w") as f:
        f.write(f"Machine: {machine_line()}. Release build, best of {args.repeat} runs.\n\n{table}\n")
    print(table)


def gas(args):
    """Dilute gas of spheres or cubes in a closed static box, e = 1, no gravity: cost per
    simulated second against the number of bodies, and the growth exponent."""
    rng = np.random.default_rng(7)
    results = []
    for shape in ("sphere", "box"):
        for n in [int(x) for x in args.gas_sizes.split(",")]:
            side = round(n ** (1 / 3))
            n = side ** 3
            edge = 0.1
            spacing = edge / 0.05 ** (1 / 3)         # volume fraction ~5% of the lattice cell
            length = side * spacing
            body = (f"shape='sphere', radius={edge / 2}" if shape == "sphere" else f"shape='box', size={edge},{edge},{edge}")
            wall = 0.2
            walls = []
            for axis in range(3):
                for sign in (-1, 1):
                    size = [length + 2 * wall] * 3
                    size[axis] = wall
                    pos = [length / 2] * 3
                    pos[axis] = length / 2 + sign * (length / 2 + wall / 2 + spacing / 4)
                    walls.append(f"&body name='wall{axis}{sign:+d}', shape='box', size={size[0]},{size[1]},{size[2]}, "
                                 f"position={pos[0]},{pos[1]},{pos[2]}, fixed=.true. /")
            t_end = args.gas_time
            deck = f"""&run title='gas', t_end={t_end!r}, dt_max=1e-2 /
&contact restitution=1.0 /
&output write_frames=.false., history_interval={t_end!r} /
&body name='gas', {body}, density=1000, copies={side},{side},{side}, spacing={spacing},{spacing},{spacing},
      position={spacing / 2},{spacing / 2},{spacing / 2}, velocity=0,0,0, seed=11, jitter_velocity=1.0,
      jitter_angle=3.0, jitter_position={0.2 * spacing} /
""" + "\n".join(walls) + "\n"
            with tempfile.TemporaryDirectory() as work:
                t0 = time.perf_counter()
                cpu, wall_s, out, stdout = run_deck(args.exe, deck, work, 1)
            events = int(re.search(r"contact events\s+(\d+)", stdout).group(1))
            sep = re.search(r"smallest separation\s+([0-9.eE+-]+)", stdout)
            results.append((shape, n, cpu / t_end, events, float(sep.group(1)) if sep else float("nan")))
            print(f"{shape:6s} n={n:7d} cpu per simulated s={cpu / t_end:9.3f} events={events} "
                  f"smallest separation={results[-1][4]:.2e}", flush=True)
    lines = ["| shape | bodies | CPU per simulated second [s] | events | smallest separation [m] |", "|---|---|---|---|---|"]
    for shape, n, c, ev, sep in results:
        lines.append(f"| {shape} | {n} | {c:.3f} | {ev} | {sep:.2e} |")
    for shape in ("sphere", "box"):
        rs = [r for r in results if r[0] == shape and r[2] > 0]
        if len(rs) >= 2:
            slope = np.polyfit(np.log([r[1] for r in rs]), np.log([r[2] for r in rs]), 1)[0]
            lines.append(f"\n{shape}: cost grows like n^{slope:.2f}")
    table = "\n".join(lines)
    with open(os.path.join(args.out_dir, "bench_gas.md"), "w") as f:
        f.write(f"Machine: {machine_line()}. Release build, one rank, {args.gas_time} s simulated.\n\n{table}\n")
    print(table)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("case", choices=["free-rotation", "throughput", "bouncing-ball", "cradle", "gas"])
    p.add_argument("--separations", default="1e-3,1e-4,1e-5,1e-6,1e-7,1e-8")
    p.add_argument("--gas-sizes", default="125,1000,8000")
    p.add_argument("--gas-time", type=float, default=0.5)
    p.add_argument("--exe", default=os.path.join(ROOT, "build", "app", "ricochet"))
    p.add_argument("--out-dir", default=os.path.join(ROOT, "docs", "bench"))
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--methods", default="newmark,exact")
    p.add_argument("--dts", default="1e-2,3e-3,1e-3,3e-4,1e-4,3e-5,1e-5", help="steps for newmark")
    p.add_argument("--exact-dts", default="20,1,1e-1,1e-2,1e-3,1e-4", help="steps for exact")
    p.add_argument("--sides", default="10,22,46,100", help="lattice sides: n = side^3 bodies")
    p.add_argument("--updates", type=float, default=1e7, help="body updates per run")
    args = p.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    {"free-rotation": free_rotation, "throughput": throughput, "bouncing-ball": bouncing_ball,
     "cradle": cradle, "gas": gas}[args.case](args)


if __name__ == "__main__":
    main()
