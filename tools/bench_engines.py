#!/usr/bin/env python3
"""Reference collision scenes (gas, bouncing ball) in PyBullet and MuJoCo.

For side-by-side comparison with ricochet's collision benchmarks; docs/bench/engines.md
describes the scenes exactly.

Scenes (each takes a body count or a time step list):
  gas    N spheres (r 0.05 m) or cubes (edge 0.1 m), density 1000 kg/m^3, in a closed static
         box sized for a 5% volume fraction, rms speed 1 m/s, no gravity, no friction,
         restitution 1 (MuJoCo: undamped contact spring, it has no restitution).
  ball   sphere r 0.1 m, bottom 1 m above a static floor, e = 0.8, g = 9.81: apexes of the
         first 5 bounces against h0 e^(2k), for time steps 1e-2 .. 1e-4 s.

The resting-contact scenes (the stack of 10 cubes, the pyramid, the piles) are in
tools/bench_resting.py, which extends the engine classes below.

Timing: time.perf_counter around the engine's step call only (set-up, contact queries and
energy bookkeeping are outside); reported per simulated second, over the whole run and over
its second half (the gas starts with no gap under 5 mm). ricochet (--engines ricochet) runs
as a program on a deck of the same bodies and is timed by its history's wall clock from
t = 0 (after set-up) to t_end. Penetration: the most
negative contact distance seen after any step (PyBullet getContactPoints contactDistance,
MuJoCo data.contact.dist).

    .venv/bin/python tools/bench_engines.py                 # all scenes, ~10 min
    .venv/bin/python tools/bench_engines.py --quick         # under a minute, N <= 3000
    .venv/bin/python tools/bench_engines.py --scenes gas --gas-n 100 1000 --engines mujoco
    .venv/bin/python tools/bench_engines.py --dump-initial /tmp/gas   # initial states as CSV
    # large gases: shorter simulated times for large N, own output files
    .venv/bin/python tools/bench_engines.py --scenes gas --engines ricochet pybullet mujoco \
        --gas-n 100 1000 10000 100000 --gas-t 0.5 --gas-t-for 10000=0.05 100000=0.02 \
        --budget 3600 --tag large      # -> docs/bench/engines_gas_large.{md,json}

Install the engines with `.venv/bin/pip install pybullet mujoco`; a missing engine is
skipped with a message. Writes docs/bench/engines_<scene>.md and docs/bench/engines.json.
"""
import argparse
import functools
import json
import math
import os
import platform
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

RHO = 1000.0            # density of every moving body [kg/m^3]
SPHERE_R = 0.05         # gas sphere radius [m]
CUBE_A = 0.1            # cube edge [m]
PHI = 0.05              # gas volume fraction
WALL_T = 0.2            # container wall thickness [m]
GAP = 0.005             # smallest initial clearance between bodies, and to walls [m]
SEED = 12345            # numpy default_rng seed of the gas initial state
G = 9.81                # gravity [m/s^2]
BALL_R, BALL_H0, BALL_E = 0.1, 1.0, 0.8
MJ_MAX_ARENA_MB = 4096  # largest MuJoCo arena this script asks for [MB]
MJ_CONTACT_TIME = 0.02  # MuJoCo contact half-period for the spring standing in for e [s]


# ----------------------------------------------------------------------------- scenes

@functools.lru_cache(maxsize=2)
def gas_setup(n, shape, seed=SEED):
    """Deterministic gas: box edge L, centres, unit quaternions (w, x, y, z), velocities.

    Box interior [0, L]^3 with L = (n v / PHI)^(1/3), v the body volume. Centres by random
    sequential addition: candidates uniform in [rex + GAP, L - rex - GAP]^3, accepted when
    at least 2 rex + GAP from every accepted centre, rex the bounding radius (r for a
    sphere, a sqrt(3)/2 for a cube, so any orientation is overlap-free). Quaternions:
    uniform random (normalised 4-d normals, w >= 0), drawn after the positions (cubes
    only). Velocities: normals / sqrt(3), mean removed, scaled to rms speed 1 m/s exactly.
    Angular velocities zero.
    """
    rng = np.random.default_rng(seed)
    vol = 4.0 / 3.0 * math.pi * SPHERE_R ** 3 if shape == 'sphere' else CUBE_A ** 3
    L = (n * vol / PHI) ** (1.0 / 3.0)
    rex = SPHERE_R if shape == 'sphere' else CUBE_A * math.sqrt(3.0) / 2.0
    dmin = 2.0 * rex + GAP
    lo, hi = rex + GAP, L - rex - GAP
    cell = dmin
    grid = {}
    pos = np.empty((n, 3))
    k = 0
    while k < n:
        cand = rng.uniform(lo, hi, size=(1024, 3))
        for c in cand:
            ijk = tuple((c // cell).astype(int))
            ok = True
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    for dk in (-1, 0, 1):
                        for j in grid.get((ijk[0] + di, ijk[1] + dj, ijk[2] + dk), ()):
                            if np.sum((pos[j] - c) ** 2) < dmin * dmin:
                                ok = False
                                break
                        if not ok:
                            break
                    if not ok:
                        break
                if not ok:
                    break
            if ok:
                pos[k] = c
                grid.setdefault(ijk, []).append(k)
                k += 1
                if k == n:
                    break
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    if shape == 'cube':
        quat = rng.normal(size=(n, 4))
        quat /= np.linalg.norm(quat, axis=1)[:, None]
        quat[quat[:, 0] < 0] *= -1.0
    vel = rng.normal(size=(n, 3)) / math.sqrt(3.0)
    vel -= vel.mean(axis=0)
    vel /= math.sqrt(np.mean(np.sum(vel ** 2, axis=1)))
    mass = RHO * vol
    inertia = (0.4 * mass * SPHERE_R ** 2 if shape == 'sphere' else mass * CUBE_A ** 2 / 6.0)
    return dict(L=L, pos=pos, quat=quat, vel=vel, mass=mass, inertia=inertia, rex=rex)


def energy_momentum(mass, inertia, v, w):
    """Kinetic energy (translation + rotation; both shapes have isotropic inertia) and
    total linear momentum."""
    e = 0.5 * mass * np.sum(v ** 2) + 0.5 * inertia * np.sum(w ** 2)
    return e, mass * v.sum(axis=0)


def apexes(z, k=5):
    """Heights of the first k local maxima after the first contact, refined by the parabola
    through the three samples around each (exact for a ballistic sampled trajectory)."""
    out = []
    for i in range(1, len(z) - 1):
        if z[i] > z[i - 1] and z[i] >= z[i + 1] and i > 2:
            a, b, c = z[i - 1], z[i], z[i + 1]
            den = a - 2 * b + c
            out.append(b - (a - c) ** 2 / (8 * den) if den < 0 else b)
            if len(out) == k:
                break
    return out


# ----------------------------------------------------------------------------- PyBullet

class Bullet:
    name = 'pybullet'

    def __init__(self):
        import pybullet
        self.p = pybullet
        self.cid = pybullet.connect(pybullet.DIRECT)
        self.version = 'pybullet %s (Bullet API %d)' % (
            _dist_version('pybullet'), pybullet.getAPIVersion())
        # resetSimulation keeps the last time step: remember the default (1/240 s).
        self.dt0 = pybullet.getPhysicsEngineParameters(physicsClientId=self.cid)['fixedTimeStep']

    def reset(self, dt=None, gravity=0.0):
        p = self.p
        p.resetSimulation(physicsClientId=self.cid)
        p.setGravity(0, 0, -gravity, physicsClientId=self.cid)
        p.setTimeStep(self.dt0 if dt is None else dt, physicsClientId=self.cid)
        return p.getPhysicsEngineParameters(physicsClientId=self.cid)['fixedTimeStep']

    def _dyn(self, b, restitution, friction):
        # Bullet combines restitution and friction of a pair as the product: callers pass
        # per-body values whose product is the wanted pair value. No drag in any scene.
        self.p.changeDynamics(b, -1, restitution=restitution, lateralFriction=friction,
                              rollingFriction=0.0, spinningFriction=0.0, linearDamping=0.0,
                              angularDamping=0.0, physicsClientId=self.cid)

    def settings(self):
        return self.p.getPhysicsEngineParameters(physicsClientId=self.cid)

    def ncontacts(self):
        return len(self.p.getContactPoints(physicsClientId=self.cid))

    def min_dist(self):
        cps = self.p.getContactPoints(physicsClientId=self.cid)
        return min((c[8] for c in cps), default=math.inf)

    def gas(self, n, shape, t_end, budget):
        p, cid = self.p, self.cid
        s = gas_setup(n, shape)
        L = s['L']
        dt = self.reset()
        for axis in range(3):
            for side in (-1, 1):
                ext = [L / 2 + WALL_T] * 3
                ext[axis] = WALL_T / 2
                c = [L / 2] * 3
                c[axis] = L / 2 + side * (L / 2 + WALL_T / 2)
                col = p.createCollisionShape(p.GEOM_BOX, halfExtents=ext, physicsClientId=cid)
                w = p.createMultiBody(0, col, basePosition=c, physicsClientId=cid)
                self._dyn(w, 1.0, 0.0)
        if shape == 'sphere':
            col = p.createCollisionShape(p.GEOM_SPHERE, radius=SPHERE_R, physicsClientId=cid)
        else:
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[CUBE_A / 2] * 3,
                                         physicsClientId=cid)
        ids = []
        for i0 in range(0, n, 1000):  # batchPositions creates many bodies in one call
            r = p.createMultiBody(s['mass'], col, batchPositions=s['pos'][i0:i0 + 1000].tolist(),
                                  useMaximalCoordinates=True, physicsClientId=cid)
            ids.extend(r if isinstance(r, (list, tuple)) else [r])
        for i, b in enumerate(ids):
            q = s['quat'][i]
            p.resetBasePositionAndOrientation(b, s['pos'][i], [q[1], q[2], q[3], q[0]],
                                              physicsClientId=cid)
            p.resetBaseVelocity(b, s['vel'][i], [0, 0, 0], physicsClientId=cid)
            self._dyn(b, 1.0, 0.0)

        def state():
            v = np.empty((n, 3)); w = np.empty((n, 3))
            for i, b in enumerate(ids):
                v[i], w[i] = p.getBaseVelocity(b, physicsClientId=cid)
            return v, w
        return self._run_gas(s, dt, t_end, budget, lambda: p.stepSimulation(physicsClientId=cid),
                             state, n)

    def _run_gas(self, s, dt, t_end, budget, step, state, n):
        e0, p0 = energy_momentum(s['mass'], s['inertia'], *state())
        nsteps = int(round(t_end / dt))
        every = 1 if n <= 1000 else 10
        tstep, dmin, k = 0.0, math.inf, 0
        half, t_half = nsteps // 2, 0.0
        while k < nsteps:
            t0 = time.perf_counter()
            step()
            tstep += time.perf_counter() - t0
            k += 1
            if k == half:
                t_half = tstep
            if k % every == 0 or k == nsteps:   # and after the last step: short runs of large N
                dmin = min(dmin, self.min_dist())
            if k == 20 and tstep / 20 * nsteps > budget:
                return dict(skipped=True, predicted_s=tstep / 20 * nsteps, dt=dt)
        e1, p1 = energy_momentum(s['mass'], s['inertia'], *state())
        # Contacts open at the end: with MuJoCo's soft contacts part of the energy then sits
        # in the contact springs and is missing from the kinetic energy e1.
        ncon = self.ncontacts()
        return dict(dt=dt, steps=nsteps, t_sim=nsteps * dt, wall_step=tstep,
                    wall_per_sim_s=tstep / (nsteps * dt),
                    wall_per_sim_s_late=(tstep - t_half) / ((nsteps - half) * dt), max_pen=max(0.0, -dmin),
                    pen_every=every, e_drift=(e1 - e0) / e0,
                    p_drift=float(np.linalg.norm(p1 - p0) / (n * s['mass'] * 1.0)),
                    L=s['L'], contacts_end=ncon)

    def ball(self, dt, t_end):
        p, cid = self.p, self.cid
        self.reset(dt, G)
        floor = p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid),
                                  physicsClientId=cid)
        self._dyn(floor, 1.0, 0.0)
        m = RHO * 4.0 / 3.0 * math.pi * BALL_R ** 3
        b = p.createMultiBody(m, p.createCollisionShape(p.GEOM_SPHERE, radius=BALL_R,
                                                        physicsClientId=cid),
                              basePosition=[0, 0, BALL_R + BALL_H0], useMaximalCoordinates=True,
                              physicsClientId=cid)
        self._dyn(b, BALL_E, 0.0)
        return self._run_ball(dt, t_end, lambda: p.stepSimulation(physicsClientId=cid),
                              lambda: p.getBasePositionAndOrientation(b, physicsClientId=cid)[0][2])

    def _run_ball(self, dt, t_end, step, z):
        nsteps = int(round(t_end / dt))
        zs = np.empty(nsteps)
        tstep, dmin = 0.0, math.inf
        for k in range(nsteps):
            t0 = time.perf_counter()
            step()
            tstep += time.perf_counter() - t0
            zs[k] = z() - BALL_R
            dmin = min(dmin, self.min_dist())
        h = apexes(zs)
        ref = [BALL_H0 * BALL_E ** (2 * k) for k in range(1, 6)]
        return dict(dt=dt, steps=nsteps, wall_per_sim_s=tstep / (nsteps * dt),
                    max_pen=max(0.0, -dmin), apex=h,
                    rel_err=[(a - r) / r for a, r in zip(h, ref)])


# ----------------------------------------------------------------------------- MuJoCo

def _dist_version(name):
    try:
        from importlib.metadata import version
        return version(name)
    except Exception:
        return '?'


def _mj_solref(e, tc=MJ_CONTACT_TIME):
    """Direct-form solref (-stiffness, -damping) of the mass-normalised spring-damper whose
    half-period is tc and whose restitution is e: w = pi/tc, zeta from e = exp(-zeta pi /
    sqrt(1 - zeta^2)), k = w^2, b = 2 zeta w. MuJoCo has no restitution coefficient."""
    w = math.pi / tc
    le = -math.log(e) if e < 1 else 0.0
    zeta = le / math.sqrt(math.pi ** 2 + le ** 2)
    return '%.9g %.9g' % (-w * w, -2 * zeta * w)


class Mujoco(Bullet):
    name = 'mujoco'

    def __init__(self):
        import mujoco
        self.mj = mujoco
        self.version = 'mujoco %s' % mujoco.__version__

    def settings(self):
        o = self.m.opt
        return dict(timestep=o.timestep, integrator=int(o.integrator), solver=int(o.solver),
                    cone=int(o.cone), iterations=int(o.iterations), tolerance=o.tolerance,
                    ls_iterations=int(o.ls_iterations), noslip_iterations=int(o.noslip_iterations),
                    o_solref=o.o_solref.tolist(), o_solimp=o.o_solimp.tolist())

    def ncontacts(self):
        return int(self.d.ncon)

    def min_dist(self):
        nc = self.d.ncon
        return float(self.d.contact.dist[:nc].min()) if nc else math.inf

    def _load(self, xml):
        self.m = self.mj.MjModel.from_xml_string(xml)
        self.d = self.mj.MjData(self.m)
        self.mj.mj_forward(self.m, self.d)
        return self.m.opt.timestep

    def gas(self, n, shape, t_end, budget):
        mj = self.mj
        # The broad phase takes ~4 bytes per geom pair from the arena (measured: two 200 MB
        # blocks at 10^4 bodies), so the arena grows like n^2 (6 bytes per pair asked for).
        mem_mb = 64 + int(6.0 * (n + 6) ** 2 / 2 ** 20)
        if mem_mb > MJ_MAX_ARENA_MB:
            return dict(skipped=True, cheap_skip=True,
                        reason='not run: needs %.0f GB of arena (~4 bytes per geom pair in the '
                        'broad phase; --mj-max-arena-mb %d)' % (mem_mb / 1024, MJ_MAX_ARENA_MB))
        s = gas_setup(n, shape)
        L = s['L']
        walls = []
        for axis in range(3):
            for side in (-1, 1):
                ext = [L / 2 + WALL_T] * 3
                ext[axis] = WALL_T / 2
                c = [L / 2] * 3
                c[axis] = L / 2 + side * (L / 2 + WALL_T / 2)
                walls.append('<geom type="box" size="%.9g %.9g %.9g" pos="%.9g %.9g %.9g"/>'
                             % (*ext, *c))
        g = ('type="sphere" size="%g"' % SPHERE_R if shape == 'sphere'
             else 'type="box" size="%g %g %g"' % ((CUBE_A / 2,) * 3))
        bodies = ['<body pos="%.12g %.12g %.12g" quat="%.12g %.12g %.12g %.12g"><freejoint/>'
                  '<geom %s/></body>' % (*s['pos'][i], *s['quat'][i], g) for i in range(n)]
        # condim 1: frictionless contacts; the undamped spring stands in for e = 1.
        xml = ('<mujoco><option gravity="0 0 0"/><size memory="%dM"/>'
               '<default><geom density="%g" condim="1" solref="%s"/></default>'
               '<worldbody>%s%s</worldbody></mujoco>'
               % (mem_mb, RHO, _mj_solref(1.0), ''.join(walls), ''.join(bodies)))
        dt = self._load(xml)
        self.d.qvel[:] = np.hstack([s['vel'], np.zeros((n, 3))]).ravel()
        mj.mj_forward(self.m, self.d)

        def state():
            qv = self.d.qvel.reshape(n, 6)
            return qv[:, :3].copy(), qv[:, 3:].copy()
        m, d = self.m, self.d
        out = self._run_gas(s, dt, t_end, budget, lambda: mj.mj_step(m, d), state, n)
        out['mass_model'] = float(self.m.body_mass[1])
        return out

    def ball(self, dt, t_end):
        xml = ('<mujoco><option timestep="%g"/><worldbody>'
               '<geom type="plane" size="5 5 0.1" condim="1" solref="%s"/>'
               '<body pos="0 0 %g"><freejoint/><geom type="sphere" size="%g" density="%g" '
               'condim="1" solref="%s"/></body></worldbody></mujoco>'
               % (dt, _mj_solref(BALL_E), BALL_R + BALL_H0, BALL_R, RHO, _mj_solref(BALL_E)))
        self._load(xml)
        m, d = self.m, self.d
        return self._run_ball(dt, t_end, lambda: self.mj.mj_step(m, d), lambda: d.qpos[2])


# ----------------------------------------------------------------------------- driver

class Ricochet:
    """ricochet itself, run as a program on a deck that holds exactly the same bodies (one
    &body per body: position, orientation, velocity) and walls. Timing: the stepping time,
    from the history's wall clock between its rows at t = 0 (after the set-up) and t_end,
    per simulated second (set-up, the final checkpoint and reading the deck are outside, as
    they are for the other engines); the whole process and the run's own wall time are
    kept beside it. Penetration: ricochet never allows
    any; its smallest separation is reported instead (negative would be a penetration)."""
    name = 'ricochet'
    events = 'auto'     # &integrator events: the local loop with exact rotation

    def __init__(self):
        self.exe = os.environ.get('RICOCHET_EXE', os.path.join(ROOT, 'build', 'app', 'ricochet'))
        if not os.path.exists(self.exe):
            raise ImportError('no ricochet program at %s (build it first)' % self.exe)
        self.version = 'ricochet (this repository)' + ('' if self.events == 'auto' else ', %s event loop' % self.events)
        self.keep_history = None   # folder to copy each run's history.csv into, or None

    def settings(self):
        return dict(restitution=1.0, min_separation='auto (1e-4 of the smallest body)', rotation='exact')

    def gas(self, n, shape, t_end, budget):
        import subprocess
        import tempfile
        s = gas_setup(n, shape)
        L = s['L']
        lines = ["&run title='gas %s %d', t_end=%r, dt_max=1e-2 /" % (shape, n, t_end),
                 "&contact restitution=1.0 /",
                 "&integrator events='%s' /" % self.events,
                 "&output write_frames=.false., history_interval=%r /" % (t_end / 10)]
        for axis in range(3):
            for side in (-1, 1):
                size = [L + 2 * WALL_T] * 3
                size[axis] = WALL_T
                c = [L / 2] * 3
                c[axis] = L / 2 + side * (L / 2 + WALL_T / 2)
                lines.append("&body name='wall%d%+d', shape='box', size=%r,%r,%r, position=%r,%r,%r, fixed=.true. /"
                             % (axis, side, *map(float, size), *map(float, c)))
        body = ("shape='sphere', radius=%r" % SPHERE_R) if shape == 'sphere' else ("shape='box', size=%r,%r,%r" % ((CUBE_A,) * 3))
        for k in range(n):
            q = s['quat'][k]
            lines.append("&body name='b%d', %s, density=%r, position=%r,%r,%r, orientation=%r,%r,%r,%r, velocity=%r,%r,%r /"
                         % (k, body, RHO, *map(float, s['pos'][k]), *map(float, q), *map(float, s['vel'][k])))
        with tempfile.TemporaryDirectory() as work:
            deck = os.path.join(work, 'gas.nml')
            with open(deck, 'w') as f:
                f.write('\n'.join(lines) + '\n')
            t0 = time.perf_counter()
            try:
                proc = subprocess.run([self.exe, deck, '--output-dir', os.path.join(work, 'out')],
                                      capture_output=True, text=True, timeout=budget)
            except subprocess.TimeoutExpired:
                return dict(skipped=True, reason='stopped after the %g s budget' % budget)
            process_wall = time.perf_counter() - t0
            if proc.returncode != 0:
                raise RuntimeError(proc.stderr)
            if self.keep_history:
                import shutil
                os.makedirs(self.keep_history, exist_ok=True)
                shutil.copy(os.path.join(work, 'out', 'history.csv'),
                            os.path.join(self.keep_history, 'history_%s_%d.csv' % (shape, n)))
            with open(os.path.join(work, 'out', 'history.csv')) as f:
                names = [c.strip().split(' [')[0] for c in f.readline().split(',')]
            hist = np.loadtxt(os.path.join(work, 'out', 'history.csv'), delimiter=',', skiprows=1, ndmin=2)
        col = {k: hist[:, names.index(k)] for k in names}
        # Stepping time: the history's wall clock from the row written at t = 0 (end of the
        # set-up: shapes, bodies, overlap check, grid) to the row at t_end, so that large N
        # compares with the other engines' step-only timing. The run's own 'wall time' also
        # holds the set-up and the final checkpoint; reading the deck is outside both.
        wall = float(col['wall_time'][-1] - col['wall_time'][0])
        out = proc.stdout
        run_wall = float(out.split('wall time')[1].split()[0])
        sep = float(out.split('smallest separation')[1].split()[0])
        ev = out.split('contact events')[1].split()
        events, points, groups = int(ev[0]), int(ev[1].lstrip('(')), int(ev[4])
        queries = int(out.split('time of contact')[1].split()[0])
        e0 = col['kinetic_translational'][0] + col['kinetic_rotational'][0]
        e1 = col['kinetic_translational'][-1] + col['kinetic_rotational'][-1]
        p0 = np.array([col['momentum_%s' % c][0] for c in 'xyz'])
        p1 = np.array([col['momentum_%s' % c][-1] for c in 'xyz'])
        steps = int(col['steps'][-1])
        # Second half of the run: the gas starts with every gap >= GAP (5 mm between bounding
        # spheres, more between cube faces), so the first milliseconds have fewer events.
        h = int(np.argmax(col['time'] >= 0.5 * t_end - 1e-12))
        late_t = float(col['time'][-1] - col['time'][h])
        late_wall = float(col['wall_time'][-1] - col['wall_time'][h])
        late_events = int(col['events'][-1] - col['events'][h])
        return dict(dt=float('nan'), steps=steps, t_sim=t_end, wall_step=wall, wall_per_sim_s=wall / t_end,
                    wall_per_sim_s_late=late_wall / late_t, events_late=late_events, t_late=late_t,
                    wall_per_event_late=late_wall / max(late_events, 1),
                    run_wall=run_wall, process_wall=process_wall, setup_wall=float(col['wall_time'][0]),
                    events=events, contact_points=points, impulse_groups=groups, pair_queries=queries,
                    groups_per_event=groups / max(events, 1), wall_per_event=wall / max(events, 1),
                    max_pen=max(0.0, -sep), smallest_separation=sep, e_drift=(e1 - e0) / e0,
                    p_drift=float(np.linalg.norm(p1 - p0) / (n * s['mass'] * 1.0)), L=L, contacts_end=0)

    def ball(self, dt, t_end):
        raise NotImplementedError('ricochet runs the bouncing ball as input/validation/bouncing_ball.nml')




class RicochetGlobal(Ricochet):
    """ricochet's global event loop (&integrator events = 'global'): every event a step of
    the whole scene; the reference the local loop is measured against."""
    name = 'ricochet-global'
    events = 'global'

def fmt(x, spec='%.3g'):
    return '-' if x is None else spec % x


def write_md(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + '.tmp'
    with open(tmp, 'w') as f:
        f.write(text)
    os.replace(tmp, path)


def growth_exponents(runs, key='wall_per_sim_s'):
    """Least-squares slope of log(key) against log(N) per (shape, engine), over the runs
    that ran; with the N range it covers."""
    out = []
    for shape in sorted(set(r['shape'] for r in runs)):
        for eng in sorted(set(r['engine'] for r in runs)):
            rs = [r for r in runs if r['shape'] == shape and r['engine'] == eng
                  and not r.get('skipped') and r.get(key, 0) > 0]
            if len(rs) >= 2:
                x = np.log([r['n'] for r in rs])
                y = np.log([r[key] for r in rs])
                slope = float(np.polyfit(x, y, 1)[0])
                pairs = ['%.2f' % (math.log(b[key] / a_[key]) / math.log(b['n'] / a_['n']))
                         for a_, b in zip(rs, rs[1:])]
                out.append((shape, eng, min(r['n'] for r in rs), max(r['n'] for r in rs), slope, pairs))
    return out


def write_gas_md(a, results, rows, sfx):
    runs = results['runs'].get('gas', [])
    hdr = ('| scene | engine | N | simulated [s] | time per simulated second [s], whole run | same, second half '
           '| largest penetration [m] | energy / momentum drift |\n|---|---|---|---|---|---|---|---|\n')
    md = ('Dilute gas, engine default time step, simulated time per run as listed. Timing: '
          'stepping only (ricochet: history wall clock from t = 0 to t_end, after the set-up). '
          'Drift: relative kinetic energy change (E1-E0)/E0; momentum |P1-P0| / (N m * 1 m/s).\n\n'
          'Machine: %s, %d cores, Python %s; %s.\n\n' % (
              platform.platform(), os.cpu_count(), platform.python_version(),
              ', '.join(results['engines'].values()))
          + hdr + '\n'.join(rows) + '\n')
    ric = [r for r in runs if r['engine'].startswith('ricochet') and not r.get('skipped')]
    if ric:
        md += ('\nricochet in detail (stepping = history wall clock t = 0 .. t_end; set-up = '
               'history wall clock at t = 0; process = whole program, deck reading included):\n\n'
               '| shape | N | simulated [s] | steps | events | events per N per simulated s, second half '
               '| impulse groups | groups per event | pair queries per step | stepping [s] | per event [s] '
               '| per event, second half [s] | set-up [s] | process [s] |\n'
               '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n')
        for r in ric:
            md += '| %s | %d | %g | %d | %d | %.2f | %d | %.2f | %.1f | %.3g | %.3g | %.3g | %.3g | %.3g |\n' % (
                r['shape'] + ('' if r['engine'] == 'ricochet' else ' (global loop)'), r['n'], r['t_sim'], r['steps'], r['events'], r['events_late'] / r['n'] / r['t_late'],
                r['impulse_groups'], r['groups_per_event'], r['pair_queries'] / max(r['steps'], 1),
                r['wall_step'], r['wall_per_event'], r['wall_per_event_late'], r['setup_wall'], r['process_wall'])
    ric_runs = [r for r in runs if r['engine'].startswith('ricochet')]
    ex = [('time per simulated second, whole run',) + x for x in growth_exponents(runs)]
    ex += [('time per simulated second, second half',) + x for x in growth_exponents(runs, 'wall_per_sim_s_late')]
    ex += [('time per event, whole run',) + x for x in growth_exponents(ric_runs, 'wall_per_event')]
    ex += [('time per event, second half',) + x for x in growth_exponents(ric_runs, 'wall_per_event_late')]
    if ex:
        md += '\nGrowth exponents (least squares over the N that ran; successive pairs in brackets):\n\n'
        for what, shape, eng, lo, hi, slope, pairs in ex:
            md += '- %s, %s, %s: n^%.2f (N %d..%d) [%s]\n' % (shape, eng, what, slope, lo, hi, ', '.join(pairs))
    write_md(os.path.join(a.out, 'engines_gas%s.md' % sfx), md)


def main():
    global MJ_MAX_ARENA_MB
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--quick', action='store_true', help='gas up to N = 3000, three time steps (under a minute)')
    ap.add_argument('--scenes', nargs='+', default=['gas', 'ball'], help='gas, ball (the stack is in bench_resting.py)')
    ap.add_argument('--engines', nargs='+', default=['pybullet', 'mujoco'],
                    help='pybullet, mujoco, ricochet, ricochet-global (the global event loop; gas only: the ball is a validation deck)')
    ap.add_argument('--gas-n', type=int, nargs='+', help='gas body counts')
    ap.add_argument('--gas-shapes', nargs='+', default=['sphere', 'cube'])
    ap.add_argument('--gas-t', type=float, help='simulated gas time [s]')
    ap.add_argument('--gas-t-for', nargs='+', default=[], metavar='N=T',
                    help='simulated gas time T [s] for body count N (shorter runs for large N); '
                    'SHAPE:N=T for one shape only')
    ap.add_argument('--keep-history', metavar='DIR',
                    help="copy each ricochet gas run's history.csv (rows every t/10) into DIR")
    ap.add_argument('--tag', default='', help='suffix of the output files: engines_gas_TAG.{md,json}')
    ap.add_argument('--mj-max-arena-mb', type=int, default=MJ_MAX_ARENA_MB,
                    help='largest MuJoCo arena to ask for [MB]; larger gases are reported as not run')
    ap.add_argument('--budget', type=float, default=60.0,
                    help='skip a gas run (and larger N) predicted to step longer [s]')
    ap.add_argument('--dts', type=float, nargs='+', help='ball time steps [s]')
    ap.add_argument('--out', default=os.path.join(ROOT, 'docs', 'bench'))
    ap.add_argument('--dump-initial', metavar='DIR',
                    help='write the gas initial states (CSV) for the sizes and exit')
    a = ap.parse_args()
    MJ_MAX_ARENA_MB = a.mj_max_arena_mb
    gas_n = a.gas_n or ([100, 1000, 3000] if a.quick else [100, 1000, 3000, 10000, 30000, 100000])
    gas_t = a.gas_t or 1.0
    # N=T for both shapes, or SHAPE:N=T for one (cube:100000=0.01)
    gas_t_for = {(k.split(':')[0] if ':' in k else None, int(k.split(':')[-1])): float(v)
                 for k, v in (x.split('=') for x in a.gas_t_for)}
    dts = a.dts or ([1e-2, 1e-3, 1e-4] if a.quick else [1e-2, 3e-3, 1e-3, 3e-4, 1e-4])

    if a.dump_initial:
        os.makedirs(a.dump_initial, exist_ok=True)
        for shape in a.gas_shapes:
            for n in gas_n:
                s = gas_setup(n, shape)
                fn = os.path.join(a.dump_initial, 'gas_%s_%d.csv' % (shape, n))
                hdr = 'box interior [0,%.12g]^3 m, mass %.12g kg; x y z qw qx qy qz vx vy vz' % (
                    s['L'], s['mass'])
                np.savetxt(fn, np.hstack([s['pos'], s['quat'], s['vel']]), fmt='%.17g',
                           delimiter=',', header=hdr)
                print('wrote', fn)
        return

    engines = []
    for e in a.engines:
        try:
            engines.append({'pybullet': Bullet, 'mujoco': Mujoco, 'ricochet': Ricochet,
                            'ricochet-global': RicochetGlobal}[e]())
        except ImportError as err:
            print('skipping %s: %s (pip install %s)' % (e, err, e), file=sys.stderr)
    for e in engines:
        if e.name.startswith('ricochet'):
            e.keep_history = a.keep_history
    results = dict(machine=platform.platform(), python=platform.python_version(),
                   engines={e.name: e.version for e in engines}, quick=a.quick, runs={})
    sfx = ('_quick' if a.quick else '') + ('_' + a.tag if a.tag else '')
    jpath = os.path.join(a.out, ('engines_gas_%s.json' % a.tag) if a.tag else 'engines%s.json' % sfx)
    hdr = '| scene | engine | %s | time per simulated second [s] | largest penetration [m] | %s |\n|---|---|---|---|---|---|\n'

    if 'gas' in a.scenes:
        rows = []
        for shape in a.gas_shapes:
            stopped_by = {e.name: False for e in engines}
            # N outside, engines inside: the runs of one scene follow each other (and share
            # the cached initial state).
            for n in gas_n:
                for e in engines:
                    stopped = stopped_by[e.name]
                    t_sim = gas_t_for.get((shape, n), gas_t_for.get((None, n), gas_t))
                    if stopped:
                        r = dict(skipped=True, reason='a smaller N was already skipped')
                    else:
                        t0 = time.perf_counter()
                        r = e.gas(n, shape, t_sim, a.budget)
                        r['wall_total'] = time.perf_counter() - t0
                        # A run skipped for its predicted cost stops the larger ones; one
                        # skipped for memory (found before any work) does not.
                        stopped_by[e.name] = r.get('skipped', False) and not r.get('cheap_skip', False)
                    if not r.get('skipped'):
                        r['settings'] = e.settings()
                    results['runs'].setdefault('gas', []).append(dict(engine=e.name, shape=shape, n=n,
                                                                      t_sim_asked=t_sim, **r))
                    if r.get('skipped'):
                        why = r.get('reason') or ('skipped: predicted %.0f s of stepping > %g s budget'
                                                   % (r['predicted_s'], a.budget))
                        line = '| gas %s | %s | %d | %g | %s | - | - | - |' % (
                            shape, e.name, n, t_sim, why if why.startswith('not run') else 'skipped: ' + why)
                    else:
                        pen = fmt(r['max_pen'])
                        if 'smallest_separation' in r:
                            pen += ' (smallest gap %.2e)' % r['smallest_separation']
                        line = '| gas %s | %s | %d | %g | %s | %s | %s | energy %+.2e, momentum %.2e |' % (
                            shape, e.name, n, t_sim, fmt(r['wall_per_sim_s']), fmt(r['wall_per_sim_s_late']),
                            pen, r['e_drift'], r['p_drift'])
                    print(line, flush=True)
                    rows.append(line)
                    write_gas_md(a, results, rows, sfx)
                    write_md(jpath, json.dumps(results, indent=1))

    if 'ball' in a.scenes:
        rows = []
        for e in engines:
            for dt in dts:
                r = e.ball(dt, 3.5)
                r['settings'] = e.settings()
                results['runs'].setdefault('ball', []).append(dict(engine=e.name, **r))
                err = ', '.join('%+.1e' % x for x in r['rel_err'])
                line = '| ball | %s | %g | %s | %s | %s |' % (
                    e.name, dt, fmt(r['wall_per_sim_s']), fmt(r['max_pen']),
                    (err or 'no bounce') + ('' if len(r['rel_err']) == 5 else ' (%d apexes)' % len(r['rel_err'])))
                print(line, flush=True)
                rows.append(line)
        md = ('Bouncing ball: relative errors of the apex heights of bounces 1..5 against '
              'h0 e^(2k).\n\n' + hdr % ('dt [s]', 'apex errors k = 1..5') + '\n'.join(rows) + '\n')
        write_md(os.path.join(a.out, 'engines_ball%s.md' % sfx), md)
        write_md(jpath, json.dumps(results, indent=1))

    if 'stack' in a.scenes:
        print('the stack scene moved to tools/bench_resting.py (--scenes stack)', file=sys.stderr)


if __name__ == '__main__':
    main()
