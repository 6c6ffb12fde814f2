"""Comparisons of two runs' output directories for the MPI checks: what "the same files"
means for frames, history and checkpoints on any number of ranks (check_decomposition.py
says why each exception is there). Each function records its checks in c (Checks)."""
import filecmp
import os

import h5py
import numpy as np

SAMPLED_ATTRS = {"n_ranks", "wall_time_before"}
SAMPLED_COUNTERS = {b"pair_tests", b"min_separation"}
SAMPLED_COLUMNS = {13, 17}     # wall_time [s], min_separation [m] (0-based)


def same_checkpoint(c, a, b, what, sampled_counters=SAMPLED_COUNTERS):
    with h5py.File(a, "r") as x, h5py.File(b, "r") as y:
        def walk(g, h, path):
            for k, v in g.attrs.items():
                if k in SAMPLED_ATTRS:
                    continue
                c.check(k in h.attrs and np.asarray(v).tobytes() == np.asarray(h.attrs[k]).tobytes(),
                        f"{what}: attribute {path}/{k}")
            c.check(sorted(g.keys()) == sorted(h.keys()), f"{what}: the same datasets in {path}/")
            for k in g:
                if k not in h:
                    continue
                if isinstance(g[k], h5py.Group):
                    walk(g[k], h[k], path + "/" + k)
                    continue
                u, w = g[k][()], h[k][()]
                if path + "/" + k == "/meta/counters":
                    names = list(g["counter_names"][()])
                    keep = [i for i, n in enumerate(names) if n not in sampled_counters]
                    u, w = u[keep], w[keep]
                c.check(u.shape == w.shape and u.tobytes() == w.tobytes(), f"{what}: dataset {path}/{k} bit for bit")
        walk(x, y, "")


def same_history(c, a, b, what, from_time=None, sampled_columns=SAMPLED_COLUMNS):
    ra = [l.rstrip("\n").split(",") for l in open(os.path.join(a, "history.csv"))][1:]
    rb = [l.rstrip("\n").split(",") for l in open(os.path.join(b, "history.csv"))][1:]
    strip = lambda rows: [[x for i, x in enumerate(r) if i not in sampled_columns] for r in rows]
    c.check(strip(ra) == strip(rb), f"{what}: history.csv the same rows (but wall time, min_separation)")


def same_frames(c, a, b, what, first=0):
    names = sorted(os.listdir(os.path.join(a, "frames")))
    other = sorted(os.listdir(os.path.join(b, "frames")))
    c.check(names == other, f"{what}: the same frame files ({len(names)} against {len(other)})")
    for name in names[first:]:
        if name in other:
            c.check(filecmp.cmp(os.path.join(a, "frames", name), os.path.join(b, "frames", name), shallow=False),
                    f"{what}: frames/{name} cmp-identical")
    for name in ("bodies.xmf", "surfaces.xmf"):
        c.check(filecmp.cmp(os.path.join(a, name), os.path.join(b, name), shallow=False), f"{what}: {name} identical")
