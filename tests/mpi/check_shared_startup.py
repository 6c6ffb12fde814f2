"""The start-up checks shared among ranks (docs/architecture.md, "Domain decomposition in a
run"): each rank runs the overlap test on every n_ranks-th candidate pair and sweeps every
n_ranks-th sorted position of contact_possible; the first hit any rank finds is the one-rank
answer. So on 1, 2, 3 and 4 ranks:
- a deck with overlapping bodies stops with the same error line, naming the same bodies,
  whichever rank tested that pair (never a hang: each run has a timeout);
- a deck with two pairs that may touch names the same pair in the notice, the one the
  one-rank sweep meets first, though another rank finds the other pair.

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
errors = {}
for ranks in (1, 2, 3, 4):
    proc = run(ranks, overlaps, f"overlaps_{ranks}")
    if proc is None:
        continue
    lines = [l for l in proc.stderr.splitlines() if l.startswith("ricochet: error")]
    c.check(proc.returncode != 0, f"{ranks} rank(s): overlapping bodies stop the run (exit {proc.returncode})")
    c.check(len(lines) == 1 and "overlap at the start" in lines[0],
            f"{ranks} rank(s): one error line from rank 0 naming the overlap, got {lines}")
    errors[ranks] = lines
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
c.finish()
