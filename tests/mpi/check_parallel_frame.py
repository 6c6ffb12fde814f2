"""Checks the frames mpi.test_parallel_output wrote from two ranks (h5py, serial read):
rows of rank 0 then rank 1, triangle indices offset by the points of the lower ranks, every
triangle on the surface of its own body, point velocities v + w x r.

Usage: check_parallel_frame.py OUTPUT_DIR. The body values repeat body_values() of the test."""
import sys

import h5py
import numpy as np

# Values computed from the same f64 inputs with a few more roundings: 1e-12 m is far below
# any indexing error (neighbouring bodies are 1 m apart).
TOL = 1e-12
BOX = np.array([[sx * 0.1, sy * 0.2, sz * 0.3] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL: " + what)


def expected(gid):
    g = float(gid)
    return np.array([g, 2 * g, -g / 3]), np.array([0.1 * g, 0, 0]), np.array([0, 0, g])


def check_frame(path, gids):
    with h5py.File(path, "r") as f:
        check(f.attrs["format"] == b"ricochet-frame", f"{path}: format attribute")
        check(list(f["bodies/gid"][:]) == gids, f"{path}: gid rows {list(f['bodies/gid'][:])} != {gids}")
        check(list(f["bodies/vertex"][:]) == list(range(len(gids))), f"{path}: vertex is not 0..n-1")
        for row, gid in enumerate(gids):
            x, v, w = expected(gid)
            check(np.allclose(f["bodies/position"][row], x, rtol=0, atol=TOL), f"{path}: position of body {gid}")
            check(np.allclose(f["bodies/velocity"][row], v, rtol=0, atol=TOL), f"{path}: velocity of body {gid}")
            name = f["bodies/name"][row].decode()
            check(name == ("odd" if gid % 2 else "even"), f"{path}: name of body {gid} is {name!r}")
        points = f["surface/points"][:]
        velocity = f["surface/velocity"][:]
        triangles = f["surface/triangles"][:]
        body_id = f["surface/body_id"][:]
        check(triangles.min() == 0 and triangles.max() == len(points) - 1, f"{path}: triangle indices out of range")
        check(len(np.unique(triangles)) == len(points), f"{path}: some points belong to no triangle")
        for gid in gids:
            x, v, w = expected(gid)
            ids = np.unique(triangles[body_id == gid])
            arm = points[ids] - x
            if gid == 4:
                ok = len(ids) == 8 and all(np.min(np.abs(BOX - a).max(axis=1)) < TOL for a in arm)
                check(ok, f"{path}: box corners of body 4 misplaced")
            else:
                check(len(ids) == 162 and np.allclose(np.linalg.norm(arm, axis=1), 0.25, rtol=0, atol=TOL),
                      f"{path}: sphere {gid}: points not at 0.25 m from its centre")
            check(np.allclose(velocity[ids], v + np.cross(w, arm), rtol=0, atol=TOL),
                  f"{path}: point velocities of body {gid}")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "output"
    check_frame(out + "/frames/frame_000000.h5", [1, 3, 5, 2, 4])
    check_frame(out + "/frames/frame_000001.h5", [5, 4, 3, 2, 1])
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("frames written from two ranks hold every body in place")
    return 0


if __name__ == "__main__":
    sys.exit(main())
