"""Contacts between bodies of different ranks (cross-rank windows, docs/architecture.md
"Cross-rank contacts: windows with ghosts"): scenes whose bodies meet across brick faces
and edges, run on 1 to 4 ranks, must write the same files as one rank, bit for bit.

Usage: check_cross_rank_contacts.py EXE WORKDIR MPIEXEC [MPIEXEC FLAGS...]

Scenes (elastic, no gravity: the scenes cross-rank windows are built for), each checked
against one rank with run_compare (frames cmp-identical, history but for wall time and
min_separation, checkpoints bit for bit but for n_ranks, wall_time_before and the sampled
counters):
- face: two spheres meeting head on exactly across the face of a 2 x 1 x 1 decomposition,
  a third pair meeting off-centre; 2 ranks. The impact is a cross-rank impact (summary).
- edge: two spheres meeting at the edge of a 2 x 2 x 1 decomposition (from the two
  bricks that share only that edge); 4 ranks.
- corner: the same at the corner of a 2 x 2 x 2 decomposition; 8 ranks (oversubscribed,
  a scene of four bodies).
- gas: 200 spheres in a closed box, random start, e = 1; 2, 3 and 4 ranks; bodies change
  rank, cross-rank impacts happen, and windows start light (only the ghosts whose owners
  changed them come again, and the bodies that came near a neighbouring brick: both checked
  to happen, so that the comparison covers them). A
  restart written on 4 ranks at t = 0.5 s goes on
  on 2 ranks, and one written on 1 rank goes on on 4, as the uninterrupted run.
- gas_8000: tools/bench_cross_windows.py's gas of 8,000 spheres to 0.08 s on 2 ranks (light
  starts re-zone bodies many times; a stale-row certificate once stopped it at 0.0763 s).
- three scenes from a review (tests/data/cross_rank): a ghost-held body wandering to
  another neighbour's side, two bodies that both changed with no pair ever made, a body
  re-placed at every bounce in a channel (never a box crossing);
- the billiards break (input/validation/billiards_break.nml): groups of touching balls
  split between ranks; 2 ranks, and 4 with `&parallel skin = 0` (the skin's larger bricks
  do not fit four ranks on this small table).
- the window length (`&parallel window_events`): the 200-sphere gas with windows of about
  one event per rank and with windows up to the output times gives the one-rank files, and
  fewer events a window make more windows.
- the migration skin (`&parallel skin`, docs/architecture.md "Migration at full starts
  only, past a skin"): the 200-sphere gas and the three review scenes also run with skin =
  0 (migration at every brick a body leaves, the rule before the skin); both give the
  one-rank files, bodies change rank in both, and the default skin needs fewer full window
  starts than skin = 0.
- an impulse group reaching across more than one brick (a Newton's cradle of 13 balls on
  3 ranks) is not built yet: every rank stops with an error naming it, never a wrong answer.
Why bit for bit is the bar: a time of contact is a function of the two trajectories alone
(time_of_contact's canonical crossing), the loop built again at a window's start keeps
every anchor, and a cross-rank impact is solved once, by one rank, with the same bodies in
the same order as on one rank; a missed ghost, a stale one or a group solved on two ranks
shows as a different event and then as a different frame."""
import math
import os
import re
import shutil
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks, box_walls
from run_compare import SAMPLED_COLUMNS, SAMPLED_COUNTERS, same_checkpoint, same_frames, same_history

exe, work, mpiexec = sys.argv[1:4]
flags = sys.argv[4:]
os.makedirs(work, exist_ok=True)
c = Checks()
SOURCE = os.path.join(os.path.dirname(__file__), "..", "..")


def deck(name, text):
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def run(ranks, path, out, *extra, expect_ok=True):
    if not extra:
        shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.run([mpiexec, "-n", str(ranks), *flags, exe, path, "--output-dir", out, *extra],
                          capture_output=True, text=True)
    if expect_ok:
        c.check(proc.returncode == 0, f"{os.path.basename(path)} on {ranks} rank(s) {' '.join(extra)}: exit "
                f"{proc.returncode} {proc.stdout.strip()[-300:]} {proc.stderr.strip()[-500:]}")
    return proc


def cross_counts(text):
    """(windows, repeated, cross phases, ghosts sent back, light starts, bodies that changed rank)
    of the summary."""
    m = re.search(r"cross-rank windows\s+(\d+) \((\d+) run again.*?, (\d+) of them ending in a cross phase \([^)]*\), "
                  r"(\d+) ghosts sent back to their owners, (\d+) started light[^)]*\); (\d+) bodies changed rank", text)
    return tuple(int(x) for x in m.groups()) if m else None


# Sampled besides run_compare's: advancement iterations count the conservative advancement
# of certificates, which every window's start computes afresh (the events do not change).
COUNTERS = SAMPLED_COUNTERS | {b"advancement_iterations"}
COLUMNS = SAMPLED_COLUMNS | {16}


def same_run(one, other, what):
    same_frames(c, one, other, what)
    same_history(c, one, other, what, sampled_columns=COLUMNS)
    for name in sorted(os.listdir(one)):
        if name.startswith("checkpoint_") and name.endswith(".h5"):
            same_checkpoint(c, os.path.join(one, name), os.path.join(other, name), f"{what}, {name}",
                            sampled_counters=COUNTERS)


def rezoned_count(text):
    """Bodies sent at light starts to neighbours they came near (re-zoned), from the summary."""
    m = re.search(r"and (\d+) bodies that came near a neighbouring brick", text)
    return int(m.group(1)) if m else None


def shared_impacts(text):
    """Cross-rank impacts taken by both ranks in the windows' runs, from the summary."""
    m = re.search(r"cross-rank impacts\s+(\d+) taken by both ranks", text)
    return int(m.group(1)) if m else None


# per scene and rank count: (cross-rank impacts taken by both ranks in a window's run, ghosts
# a cross phase sent back to their owners): both ways are part of the bitwise comparison
paths = {}

# windows run again after a restore, per scene and rank count: the restore (the loop's undo
# journals rolled back) is then part of what the bitwise comparison checks
repeated_windows = {}


def compare(name, path, ranks_list, need_cross=True, need_light=False):
    one = os.path.join(work, f"{name}_1")
    run(1, path, one)
    rezoned = []
    for ranks in ranks_list:
        out = os.path.join(work, f"{name}_{ranks}")
        proc = run(ranks, path, out)
        with open(out + ".log", "w") as f:
            f.write(proc.stdout)
        counts = cross_counts(proc.stdout)
        c.check(counts is not None, f"{name} on {ranks} ranks: cross-rank windows ({proc.stdout[-400:]})")
        if counts:
            repeated_windows[f"{name}_{ranks}"] = counts[1]
        shared = shared_impacts(proc.stdout)
        c.check(shared is not None, f"{name} on {ranks} ranks: cross-rank impacts line ({proc.stdout[-400:]})")
        if counts and shared is not None:
            paths[f"{name}_{ranks}"] = (shared, counts[3])
        if counts and need_cross and shared is not None:
            # (taken by both ranks in a window's run, or by one in a cross phase)
            c.check(shared > 0 or counts[3] > 0, f"{name} on {ranks} ranks: impacts across ranks happened "
                                                 f"(windows, repeated, phases, ghosts sent, light, migrated: "
                                                 f"{counts}; taken by both: {shared})")
        if counts and need_light:
            # (light starts, where only the ghosts that changed come again, are then part of
            # what the bitwise comparison below checks)
            c.check(counts[4] > 0, f"{name} on {ranks} ranks: windows started light ({counts})")
            rezoned.append(rezoned_count(proc.stdout) or 0)
        # the load report's busy time: the rank's work on events, so the busiest rank's at
        # least rank 0's impacts and certificates ("time by phase", 4 digits printed), and not
        # more than the run (it counted only the outputs' evaluations of the local loop)
        busy = re.search(r"busy ([0-9.Ee+-]+) / ([0-9.Ee+-]+) / ([0-9.Ee+-]+) s", proc.stdout)
        wall = re.search(r"wall time\s+([0-9.Ee+-]+) s", proc.stdout)
        phases = re.search(r"impacts ([0-9.Ee+-]+) s, certificates and box crossings ([0-9.Ee+-]+) s", proc.stdout)
        c.check(busy is not None and wall is not None and phases is not None and
                float(busy.group(3)) * 1.001 >= float(phases.group(1)) + float(phases.group(2)) and
                float(busy.group(3)) <= float(wall.group(1)),
                f"{name} on {ranks} ranks: the busiest rank's busy time covers rank 0's event phases, within "
                f"the wall time ({busy.group(0) if busy else None}; {phases.group(0) if phases else None}; "
                f"{wall.group(0) if wall else None})")
        same_run(one, out, f"{name}: 1 vs {ranks} ranks")
    if need_light:
        # (bodies that came near a neighbouring brick were sent at a light start, appended
        # there as ghosts, instead of a full start: part of the bitwise comparison too)
        c.check(max(rezoned, default=0) > 0, f"{name}: some light start sent bodies that came near a neighbouring "
                                             f"brick (per rank count: {rezoned})")
    return one


OUTPUT = "&output interval = 0.1 /\n"
SPHERE = "shape = 'sphere', radius = 0.05, density = 1000.0"

# Face: the bricks split x at the middle of the scene (x = 0: the spacers at -1.5 and 1.5
# make the scene symmetric); the head-on pair meets at x = 0 exactly, the other pair
# at an angle a little to the right.
face = deck("face.nml", "&run title = 'face', t_end = 1.0, dt_max = 0.01 /\n&contact restitution = 1.0 /\n" + OUTPUT +
            f"&body name = 'left', {SPHERE}, position = -0.5, 0.0, 0.0, velocity = 1.0, 0.0, 0.0 /\n"
            f"&body name = 'right', {SPHERE}, position = 0.5, 0.0, 0.0, velocity = -1.0, 0.0, 0.0 /\n"
            f"&body name = 'low_left', {SPHERE}, position = -0.45, 0.3, 0.0, velocity = 1.0, 0.05, 0.0 /\n"
            f"&body name = 'low_right', {SPHERE}, position = 0.55, 0.33, 0.0, velocity = -1.0, 0.0, 0.0 /\n"
            f"&body name = 'spacer_left', {SPHERE}, position = -1.5, 0.0, 0.0 /\n"
            f"&body name = 'spacer_right', {SPHERE}, position = 1.5, 0.0, 0.0 /\n"
            "&parallel dims = 2, 1, 1 /\n")
compare("face", face, (2,))

# Edge: bricks 2 x 2 x 1 split at x = 0 and y = 0; one sphere comes from (-, -), the other
# from (+, +): they meet at the shared edge of those two bricks.
edge = deck("edge.nml", "&run title = 'edge', t_end = 1.0, dt_max = 0.01 /\n&contact restitution = 1.0 /\n" + OUTPUT +
            f"&body name = 'minus', {SPHERE}, position = -0.4, -0.4, 0.0, velocity = 1.0, 1.0, 0.0 /\n"
            f"&body name = 'plus', {SPHERE}, position = 0.4, 0.41, 0.0, velocity = -1.0, -1.0, 0.0 /\n"
            f"&body name = 'corner_a', {SPHERE}, position = -1.5, -1.5, 0.0 /\n"
            f"&body name = 'corner_b', {SPHERE}, position = 1.5, 1.5, 0.0 /\n"
            "&parallel dims = 2, 2, 1 /\n")
compare("edge", edge, (4,))

# Corner: bricks 2 x 2 x 2 (8 ranks, oversubscribed: a small scene), the two spheres come
# from the bricks (-, -, -) and (+, +, +), which share only a corner.
corner = deck("corner.nml", "&run title = 'corner', t_end = 1.0, dt_max = 0.01 /\n&contact restitution = 1.0 /\n" +
              OUTPUT +
              f"&body name = 'minus', {SPHERE}, position = -0.4, -0.4, -0.4, velocity = 1.0, 1.0, 1.0 /\n"
              f"&body name = 'plus', {SPHERE}, position = 0.4, 0.41, 0.39, velocity = -1.0, -1.0, -1.0 /\n"
              f"&body name = 'corner_a', {SPHERE}, position = -1.5, -1.5, -1.5 /\n"
              f"&body name = 'corner_b', {SPHERE}, position = 1.5, 1.5, 1.5 /\n"
              "&parallel dims = 2, 2, 2 /\n")
compare("corner", corner, (8,))

# Gas: 200 spheres at 5% in a closed box (tests/regression/check_local_events.py's gas).
rng = np.random.default_rng(7)
n, radius, gap, phi = 200, 0.05, 0.005, 0.05
box = (n * 4.0 / 3.0 * math.pi * radius ** 3 / phi) ** (1.0 / 3.0)
pos = []
while len(pos) < n:
    p = rng.uniform(radius + gap, box - radius - gap, 3)
    if all(np.sum((p - q) ** 2) >= (2 * radius + gap) ** 2 for q in pos):
        pos.append(p)
vel = rng.normal(size=(n, 3))
vel -= vel.mean(axis=0)
vel *= 1.0 / math.sqrt(np.mean(np.sum(vel ** 2, axis=1)))
lines = ["&run title = 'gas', t_end = 1.0, dt_max = 0.01 /", "&contact restitution = 1.0 /",
         "&output write_frames = .true., interval = 0.25, checkpoint_interval = 0.5 /"] + box_walls(box, 0.2)
for k in range(n):
    lines.append("&body name = 'b%d', %s, position = %r, %r, %r, velocity = %r, %r, %r /"
                 % (k, SPHERE, *map(float, pos[k]), *map(float, vel[k])))
gas = deck("gas.nml", "\n".join(lines) + "\n")
gas_one = compare("gas", gas, (2, 3, 4), need_light=True)
c.check(sum(v[0] for v in paths.values()) > 0 and sum(v[1] for v in paths.values()) > 0,
        f"cross-rank impacts were taken both ways: by both ranks in a window's run, and by one in a cross phase "
        f"with its ghosts sent back ((both, sent back) per run: {paths})")
# (on 4 ranks a holder's log reaches neighbours that do not own the body, which must not
# take it for a mismatch: then no window's logs ever agreed there)
c.check(paths.get("gas_4", (0, 0))[0] > 0, f"gas on 4 ranks: cross-rank impacts taken by both ranks ({paths})")
c.check(sum(v for k, v in repeated_windows.items() if k.startswith("gas_")) > 0,
        f"gas: some window was run again from its restored start ({repeated_windows})")
# The same gas with skin = 0: a body migrates at the first window start after it left its
# brick (full starts), the rule the skin relaxes; both must be the one-rank run, and the
# skin must spare full starts (windows - light starts) while bodies still change rank.
gas_skin0 = deck("gas_skin0.nml", "\n".join(lines) + "\n&parallel skin = 0.0 /\n")
compare("gas_skin0", gas_skin0, (2, 3), need_light=True)
full_starts = {}
for name, path in (("skin", gas), ("skin0", gas_skin0)):
    proc = run(2, path, os.path.join(work, f"gas_starts_{name}"))
    counts = cross_counts(proc.stdout)
    c.check(counts is not None and counts[5] > 0, f"gas ({name}) on 2 ranks: bodies changed rank ({counts})")
    full_starts[name] = counts[0] - counts[4] if counts else None
c.check(None not in full_starts.values() and full_starts["skin"] < full_starts["skin0"],
        f"gas on 2 ranks: the default skin needs fewer full window starts than skin = 0 ({full_starts})")
# The window length (&parallel window_events, docs/architecture.md "Window length"): windows
# of about one event per rank, and windows up to the output times (the rule before it), cut
# the run elsewhere and must give the one-rank files; fewer events a window, more windows.
window_counts = {}
for name, aim in (("short", "1.0"), ("long", "1.0e9")):
    path = deck(f"gas_windows_{name}.nml", "\n".join(lines) + f"\n&parallel window_events = {aim} /\n")
    compare(f"gas_windows_{name}", path, (2,))
    with open(os.path.join(work, f"gas_windows_{name}_2.log")) as f:
        counts = cross_counts(f.read())
    window_counts[name] = counts[0] if counts else None
with open(os.path.join(work, "gas_2.log")) as f:
    counts = cross_counts(f.read())
window_counts["default"] = counts[0] if counts else None
# (the default aims at more events than this small gas has between its output times)
c.check(None not in window_counts.values() and
        window_counts["short"] > window_counts["default"] >= window_counts["long"],
        f"gas on 2 ranks: fewer events per window, more windows (windows per window_events: {window_counts})")
# restarts across rank counts: 4 -> 2 and 1 -> 4, from the checkpoint at t = 0.5 s
for written, goes_on in ((4, 2), (1, 4)):
    out = os.path.join(work, f"gas_restart_{written}_{goes_on}")
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(os.path.join(work, f"gas_{written}"), out)
    run(goes_on, gas, out, "--restart", os.path.join(out, "checkpoint_000001.h5"))
    what = f"gas: restart written on {written} rank(s), continued on {goes_on}"
    same_checkpoint(c, os.path.join(gas_one, "checkpoint_final.h5"), os.path.join(out, "checkpoint_final.h5"), what,
                    sampled_counters=COUNTERS)
    same_frames(c, gas_one, out, what)

# A larger gas (tools/bench_cross_windows.py's: 8,000 spheres, 5%, seed 11, to 0.08 s) on
# 2 ranks: windows start light and re-zone bodies many times. Its light start at t =
# 0.0762546 s once certified a pair with a re-zoned arrival from rows the loop took for
# evaluated at that time and were not (remap_bodies' state_time): an impact due at once on
# the rank not owning its lower id, and 1000 windows in a row ended there.
sys.path.insert(0, os.path.join(SOURCE, "tools"))
from bench_cross_windows import deck_text  # noqa: E402
compare("gas_8000", deck("gas_8000.nml", deck_text(8000, 0.08, 11).replace("write_frames = .false.", "write_frames = .true.")),
        (2,), need_light=True)

# Three scenes a review built against the first versions, each of which then missed a
# contact on 2-3 ranks (tests/data/cross_rank): a body held as a ghost by one neighbour
# wandering inside its brick to another neighbour's side (3 ranks); two bodies of two ranks
# that both changed towards each other while their ghost copies stayed far apart (no pair of
# them was ever made); a body bounced along a channel whose region moves at every impact,
# so that it never has a box crossing. Each must give the one-rank files.
DATA = os.path.join(os.path.dirname(__file__), "..", "data", "cross_rank")
# (built for bricks without the skin: each also with skin = 0)
for name, ranks in (("zone_body_wanders", 3), ("both_changed_pair_never_made", 2), ("channel_no_crossing", 2)):
    path = os.path.join(DATA, name + ".nml")
    compare(name, path, (ranks,), need_cross=False)
    with open(path) as f:
        text = re.sub(r"&parallel dims = ([0-9, ]+) /", r"&parallel dims = \1, skin = 0.0 /", f.read())
    c.check("skin = 0.0" in text, f"{name}: its &parallel group takes skin = 0")
    compare(name + "_skin0", deck(name + "_skin0.nml", text), (ranks,), need_cross=False)

# The billiards break: touching balls of the rack in impulse groups split between ranks.
billiards = os.path.join(SOURCE, "input", "validation", "billiards_break.nml")
compare("billiards", billiards, (2,), need_cross=False)
with open(billiards) as f:
    billiards_skin0 = deck("billiards_skin0.nml", f.read() + "\n&parallel skin = 0.0 /\n")
compare("billiards_skin0", billiards_skin0, (4,), need_cross=False)

# An impulse group across more than one brick: a cradle of 13 touching balls on 3 ranks
# (the striker's impulse crosses two brick faces at once). Not built: an error on every
# rank, naming it.
cradle = deck("long_cradle.nml", "&run title = 'long cradle', t_end = 1.0, dt_max = 0.01 /\n"
              "&contact restitution = 1.0, min_separation = 1.0e-6 /\n" + OUTPUT +
              "&body name = 'striker', shape = 'sphere', radius = 0.1, density = 1000.0, position = -1.6, 0.0, 0.0, "
              "velocity = 1.0, 0.0, 0.0 /\n"
              "&body name = 'row', shape = 'sphere', radius = 0.1, density = 1000.0, position = -1.299999, 0.0, 0.0, "
              "copies = 13, 1, 1, spacing = 0.200001, 0.0, 0.0 /\n&parallel dims = 3, 1, 1 /\n")
proc = run(3, cradle, os.path.join(work, "long_cradle_3"), expect_ok=False)
c.check(proc.returncode != 0 and "impulse groups across more than one brick face are not built yet" in proc.stderr,
        f"long cradle on 3 ranks: an error naming the limit ({proc.returncode}, {proc.stderr.strip()[-400:]})")
c.finish()
