#!/usr/bin/env python3
"""Closest-point benchmark: ricochet's SKD-tree distance query against coal (the successor
of FCL; BVHModelOBBRSS, coal.distance) on the same meshes and the same poses.

Steps: compile tools/bench/bench_closest_points.f90 against a Release build (default
build-rel/, or the folder given with --build), run it (it writes the meshes as OBJ, the
poses and its own timings into a work folder), then time coal on each pose and print a
Markdown table with both times and their ratio, and whether the distances agree.

    .venv/bin/python tools/bench_closest_points.py [--build build-rel] [--work /tmp/bench]

coal is installed with `.venv/bin/pip install coal`. Both are timed in a loop of at least
0.05 s per pose, each side --repeat times (default 3), keeping the fastest run, since the
machine may be shared; coal's times include the Python call overhead (about 1-2 us, measured and
printed), which matters only for the smallest meshes.
"""
import argparse
import csv
import os
import subprocess
import sys
import time
from collections import defaultdict

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def load_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == 'v':
                verts.append([float(v) for v in parts[1:4]])
            elif parts[0] == 'f':
                faces.append([int(v) - 1 for v in parts[1:4]])
    return np.array(verts), np.array(faces, dtype=np.int64)


def coal_model(coal, verts, faces):
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(faces), len(verts))
    model.addVertices(np.ascontiguousarray(verts, dtype=np.float64))
    model.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    model.endModel()
    return model


def build_bench(build, exe):
    src = os.path.join(ROOT, 'tools', 'bench', 'bench_closest_points.f90')
    cmd = ['gfortran', '-O3', '-funroll-loops', '-ffree-line-length-none', '-std=f2018',
           '-I', os.path.join(build, 'modules'), src,
           os.path.join(build, 'tests', 'libricochet_testing.a'),
           os.path.join(build, 'src', 'libricochet_core.a'), '-o', exe]
    subprocess.run(cmd, check=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--build', default=os.path.join(ROOT, 'build-rel'))
    parser.add_argument('--work', default='/tmp/ricochet_bench_closest_points')
    parser.add_argument('--skip-run', action='store_true', help='reuse the Fortran results in --work')
    parser.add_argument('--repeat', type=int, default=3,
                        help='runs of each side; the fastest is kept (the machine may be shared)')
    args = parser.parse_args()
    import coal

    os.makedirs(args.work, exist_ok=True)
    exe = os.path.join(args.work, 'bench_closest_points')
    if not args.skip_run:
        build_bench(args.build, exe)
        for run in range(args.repeat):
            subprocess.run([exe, args.work], check=True, stdout=subprocess.DEVNULL)
            os.replace(os.path.join(args.work, 'ricochet_times.csv'),
                       os.path.join(args.work, f'ricochet_times_{run}.csv'))

    ours = {}
    for run in range(args.repeat):
        with open(os.path.join(args.work, f'ricochet_times_{run}.csv')) as f:
            for row in csv.DictReader(f):
                key = (int(row['case']), float(row['gap']), int(row['pose']))
                if key not in ours or float(row['time_us']) < float(ours[key]['time_us']):
                    ours[key] = row

    models = {}
    request = coal.DistanceRequest()
    result = coal.DistanceResult()
    # Python overhead of one coal.distance call: two far-apart tiny boxes.
    box = coal.Box(0.1, 0.1, 0.1)
    t_far = coal.Transform3s(np.eye(3), np.array([10.0, 0.0, 0.0]))
    t_id = coal.Transform3s()
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        coal.distance(box, t_id, box, t_far, request, result)
    overhead_us = (time.perf_counter() - t0) / n * 1e6

    rows = defaultdict(list)
    with open(os.path.join(args.work, 'poses.txt')) as f:
        for line in f:
            parts = line.split()
            case, name_a, name_b, gap, pose = int(parts[0]), parts[1], parts[2], float(parts[3]), int(parts[4])
            vals = np.array([float(v) for v in parts[5:]])
            xa, qa, xb, qb = vals[0:3], vals[3:7], vals[7:10], vals[10:14]
            for name in (name_a, name_b):
                if name not in models:
                    models[name] = coal_model(coal, *load_obj(os.path.join(args.work, name + '.obj')))
            ta = coal.Transform3s(quat_to_matrix(qa), xa)
            tb = coal.Transform3s(quat_to_matrix(qb), xb)
            ma, mb = models[name_a], models[name_b]
            t_coal = float('inf')
            for run in range(args.repeat):
                reps = 0
                t0 = time.perf_counter()
                while True:
                    for _ in range(5):
                        result.clear()
                        coal.distance(ma, ta, mb, tb, request, result)
                    reps += 5
                    elapsed = time.perf_counter() - t0
                    if elapsed > 0.05:
                        break
                t_coal = min(t_coal, elapsed / reps * 1e6)
            ref = ours[(case, gap, pose)]
            d_ours = float(ref['distance'])
            d_coal = result.min_distance
            rows[(case, gap)].append(dict(name_a=name_a, name_b=name_b, fa=int(ref['faces_a']), fb=int(ref['faces_b']),
                                          t_ours=float(ref['time_us']), t_brute=float(ref['brute_time_us']),
                                          t_coal=t_coal, d_ours=d_ours, d_coal=d_coal,
                                          prims=int(ref['primitive_tests'])))

    print(f'coal {getattr(coal, "__version__", "?")}; Python call overhead of coal.distance: {overhead_us:.2f} us\n')
    print('| meshes (triangles) | gap [m] | ricochet [us] | coal [us] | coal / ricochet | brute force [us] '
          '| speed-up vs brute | primitive tests | max rel. diff. in distance |')
    print('|---|---|---|---|---|---|---|---|---|')
    for (case, gap), lst in sorted(rows.items()):
        t_ours = np.mean([r['t_ours'] for r in lst])
        t_coal = np.mean([r['t_coal'] for r in lst])
        brute = [r['t_brute'] for r in lst if r['t_brute'] > 0]
        t_brute = f'{brute[0]:.0f}' if brute else '-'
        speedup = f'{brute[0] / lst[0]["t_ours"]:.0f}' if brute else '-'
        diff = max(abs(r['d_ours'] - r['d_coal']) / max(r['d_coal'], 1e-300) for r in lst)
        r0 = lst[0]
        print(f'| {r0["name_a"]} ({r0["fa"]}) / {r0["name_b"]} ({r0["fb"]}) | {gap:g} | {t_ours:.1f} | {t_coal:.1f} '
              f'| {t_coal / t_ours:.2f} | {t_brute} | {speedup} | {np.mean([r["prims"] for r in lst]):.0f} | {diff:.1e} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
