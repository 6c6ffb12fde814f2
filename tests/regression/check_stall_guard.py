"""The local loop never hangs: restarted from tests/data/stall's checkpoint (a pair its
island's contact pass leaves approaching inside the band, found in contact again at the
same time over and over), the run either completes or stops with the "collision loop
stalled" error naming the pair, within the time bound. Before the guard it ran forever.

Usage: check_stall_guard.py EXE DATA_DIR WORK_DIR

The bound: 50 repeats of an island step of 190 bodies take about 10 s here; 240 s leaves
room for a slow machine while a hang (the defect) is still caught. When the livelock itself
is fixed (docs/contact.md, "Known limits"), the completing branch below takes over and the
run's own checks apply."""
import os
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
cmd = [exe, os.path.join(data, "pile_l_shapes_0.79.nml"), "--output-dir", out,
       "--restart", os.path.join(out, "checkpoint_000001.h5")]
try:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
except subprocess.TimeoutExpired:
    c.check(False, "the restarted run ended within 240 s (it hung: the stall guard did not fire)")
    c.finish()
if proc.returncode == 0:
    c.check("run finished" in proc.stdout, "completed with a summary")
    check_separation_floor(c, proc)
else:
    c.check("collision loop stalled: bodies 18 and 43" in proc.stderr,
            f"stopped with the stall error naming the pair (exit {proc.returncode}): {proc.stderr.strip()[-400:]}")
    c.check(proc.returncode == 4, f"exit code 4 (ERR_NUMERIC), got {proc.returncode}")
c.finish()
