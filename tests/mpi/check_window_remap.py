"""The local loop through a migration (event_loop%remap_bodies, docs/architecture.md "The
loop through a migration"): a decomposed run whose windows end with bodies changing rank,
with the certificate audit on, on 1 and 2 ranks.

Usage: check_window_remap.py EXE DECK WORKDIR MPIEXEC [MPIEXEC FLAGS...]

Checks: both runs finish (the audit stops a run whose pair lacks a current certificate
after a migration or any event); on 2 ranks the run is decomposed, bodies change rank and
no loop is built again (no island here); frames are cmp-identical to one rank's and the
history is the same but for wall time and min_separation (sampled by certificates); and
the window ends certify only the arrivals' pairs: a rebuild certified every pair of every
body at each window end (about 2,400 per window here, 4,864 for the two), the remap about
7 per body that changed rank."""
import filecmp
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "regression"))
from ricochet_run import Checks

exe, deck, work, mpiexec = sys.argv[1:5]
flags = sys.argv[5:]
os.makedirs(work, exist_ok=True)
c = Checks()
SAMPLED_COLUMNS = {13, 17}     # wall_time [s], min_separation [m] (0-based)

outs, texts = {}, {}
for ranks in (1, 2):
    out = os.path.join(work, f"ranks{ranks}")
    shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.run([mpiexec, "-n", str(ranks), *flags, exe, deck, "--output-dir", out],
                          capture_output=True, text=True)
    c.check(proc.returncode == 0, f"{ranks} rank(s): exit {proc.returncode} {proc.stderr.strip()[-500:]}")
    outs[ranks], texts[ranks] = out, proc.stdout

text = texts[2]
get = lambda pattern: int(re.search(pattern, text).group(1)) if re.search(pattern, text) else None
windows = get(r"windows\s+(\d+) ended by a migration")
migrated = get(r"(\d+) bodies changed rank")
certs = get(r"(\d+) pair certificates computed there")
rebuilds = get(r"(\d+) loops built again")
c.check("domain decomposition" in text and bool(windows) and bool(migrated),
        f"2 ranks: decomposed, windows ended with migrations ({windows} windows, {migrated} bodies moved)")
c.check(rebuilds == 0, f"2 ranks: no loop built again (no island to split): {rebuilds}")
c.check(certs is not None and migrated is not None and 0 < certs <= 10 * migrated,
        f"2 ranks: window ends certify the arrivals' pairs only ({certs} certificates for {migrated} arrivals)")

names = sorted(os.listdir(os.path.join(outs[1], "frames")))
c.check(names == sorted(os.listdir(os.path.join(outs[2], "frames"))), "the same frame files")
for name in names:
    c.check(filecmp.cmp(os.path.join(outs[1], "frames", name), os.path.join(outs[2], "frames", name), shallow=False),
            f"frames/{name} cmp-identical on 1 and 2 ranks")
rows = {r: [[x for i, x in enumerate(l.rstrip("\n").split(",")) if i not in SAMPLED_COLUMNS]
            for l in open(os.path.join(outs[r], "history.csv"))][1:] for r in (1, 2)}
c.check(rows[1] == rows[2], "history.csv the same rows on 1 and 2 ranks (but wall time, min_separation)")
c.finish()
