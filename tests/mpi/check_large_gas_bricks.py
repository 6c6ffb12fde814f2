"""A large gas on 3 x 1 and 2 x 2 bricks must end as on one rank, bit for bit, counters
included. tools/bench_cross_windows.py's gas of 100,000 spheres over 0.25 s (e = 1, no
gravity) met two defects the 200-sphere gas of check_cross_rank_contacts never met
(docs/architecture.md):
- on 4 ranks (2 x 2 x 1) it ended with 8 bodies up to 8.3e-10 m off the one-rank run: the
  impact of bodies 59340 and 60487 at t = 0.0856 s, a pair across the y face, came
  5.6e-11 s apart. The advancement had landed in the contact band tens of 2^-40 s cells
  from the crossing of the aim, and the canonical search looked only 4 cells each way;
  it now gallops out to 2^24 cells and halves back to the crossing cell;
- on 3 ranks (3 x 1 x 1) and 6 (3 x 2 x 1) every body was right but two impacts of a body
  with a wall were counted by two ranks (66,507 against 66,505): the rule "the owner of the
  lower global id counts" named the wall, a fixed body owned by one rank and held as a
  static ghost by the others; the moving body decides now (event_loop deciding_row).
Each was checked on both sides of its fix: before it this test's comparison fails.

Usage: check_large_gas_bricks.py EXE WORKDIR MPIEXEC [MPIEXEC_PREFLAGS...]
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks  # noqa: E402
from run_compare import SAMPLED_COUNTERS, same_checkpoint  # noqa: E402

exe, work, mpiexec = sys.argv[1:4]
flags = sys.argv[4:]
c = Checks()
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "tools"))
from bench_cross_windows import deck_text  # noqa: E402

deck = os.path.join(work, "gas_100k.nml")
with open(deck, "w") as f:
    f.write(deck_text(100000, 0.25, 1))   # (3 and 4 ranks choose 3 x 1 x 1, 2 x 2 x 1: checked below)
outs = {}
layouts = {3: "3 x 1 x 1", 4: "2 x 2 x 1"}
for ranks in (1, 3, 4):
    out = os.path.join(work, f"ranks_{ranks}")
    command = [exe, deck, "--output-dir", out]
    if ranks > 1:
        command = [mpiexec, "-n", str(ranks), *flags, *command]
    proc = subprocess.run(command, capture_output=True, text=True)
    c.check(proc.returncode == 0, f"100,000-sphere gas on {ranks} rank(s): exit {proc.returncode} "
            f"{proc.stderr.strip()[-400:]}")
    if ranks > 1:
        c.check(f"domain decomposition {layouts[ranks]} bricks" in proc.stdout and "cross-rank windows" in proc.stdout,
                f"{ranks} ranks: {layouts[ranks]} bricks in cross-rank windows ({proc.stdout[:300]})")
    outs[ranks] = out
# (advancement iterations count the certificates' conservative advancement, which window
# starts compute afresh: sampled, as in check_cross_rank_contacts)
for ranks in (3, 4):
    same_checkpoint(c, os.path.join(outs[1], "checkpoint_final.h5"), os.path.join(outs[ranks], "checkpoint_final.h5"),
                    f"100,000-sphere gas, 1 vs {ranks} ranks ({layouts[ranks]})",
                    sampled_counters=SAMPLED_COUNTERS | {b"advancement_iterations"})
c.finish()
