"""The local loop's livelock at one time is fixed: restarted from tests/data/stall's
checkpoint (a pair its island's contact pass leaves approaching inside the band, found in
contact again at the same time over and over: before the fix it ran forever, then stopped
with the "collision loop stalled" guard after 50 repeats), the run must now complete, with
at least one island step held to its repeated impacts (docs/contact.md, "Known limits":
that is the path which breaks the cycle, so the test fails if the checkpoint no longer
reaches it), and no gap below the settling floor.

Usage: check_stall_guard.py EXE DATA_DIR WORK_DIR

The deck is the checkpoint's own with frames off and the contact pass's turning term off
(see below): the frames written before the checkpoint
are not part of the test data, and a restart that writes frames checks them. (Frames do
not change the local loop's steps: outputs only evaluate bodies.) The bound: the restart
takes about 6 s here; 240 s leaves room for a slow machine while a hang is still caught."""
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, check_separation_floor

exe, data, work = sys.argv[1:4]
c = Checks()
out = os.path.join(work, "output")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
shutil.copy(os.path.join(data, "checkpoint_l_prisms_0.79.h5"), os.path.join(out, "checkpoint_000001.h5"))
with open(os.path.join(data, "pile_l_shapes_0.79.nml")) as f:
    deck_text = f.read()
deck_text, n_sub = re.subn(r"check_overlaps = \.true\., ", "check_overlaps = .true., write_frames = .false., ", deck_text)
c.check(n_sub == 1, "the test deck's &output group was found and its frames turned off")
# The checkpoint reached the livelock with the contact pass predicting straight lines; the
# turning term (on by default since) finds this pair's solve and no longer comes to the
# repeated impacts, so the test keeps the straight-line pass that reaches the held path.
deck_text, n_sub = re.subn(r"&contact ", "&contact turning_term = .false., ", deck_text)
c.check(n_sub == 1, "the test deck's &contact group was found and its turning term turned off")
deck = os.path.join(work, "pile_l_shapes_0.79_noframes.nml")
with open(deck, "w") as f:
    f.write(deck_text)
cmd = [exe, deck, "--output-dir", out, "--restart", os.path.join(out, "checkpoint_000001.h5")]
try:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
except subprocess.TimeoutExpired:
    c.check(False, "the restarted run ended within 240 s (it hung)")
    c.finish()
c.check(proc.returncode == 0, f"the restarted run completes (exit {proc.returncode}): {proc.stderr.strip()[-400:]}")
c.check("run finished" in proc.stdout, "completed with a summary")
held = re.search(r"(\d+) held to repeated impacts", proc.stdout)
n_held = int(held.group(1)) if held else -1
print(f"island steps held to repeated impacts: {n_held}")
c.check(n_held >= 1, f"the livelock was reached and broken by held island steps ({n_held})")
check_separation_floor(c, proc)
c.finish()
