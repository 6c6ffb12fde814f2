"""The start-up checks shared among ranks (docs/architecture.md, "Domain decomposition in a
run"): each rank runs the overlap test on every n_ranks-th candidate pair and sweeps every
n_ranks-th sorted position of contact_possible; the first hit any rank finds is the one-rank
answer. So on 1, 2, 3 and 4 ranks:
- a deck with overlapping bodies stops with the same error line, naming the same bodies,
  whichever rank tested that pair (never a hang: each run has a timeout);
- a deck with two pairs that may touch names the same pair in the notice, the one the
  one-rank sweep meets first, though another rank finds the other pair.
And the deck itself, read in shares (src/run/shared_deck: each rank parses a block of the
&body groups, the blocks gathered): a faulty &body group in the last rank's block, with a
later faulty &contact group; faulty groups in the first and the last block; the same name
in two blocks: each stops every rank with the one error line one rank gives (the first in
the file), never a hang.

Usage: check_shared_startup.py EXE WORKDIR MPIEXEC [MPIEXEC FLAGS...]"""
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks

exe, work, mpiexec = sys.argv[1:4]
flags = sys.argv[4:]
os.makedirs(work, exist_ok=True)
c = Checks()


def deck(name, text):
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def run(ranks, path, out):
    cmd = [mpiexec, "-n", str(ranks), *flags, exe, path, "--output-dir", os.path.join(work, out)]
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        c.check(False, f"{ranks} rank(s), {os.path.basename(path)}: finished within 120 s (no hang)")
        return None


# Spheres and boxes in rows, two bodies overlapping members of the rows far apart (a sphere
# in a box, a box through a sphere): candidate pairs by the hundred, two of them overlap.
overlaps = deck("overlaps.nml", """&run t_end = 0.1, dt_max = 0.01 /
&body name = 'balls', shape = 'sphere', radius = 0.4, density = 1000.0,
  copies = 30, 3, 2, spacing = 1.0, 1.0, 1.0, position = 0.0, 0.0, 0.0 /
&body name = 'crates', shape = 'box', size = 0.3, 0.2, 0.1, density = 1000.0,
  copies = 30, 3, 2, spacing = 1.0, 1.0, 1.0, position = 0.5, 0.5, 0.5 /
&body name = 'intruder', shape = 'sphere', radius = 0.1, density = 1000.0, position = 24.55, 1.5, 0.5 /
&body name = 'spike', shape = 'box', size = 0.9, 0.05, 0.05, density = 1000.0, position = 6.0, 1.0, 1.0 /
""")
def error_lines(path, tag):
    """{ranks: the error lines} of runs of a faulty deck on 1 to 4 ranks, each checked to
    stop (non-zero exit)."""
    found = {}
    for ranks in (1, 2, 3, 4):
        proc = run(ranks, path, f"{tag}_{ranks}")
        if proc is None:
            continue
        c.check(proc.returncode != 0, f"{tag} on {ranks} rank(s): the run stops (exit {proc.returncode})")
        found[ranks] = [l for l in proc.stderr.splitlines() if l.startswith("ricochet: error")]
    return found


errors = error_lines(overlaps, "overlaps")
for ranks, lines in errors.items():
    c.check(len(lines) == 1 and "overlap at the start" in lines[0],
            f"{ranks} rank(s): one error line from rank 0 naming the overlap, got {lines}")
for ranks in (2, 3, 4):
    if ranks in errors and 1 in errors:
        c.check(errors[ranks] == errors[1], f"{ranks} ranks name the bodies one rank names: {errors[ranks]} "
                                            f"against {errors[1]}")

# At rest without gravity: a row of 21 spheres (gids 3..23) and a spacer (24) far from
# everything; pair (1, 2) at x = 100 and pair (25, 26) at x = -10 close in within t_end. In
# the sweep order (lower x first) the row takes positions 1..21, then 25 (22), 26 (23), 24
# (24), 1 (25), 2 (26): the one-rank sweep meets (25, 26) first; on 2 ranks rank 1 finds
# it (position 22) and rank 0 finds (1, 2) (position 25).
touching = deck("touching.nml", """&run t_end = 1.0, dt_max = 0.01 /
&output write_frames = .false. /
&body name = 'far_a', shape = 'sphere', radius = 0.5, density = 1000.0, position = 100.0, 0.0, 0.0,
  velocity = 3.0, 0.0, 0.0 /
&body name = 'far_b', shape = 'sphere', radius = 0.5, density = 1000.0, position = 102.0, 0.0, 0.0 /
&body name = 'row', shape = 'sphere', radius = 0.5, density = 1000.0,
  copies = 21, 1, 1, spacing = 3.0, 0.0, 0.0, position = -100.0, 0.0, 0.0 /
&body name = 'spacer', shape = 'sphere', radius = 0.5, density = 1000.0, position = 50.0, 0.0, 0.0 /
&body name = 'near_a', shape = 'sphere', radius = 0.5, density = 1000.0, position = -10.0, 0.0, 0.0,
  velocity = 3.0, 0.0, 0.0 /
&body name = 'near_b', shape = 'sphere', radius = 0.5, density = 1000.0, position = -8.0, 0.0, 0.0 /
""")
for ranks in (2, 3, 4):
    proc = run(ranks, touching, f"touching_{ranks}")
    if proc is None:
        continue
    c.check(proc.returncode == 0, f"{ranks} ranks: the touching deck runs: {proc.stderr.strip()[-300:]}")
    notice = re.search(r"bodies (\d+) and (\d+) may touch", proc.stdout)
    c.check(notice is not None and notice.groups() == ("25", "26"),
            f"{ranks} ranks: the notice names bodies 25 and 26, got {notice.group(0) if notice else proc.stdout[-300:]}")
# The deck read in shares: eight &body groups (blocks of 4, 3-3-2 and 2 on 2, 3, 4 ranks).
def bodies(bad=(), same_name=False):
    lines = ["&run t_end = 0.1, dt_max = 0.01 /", "&output write_frames = .false. /"]
    for k in range(1, 9):
        radius = -0.25 if k in bad else 0.25
        name = "b1" if (same_name and k == 8) else f"b{k}"
        lines.append(f"&body name = '{name}', shape = 'sphere', radius = {radius}, density = 1000.0, "
                     f"position = {2.0 * k}, 0.0, 0.0 /")
    return lines


cases = {"last_block": bodies(bad=(7,)) + ["&contact restitution = 2.0 /"],
         "first_and_last": bodies(bad=(2, 7)),
         "same_name": bodies(same_name=True)}
for name, lines in cases.items():
    path = deck(f"shared_{name}.nml", "\n".join(lines) + "\n")
    errors = error_lines(path, f"shared_{name}")
    for ranks, err_lines in errors.items():
        c.check(len(err_lines) == 1, f"deck {name} on {ranks} rank(s): one error line: {err_lines}")
    want = {"last_block": "&body", "first_and_last": "&body", "same_name": "already used by &body #1"}[name]
    c.check(1 in errors and len(errors[1]) == 1 and want in errors[1][0],
            f"deck {name} on 1 rank: the error names {want!r}: {errors.get(1)}")
    line_of = {"last_block": ":9:", "first_and_last": ":4:", "same_name": ":10:"}[name]
    c.check(1 in errors and len(errors[1]) == 1 and line_of in errors[1][0],
            f"deck {name} on 1 rank: the first faulty group in the file ({line_of}): {errors.get(1)}")
    for ranks in (2, 3, 4):
        if ranks in errors and 1 in errors:
            c.check(errors[ranks] == errors[1], f"deck {name} on {ranks} ranks: the error one rank gives: "
                                                f"{errors[ranks]} against {errors[1]}")
c.finish()
