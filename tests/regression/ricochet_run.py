"""Helpers for regression checks that run the ricochet program: run a deck, read frames,
history and checkpoints. Each check script counts failures and exits non-zero on any."""
import os
import re
import subprocess
import sys

import h5py
import numpy as np


class Checks:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def check(self, condition, what):
        if condition:
            self.passed += 1
        else:
            self.failed += 1
            print("FAIL: " + what, flush=True)

    def finish(self):
        print(f"{self.passed} passed, {self.failed} failed")
        sys.exit(1 if self.failed else 0)


def box_walls(box, wall):
    """&body lines of six fixed walls of thickness `wall` [m] around the cube [0, box]^3."""
    lines = []
    for axis in range(3):
        for side in (-1, 1):
            size = [box + 2 * wall] * 3
            size[axis] = wall
            centre = [box / 2] * 3
            centre[axis] = box / 2 + side * (box / 2 + wall / 2)
            lines.append(f"&body name = 'wall{axis}{side:+d}', shape = 'box', size = %r, %r, %r, "
                         "position = %r, %r, %r, fixed = .true. /" % (*size, *centre))
    return lines


def run(exe, deck, out_dir, *extra, expect_ok=True):
    """Runs ricochet; returns the completed process (stdout, stderr, returncode)."""
    cmd = [exe, deck, "--output-dir", out_dir, *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if expect_ok and proc.returncode != 0:
        print(proc.stdout)
        print(proc.stderr)
        sys.exit(f"ricochet failed ({proc.returncode}): {' '.join(cmd)}")
    return proc


def smallest_separation(proc):
    """(smallest gap ever computed, min_separation) [m] from the end-of-run summary, or None
    when no two bodies ever came near. The method's guarantee: the first is never below half
    the second."""
    for line in proc.stdout.splitlines():
        m = re.search(r"smallest separation\s+([0-9.eE+-]+) m \(minimum separation\s+([0-9.eE+-]+) m\)", line)
        if m:
            return float(m.group(1)), float(m.group(2))
    return None


def check_separation_floor(checks, proc):
    """The guarantee, on every run that reports it: no gap below min_separation/2."""
    found = smallest_separation(proc)
    if found is not None:
        smallest, target = found
        checks.check(smallest >= 0.5 * target * (1.0 - 1e-9),
                     f"no gap ever below min_separation/2: smallest {smallest:.4e} m, min_separation {target:.4e} m")


def frames(out_dir):
    """All frames in time order: list of (time, {dataset: array}) of /bodies."""
    names = sorted(f for f in os.listdir(os.path.join(out_dir, "frames")) if f.endswith(".h5"))
    result = []
    for name in names:
        with h5py.File(os.path.join(out_dir, "frames", name), "r") as f:
            order = np.argsort(np.array(f["bodies"]["gid"]))
            data = {k: np.array(f["bodies"][k])[order] for k in f["bodies"].keys()}
            result.append((float(f.attrs["time"]), data))
    return result


def checkpoint(path):
    """Attributes and /bodies datasets (gid order) of a checkpoint."""
    with h5py.File(path, "r") as f:
        attrs = {k: f.attrs[k] for k in f.attrs.keys()}
        group = f["bodies"]
        order = np.argsort(np.array(group["gid"]))
        bodies = {k: np.array(group[k])[order] for k in group.keys()}
    return attrs, bodies


def history(out_dir):
    path = os.path.join(out_dir, "history.csv")
    with open(path) as f:
        header = [name.split("[")[0].strip() for name in f.readline().strip().split(",")]
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(header)}
