#!/usr/bin/env python3
"""Plots a ricochet history file (output/history.csv) to a PNG.

Panels: energies (translational, rotational, potential, total) with the relative drift of
the total energy on a second axis; linear momentum components; angular momentum components;
step size. Columns are found by name in the header ("name [unit]"), so files with extra
columns (added by later versions) plot as well.

Usage: python tools/plot_history.py output/history.csv [--out history.png] [--title TEXT]
"""
import argparse
import sys
import warnings

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_history(path):
    """Returns ({column name: values}, {column name: unit}) of a history CSV."""
    with open(path, encoding="ascii") as f:
        header = f.readline().strip()
    if not header:
        raise ValueError(f"{path}: empty file")
    names, units = [], {}
    for field in header.split(","):
        field = field.strip()
        name, _, unit = field.partition(" [")
        names.append(name)
        units[name] = unit.rstrip("]") if unit else ""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a run stopped before its first row
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.size == 0:
        data = np.zeros((0, len(names)))
    if data.shape[1] != len(names):
        raise ValueError(f"{path}: {data.shape[1]} columns in the rows, {len(names)} in the header")
    return {name: data[:, i] for i, name in enumerate(names)}, units


def relative_drift(total):
    """(E - E0)/|E0|, or E - E0 if E0 is 0 (the scale is then absolute)."""
    if len(total) == 0:
        return total, False
    scale = abs(total[0])
    if scale == 0.0:
        return total - total[0], False
    return (total - total[0]) / scale, True


def plot(columns, units, out, title):
    t = columns["time"]
    fig, axes = plt.subplots(4, 1, figsize=(9, 12), sharex=True)

    ax = axes[0]
    for name, label in (("kinetic_translational", "translational"), ("kinetic_rotational", "rotational"),
                        ("potential", "potential"), ("energy_total", "total")):
        if name in columns:
            ax.plot(t, columns[name], label=label, lw=1.8 if name == "energy_total" else 1.2)
    ax.set_ylabel(f"energy [{units.get('energy_total', 'J')}]")
    ax.legend(loc="upper left", fontsize="small")
    ax.grid(alpha=0.3)
    if "energy_total" in columns:
        drift, relative = relative_drift(columns["energy_total"])
        twin = ax.twinx()
        twin.plot(t, drift, color="black", ls=":", lw=1.0, label="total drift")
        twin.set_ylabel("(E - E0)/|E0|" if relative else "E - E0 [J]")
        twin.legend(loc="upper right", fontsize="small")

    for ax, base, label in ((axes[1], "momentum", "linear momentum"),
                            (axes[2], "angular_momentum", "angular momentum")):
        for axis in "xyz":
            name = f"{base}_{axis}"
            if name in columns:
                ax.plot(t, columns[name], label=axis)
        ax.set_ylabel(f"{label} [{units.get(base + '_x', '')}]")
        ax.legend(loc="upper left", fontsize="small")
        ax.grid(alpha=0.3)

    ax = axes[3]
    if "dt" in columns and len(t) > 0:
        ax.plot(t, columns["dt"], drawstyle="steps-post")
        if np.all(columns["dt"] > 0):
            ax.set_yscale("log")
    ax.set_ylabel(f"step size [{units.get('dt', 's')}]")
    ax.set_xlabel(f"time [{units.get('time', 's')}]")
    ax.grid(alpha=0.3)

    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("history", help="history CSV written by ricochet (output/history.csv)")
    parser.add_argument("--out", default="history.png", help="PNG to write (default: history.png)")
    parser.add_argument("--title", default=None, help="figure title (default: the file name)")
    args = parser.parse_args(argv)
    try:
        columns, units = read_history(args.history)
    except (OSError, ValueError) as error:
        print(f"plot_history: {error}", file=sys.stderr)
        return 1
    if "time" not in columns:
        print(f"plot_history: {args.history}: no 'time' column", file=sys.stderr)
        return 1
    plot(columns, units, args.out, args.title or args.history)
    print(f"wrote {args.out} ({len(columns['time'])} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
