"""A run stopped early stops cleanly and can be continued (docs/output.md, "Stopping a
run"): SIGTERM (local event loop) and SIGINT (global loop), sent once the run has written
its first progress line, end it with exit status 143 / 130, one line naming the checkpoint
it wrote (checkpoint_signal.h5) and the command to continue; &run wall_limit ends it with
75 and checkpoint_wall_limit.h5. A --restart from each checkpoint finishes with exit 0 at
a final state equal to the uninterrupted run's. stdout goes to a file, as in a batch job:
the progress lines and the stop line must be in it when the process is gone.

Usage: check_stop.py EXE WORKDIR"""
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from ricochet_run import Checks, checkpoint, run

exe, work = sys.argv[1:3]
os.makedirs(work, exist_ok=True)
c = Checks()


def deck(name, per_side, t_end, extra_run="", integrator=""):
    """Balls bouncing on a floor, far apart (they never meet): many impacts, a second or
    two of wall time, and no chaos, so a restart's round-off stays round-off."""
    path = os.path.join(work, name + ".nml")
    start = -0.25 * (per_side - 1)
    with open(path, "w") as f:
        f.write(f"""&run title = 'bouncing balls', t_end = {t_end}, dt_max = 0.01, gravity = 0.0, 0.0, -9.81 {extra_run} /
&contact restitution = 0.95 /
{integrator}
&output write_frames = .false., interval = 0.5, progress_interval = 0.02 /
&body name = 'floor', shape = 'box', size = 40.0, 40.0, 0.2, position = 0.0, 0.0, -0.1, fixed = .true. /
&body name = 'ball', shape = 'sphere', radius = 0.1, density = 1000.0
  copies = {per_side}, {per_side}, 1, spacing = 0.5, 0.5, 0.0, position = {start}, {start}, 1.0
  seed = 7, jitter_position = 0.1, jitter_velocity = 0.0 /
""")
    return path


def started(exe, deck_path, out, log):
    """ricochet in the background, stdout to the file `log` (block-buffered unless flushed)."""
    shutil.rmtree(out, ignore_errors=True)
    with open(log, "w") as f:
        return subprocess.Popen([exe, deck_path, "--output-dir", out], stdout=f, stderr=subprocess.PIPE, text=True)


def wait_for_progress(proc, log, limit=60.0):
    start = time.time()
    while time.time() - start < limit and proc.poll() is None:
        with open(log) as f:
            if "  t = " in f.read():
                return True
        time.sleep(0.01)
    return False


def compare_final(name, straight, restarted):
    """The final bodies of a restarted run against the uninterrupted run's. Not bitwise: the
    stop checkpoint is one the straight run never wrote, and writing one re-anchors every
    body (as a restart does), so later states differ by round-off. The balls never meet, so
    that round-off is not amplified: positions within 1e-9 m (the minimum separation is
    2e-5 m, and round-off at 1 m is 1e-16 m; the impacts' times of contact, found to a
    fraction of the minimum separation, may shift by a different number of advancement
    iterations, which 1e-9 m still allows for a shift of 1e-10 m), velocities within 1e-7 m/s."""
    a_attrs, a = checkpoint(os.path.join(straight, "checkpoint_final.h5"))
    b_attrs, b = checkpoint(os.path.join(restarted, "checkpoint_final.h5"))
    c.check(a_attrs["time"] == b_attrs["time"], f"{name}: the restarted run ends at t_end ({b_attrs['time']})")
    dx, dv = np.abs(a["x"] - b["x"]).max(), np.abs(a["v"] - b["v"]).max()
    print(f"{name}: stopped and restarted against uninterrupted: |dx| {dx:.2e} m, |dv| {dv:.2e} m/s")
    c.check(dx <= 1e-9 and dv <= 1e-7, f"{name}: final state as the uninterrupted run's: |dx| {dx:.2e} m, |dv| {dv:.2e} m/s")


def stop_case(name, deck_path, straight, how, expected_rc, checkpoint_name):
    out, log = os.path.join(work, name), os.path.join(work, name + ".log")
    proc = started(exe, deck_path, out, log)
    if how == "wall_limit":
        proc.wait(timeout=120)
    else:
        c.check(wait_for_progress(proc, log), f"{name}: a progress line in the log while running")
        proc.send_signal(how)
        proc.wait(timeout=120)
    stderr = proc.stderr.read()
    with open(log) as f:
        text = f.read()
    lines = text.splitlines()
    path = os.path.join(out, checkpoint_name)
    c.check(proc.returncode == expected_rc, f"{name}: exit status {proc.returncode}, expected {expected_rc} ({stderr.strip()})")
    c.check(stderr.strip() == "", f"{name}: nothing on stderr: {stderr.strip()!r}")
    c.check(os.path.exists(path), f"{name}: {checkpoint_name} written")
    c.check(not os.path.exists(os.path.join(out, "checkpoint_final.h5")), f"{name}: no final checkpoint")
    # The log as a batch job keeps it: header, progress lines, and the stop line last.
    c.check(len(lines) >= 3 and lines[0].startswith("ricochet ") and any(l.startswith("  t = ") for l in lines),
            f"{name}: the redirected log has the header and progress lines: {lines[:3]}")
    last = lines[-1] if lines else ""
    c.check(last.startswith("ricochet: ") and path in last and f"--restart {path}" in last and " at t = " in last,
            f"{name}: the last line says why, when, where the checkpoint is, how to go on: {last!r}")
    if how == "wall_limit":
        c.check("wall_limit" in last, f"{name}: the line names wall_limit")
        # wall_limit may change on restart (as t_end may): the rest of the run without it.
        with open(deck_path) as f:
            text = f.read()
        deck_path = os.path.join(work, name + "_unlimited.nml")
        with open(deck_path, "w") as f:
            f.write(text.replace(", wall_limit = 0.1", ""))
    else:
        c.check(("SIGTERM" if how == signal.SIGTERM else "SIGINT") in last, f"{name}: the line names the signal")
    if os.path.exists(path):
        attrs = checkpoint(path)[0]
        c.check(0.0 < attrs["time"] < 8.0, f"{name}: stopped before t_end (t = {attrs['time']})")
        proc = run(exe, deck_path, out, "--restart", path, expect_ok=False)
        c.check(proc.returncode == 0, f"{name}: the restart finishes (exit {proc.returncode}, {proc.stderr.strip()})")
        if proc.returncode == 0:
            compare_final(name, straight, out)


local = deck("balls_local", 25, 8.0)
glob = deck("balls_global", 12, 8.0, integrator="&integrator events = 'global', rotation = 'newmark' /")
straight_local, straight_global = os.path.join(work, "straight_local"), os.path.join(work, "straight_global")
for d, straight in ((local, straight_local), (glob, straight_global)):
    shutil.rmtree(straight, ignore_errors=True)
    clock = time.time()
    run(exe, d, straight)
    print(f"{os.path.basename(d)}: {time.time() - clock:.2f} s uninterrupted")

stop_case("sigterm_local", local, straight_local, signal.SIGTERM, 143, "checkpoint_signal.h5")
stop_case("sigint_global", glob, straight_global, signal.SIGINT, 130, "checkpoint_signal.h5")
limited = deck("balls_wall_limit", 25, 8.0, extra_run=", wall_limit = 0.1")
stop_case("wall_limit", limited, straight_local, "wall_limit", 75, "checkpoint_wall_limit.h5")
c.finish()
