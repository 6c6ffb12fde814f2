"""A full disk ends a run with one clear error line naming the file (exit status 3, ERR_IO),
no HDF5-DIAG lines, no *.tmp left behind, and the XDMF indexes still the previous valid
XML (docs/output.md, "Nothing half-written").

A full disk is simulated with a file-size limit (RLIMIT_FSIZE, as `ulimit -f`): writes
past it fail with EFBIG as they would with ENOSPC (ricochet ignores SIGXFSZ, which would
otherwise kill it). A small tmpfs would need mount rights this test cannot count on.
Open MPI's start-up makes shared-memory files, which the limit would stop too: the test
runs it with PMIx's hash store and the self transport only (one rank needs nothing else).

Usage: check_disk_full.py EXE WORKDIR"""
import os
import resource
import shutil
import signal
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks

exe, work = sys.argv[1:3]
os.makedirs(work, exist_ok=True)
c = Checks()

# One small box falling: frames of ~10 kB, history rows of ~400 B; an index grows by ~2 kB
# a frame up to a block of 32 frames, so a 24 kB limit stops bodies.xmf after ~10 frames
# while frames and checkpoints still fit.
DECK = """&run title = 'disk full', t_end = 1.0, dt_max = 0.01, gravity = 0.0, 0.0, -9.81 /
&output interval = 0.025, history_interval = {history}, write_frames = {frames}, checkpoint_interval = 0.5 /
&body name = 'box', shape = 'box', size = 0.1, 0.1, 0.1, density = 1000.0, position = 0.0, 0.0, 10.0 /
"""


def run_limited(name, limit, history="0.025", frames=".true."):
    out = os.path.join(work, name)
    shutil.rmtree(out, ignore_errors=True)
    deck = os.path.join(work, name + ".nml")
    with open(deck, "w") as f:
        f.write(DECK.format(history=history, frames=frames))

    def limit_file_size():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = dict(os.environ, PMIX_MCA_gds="hash", OMPI_MCA_btl="self", OMPI_MCA_ess_singleton_isolated="1")
    proc = subprocess.run([exe, deck, "--output-dir", out], capture_output=True, text=True,
                          preexec_fn=limit_file_size, env=env, timeout=300)
    return out, proc


def common_checks(name, out, proc, culprit):
    lines = proc.stderr.strip().splitlines()
    c.check(proc.returncode == 3, f"{name}: exit status 3 (ERR_IO), got {proc.returncode}")
    c.check("HDF5-DIAG" not in proc.stderr, f"{name}: no HDF5-DIAG lines on stderr")
    c.check(len(lines) == 1 and lines[0].startswith("ricochet: error: ") and culprit in lines[0],
            f"{name}: one error line naming {culprit}: {lines[:3]}")
    left = [os.path.join(d, f) for d, _, files in os.walk(out) for f in files if f.endswith(".tmp")]
    c.check(not left, f"{name}: no .tmp file left: {left}")


def valid_indexes(name, out):
    """Each index parses as XML and lists frames that exist (XInclude'd blocks included)."""
    for index in ("surfaces.xmf", "bodies.xmf"):
        path = os.path.join(out, index)
        if not os.path.exists(path):
            c.check(False, f"{name}: {index} exists")
            continue
        try:
            root = ElementTree.parse(path).getroot()
        except ElementTree.ParseError as e:
            c.check(False, f"{name}: {index} is valid XML ({e})")
            continue
        items = [e.text.split(":")[0] for e in root.iter("DataItem")]
        c.check(len(items) > 0 and all(os.path.exists(os.path.join(out, h5)) for h5 in items),
                f"{name}: {index} lists frames that exist ({len(set(items))} frames)")


# 1. The first frame does not fit.
out, proc = run_limited("first_frame", 4000)
common_checks("first_frame", out, proc, "frames/frame_000000.h5")

# 2. Frames fit, an index outgrows the limit: the indexes keep their previous content.
out, proc = run_limited("index", 24000, history="0.5")
common_checks("index", out, proc, ".xmf")
valid_indexes("index", out)
n_frames = len([f for f in os.listdir(os.path.join(out, "frames")) if f.endswith(".h5")])
c.check(n_frames >= 3, f"index: several frames written before the index failed ({n_frames})")

# 3. history.csv rows (appended) outgrow the limit: a clear error, not a silent stop.
out, proc = run_limited("history", 6000, history="0.001", frames=".false.")
common_checks("history", out, proc, "history.csv")
c.finish()
