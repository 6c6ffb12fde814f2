#!/usr/bin/env python3
"""Resting-contact scenes (stack, pyramid, piles) in PyBullet and MuJoCo, and ricochet decks of the same scenes.

Every scene is defined once, as the &body groups of a ricochet deck (shape, first position,
orientation, lattice copies and spacing, jitter seed and amplitudes). The Python engines
get their bodies by expanding those groups exactly as ricochet does (src/run/body_builder.f90
with the xoshiro256** stream of src/math/random_stream.f90, reproduced bit for bit below),
and `--write-decks` writes the same groups as input/validation/*.nml, so the decks and the
engine runs start from the same bodies by construction (`--check-decks` verifies the decks
on disk). docs/bench/engines.md describes the scenes exactly.

Scenes, all with gravity 9.81 m/s^2, Coulomb friction 0.5 on every pair, restitution 0
(MuJoCo: its default soft contact), density 1000 kg/m^3:
  stack     10 cubes (edge 0.1 m) on a static floor, 10 s: top-cube drift.
  pyramid   15 cubes in rows 5, 4, 3, 2, 1 (x-z plane, 1 mm gaps in a row), 10 s:
            largest drift of any cube.
  piles     N bodies poured from a jittered lattice into an open-top box: 1000 cubes,
            1000 regular tetrahedra (edge 0.15 m), 200 L-prisms (0.2 x 0.2 x 0.1 m, arms
            0.07 m; PyBullet and MuJoCo: a compound of two boxes); until the kinetic energy
            is below 1e-6 of the potential energy released, or 10 s simulated, or a
            stepping budget (then 1 s more is watched): time to rest, bodies that left
            the container, pile depth.

Timing, penetration and engine settings follow tools/bench_engines.py (whose engine classes
this script extends): time.perf_counter around the engine's step call only, per simulated
second; penetration = the most negative contact distance the engine reports after a step.

    .venv/bin/python tools/bench_resting.py                  # all scenes, full size (~20 min)
    .venv/bin/python tools/bench_resting.py --quick          # smaller piles, ~1 min
    .venv/bin/python tools/bench_resting.py --scenes stack pyramid --rest-gap 0   # touching
    .venv/bin/python tools/bench_resting.py --scenes pyramid --engines mujoco
    .venv/bin/python tools/bench_resting.py --scenes piles --piles cubes --pile-n 8 \
        --engines pybullet mujoco ricochet      # the suite's pile, ricochet beside them
    .venv/bin/python tools/bench_resting.py --write-decks    # input/validation/*.nml
    .venv/bin/python tools/bench_resting.py --check-decks    # decks on disk == scenes?

Writes docs/bench/engines_<scene>.md (engines_<scene>_quick.md with --quick) and the raw
numbers with each engine's settings to docs/bench/engines_resting[_quick].json. Pile runs
of other engines or piles already in that JSON stay in the pile table (`--engines` with no
name only rewrites it).
"""
import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_engines as be  # noqa: E402  (engine classes, timing and output helpers)

ROOT = be.ROOT
G = be.G                # gravity [m/s^2]
RHO = be.RHO            # density of every moving body [kg/m^3]
MU = 0.5                # Coulomb friction coefficient of every pair [-]
CUBE_A = be.CUBE_A      # cube edge [m]
TET_A = 0.15            # tetrahedron edge [m]
L_SIZE = (0.2, 0.2, 0.1)  # L-prism outer size x, y and extrusion z [m]
L_T = 0.07              # L-prism arm thickness [m]
REST_GAP = 1.0e-4       # vertical gap between faces that rest on each other at t = 0 [m]
PYR_GAP = 1.0e-3        # horizontal gap between the boxes of a pyramid row [m]
STACK_N, STACK_T = 10, 10.0            # cubes, simulated time [s]
PYR_ROWS, PYR_T = (5, 4, 3, 2, 1), 10.0  # cubes per row from the bottom, simulated time [s]
WALL_T = be.WALL_T      # container wall and floor thickness [m]
PILE_DEPTH = 5.0        # pile depth aimed at, in body heights h_b [-]
PILE_SEED = 2024        # jitter seed of the first lattice group of a pile (then +1, +2)
JITTER_POS = 0.005      # largest lattice jitter per axis [m]
CLEARANCE = 0.005       # smallest initial gap, body to body and body to wall, guaranteed [m]
REST_RATIO = 1.0e-6     # at rest: kinetic energy < REST_RATIO * potential energy released
PILE_T_CAP = 10.0       # simulated time cap of a pile [s]
PILE_BUDGET = 300.0     # default wall-clock cap on the stepping of one pile run [s]
PILE_CHECK_DT = 0.01    # simulated time between rest checks [s]
PILE_HOLD = 1.0         # simulated time watched after the first time at rest [s]
DECK_DIR = os.path.join(ROOT, 'input', 'validation')
DECK_T_PILE = 6.0       # t_end of the pile decks [s] (the Python runs go on to rest)
# min_separation of the 1000-body pile decks [m]: 1% of the 0.1 m bodies. The auto value (1e-4
# of the smallest body, 1.7e-5 m) keeps the turning bodies of a landing pile in steps of a
# few milliseconds: 1000 cubes reached 0.56 s in 850 s of wall time, and 1.76 s with 1e-4 m;
# with 1e-3 m they come to rest and sleep in 6 s for 126 s (docs/benchmarks.md).
PILE_MIN_SEPARATION = 1.0e-3
DECK_DT_MAX = 1.0e-2    # dt_max of every deck [s]


# ----------------------------------------------------------------------------- shapes

def _quat_mul(a, b):
    """Hamilton product of quaternions (w, x, y, z), as src/math/quaternion.f90."""
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


def _quat_exp(theta):
    """Unit quaternion of the rotation vector theta [rad], as quat_exp in ricochet."""
    angle = float(np.linalg.norm(theta))
    half = 0.5 * angle
    s = 0.5 * (1.0 - half * half / 6.0 * (1.0 - half * half / 20.0)) if angle < 1e-4 else math.sin(half) / angle
    return np.array([math.cos(half), s * theta[0], s * theta[1], s * theta[2]])


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(r):
    """Unit quaternion (w >= 0) of a proper rotation matrix."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0] * 4
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q) * (1 if q[0] >= 0 else -1)


def _box_inertia(m, ext):
    a, b, c = ext
    return m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


class Shape:
    """A moving body's shape in its own frame (the frame ricochet's builder defines it in:
    box_mesh, tetrahedron_mesh, l_shape_mesh of src/geometry/shape_builders.f90), with the
    origin moved to the centre of mass, because a deck's `position` is the centre of mass.

    boxes: the shape as non-overlapping boxes (half extents, centre) for the engines'
    compounds (the cube and the L); verts: the vertices of a convex mesh (the tetrahedron).
    inertia: the exact tensor of the uniform solid about the centre of mass, own axes.
    h: the body's height lying on its largest face (the unit of pile depth) [m].
    """

    def __init__(self, kind, deck, volume, inertia_unit, radius, lo, hi, h, boxes=None, verts=None):
        self.kind, self.deck, self.volume, self.radius, self.h = kind, deck, volume, radius, h
        self.mass = RHO * volume
        self.inertia = RHO * inertia_unit
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)   # own-frame box about the centre of mass
        self.boxes, self.verts = boxes, verts
        ev, vec = np.linalg.eigh(self.inertia)
        if np.ptp(ev) <= 1e-12 * ev.max():        # isotropic (cube, tetrahedron): own axes
            vec = np.eye(3)
        if np.linalg.det(vec) < 0:
            vec[:, 2] *= -1.0
        self.principal = ev                       # principal moments [kg m^2]
        self.q_principal = matrix_to_quat(vec)    # rotates principal-frame vectors into the own frame


def cube_shape(a=CUBE_A):
    return Shape('cube', "shape = 'box', size = %r, %r, %r" % (a, a, a), a ** 3, _box_inertia(a ** 3, (a, a, a)),
                 math.sqrt(3.0) * a / 2, [-a / 2] * 3, [a / 2] * 3, a, boxes=[((a / 2,) * 3, (0.0, 0.0, 0.0))])


def tetrahedron_shape(a=TET_A):
    # tetrahedron_mesh: vertices at alternate corners (1,1,1), (1,-1,-1), (-1,1,-1), (-1,-1,1)
    # of a cube, scaled to edge a; the centroid is the origin.
    c = a / (2.0 * math.sqrt(2.0))
    verts = c * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    vol = a ** 3 / (6.0 * math.sqrt(2.0))
    return Shape('tetrahedron', "shape = 'tetrahedron', size(1) = %r" % a, vol, np.eye(3) * vol * a * a / 20.0,
                 a * math.sqrt(6.0) / 4.0, [-c] * 3, [c] * 3, a * math.sqrt(2.0 / 3.0), verts=verts)


def l_prism_shape(size=L_SIZE, t=L_T):
    # l_shape_mesh: profile [0,sx] x [0,t] united with [0,t] x [0,sy] in x-y, extruded sz
    # along z, centred at its bounding-box centre. Split into arm A = [0,sx] x [0,t] and
    # arm B = [0,t] x [t,sy] (no overlap, so the compound's mass is right).
    sx, sy, sz = size
    arms = [((sx, t), (sx / 2, t / 2)), ((t, sy - t), (t / 2, (t + sy) / 2))]
    area = sum(e[0] * e[1] for e, _ in arms)
    com = np.array([sum(e[0] * e[1] * c[0] for e, c in arms) / area,
                    sum(e[0] * e[1] * c[1] for e, c in arms) / area, 0.0])
    boxes, inertia = [], np.zeros((3, 3))
    for (ex, ey), (cx, cy) in arms:
        r = np.array([cx, cy, sz / 2]) - np.array([com[0], com[1], sz / 2])
        m = ex * ey * sz
        inertia += _box_inertia(m, (ex, ey, sz)) + m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
        boxes.append(((ex / 2, ey / 2, sz / 2), tuple(r)))
    profile = [(0, 0), (sx, 0), (sx, t), (t, t), (t, sy), (0, sy)]
    corners = np.array([[x, y, z] for x, y in profile for z in (-sz / 2, sz / 2)]) - com
    radius = float(np.max(np.linalg.norm(corners, axis=1)))    # the arms' tips (sx, 0) and (0, sy)
    return Shape('l_prism', "shape = 'l_prism', size = %r, %r, %r, thickness = %r" % (sx, sy, sz, t),
                 area * sz, inertia, radius, [-com[0], -com[1], -sz / 2], [sx - com[0], sy - com[1], sz / 2], sz,
                 boxes=boxes)


SHAPES = {'cube': cube_shape, 'tetrahedron': tetrahedron_shape, 'l_prism': l_prism_shape}


# ----------------------------------------------------------------------------- ricochet's lattice expansion

class RandomStream:
    """src/math/random_stream.f90: SplitMix64 seeding xoshiro256**, bit for bit."""
    M = (1 << 64) - 1

    def __init__(self, seed):
        x, self.s = seed & self.M, []
        for _ in range(4):
            x = (x + 0x9E3779B97F4A7C15) & self.M
            z = x
            z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & self.M
            z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & self.M
            self.s.append(z ^ (z >> 31))

    def _rotl(self, v, k):
        return ((v << k) | (v >> (64 - k))) & self.M

    def next_u64(self):
        s = self.s
        r = (self._rotl((s[1] * 5) & self.M, 7) * 9) & self.M
        t = (s[1] << 17) & self.M
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = self._rotl(s[3], 45)
        return r

    def uniform(self):
        return (self.next_u64() >> 11) * 2.0 ** -53

    def symmetric(self, h):
        return h * (2.0 * self.uniform() - 1.0)

    def unit_vector(self):
        z = 2.0 * self.uniform() - 1.0
        phi = 6.283185307179586476925286766559 * self.uniform()
        r = math.sqrt(max(0.0, 1.0 - z * z))
        return np.array([r * math.cos(phi), r * math.sin(phi), z])


class Group:
    """One &body group: a body or a lattice of copies (the deck's variables)."""

    def __init__(self, name, shape=None, position=(0, 0, 0), copies=(1, 1, 1), spacing=(0, 0, 0), seed=0,
                 jitter_position=0.0, jitter_angle=0.0, fixed_box=None):
        # Lengths rounded to 12 digits, so that the deck prints them short and exactly.
        r12 = lambda v: np.array([float('%.12g' % x) for x in v])
        self.name, self.shape = name, shape
        self.position = r12(position)
        self.copies, self.spacing = tuple(copies), r12(spacing)
        self.seed, self.jp, self.ja = seed, jitter_position, jitter_angle
        self.fixed_box = None if fixed_box is None else r12(fixed_box)   # size of a static box [m]

    @property
    def n(self):
        return self.copies[0] * self.copies[1] * self.copies[2]

    def expand(self):
        """Centres of mass and orientations (w, x, y, z) of the copies, in ricochet's id
        order (i fastest, then j, then k), with its jitter draws in its order: three
        position offsets, an axis, an angle, three velocity offsets (zero amplitude here)."""
        st = RandomStream(self.seed) if self.seed else None
        pos, quat = [], []
        for k in range(self.copies[2]):
            for j in range(self.copies[1]):
                for i in range(self.copies[0]):
                    p = self.position + np.array([i, j, k], float) * self.spacing
                    q = np.array([1.0, 0.0, 0.0, 0.0])
                    if st:
                        p = p + np.array([st.symmetric(self.jp) for _ in range(3)])
                        axis = st.unit_vector()
                        q = _quat_mul(_quat_exp(st.uniform() * self.ja * axis), q)
                        q /= np.linalg.norm(q)
                        for _ in range(3):
                            st.symmetric(0.0)
                    pos.append(p)
                    quat.append(q)
        return np.array(pos), np.array(quat)

    def deck_line(self):
        f = lambda v: ', '.join(repr(float(x)) for x in v)
        if self.fixed_box is not None:
            return ("&body name = '%s', shape = 'box', size = %s, position = %s, fixed = .true. /"
                    % (self.name, f(self.fixed_box), f(self.position)))
        s = "&body name = '%s', %s, density = %r,\n      position = %s" % (
            self.name, self.shape.deck, RHO, f(self.position))
        if self.n > 1:
            s += ',\n      copies = %d, %d, %d, spacing = %s' % (*self.copies, f(self.spacing))
        if self.seed:
            s += ',\n      seed = %d, jitter_position = %r, jitter_angle = %r' % (self.seed, self.jp, self.ja)
        return s + ' /'


class Scene:
    """Static boxes (or the plane z = 0) and groups of moving bodies of one shape."""

    def __init__(self, name, title, shape, groups, statics, plane_floor, t_end, comments, container=None,
                 min_separation=None):
        self.min_separation = min_separation     # [m]; None: the deck's auto value
        self.name, self.title, self.shape = name, title, shape
        self.groups, self.statics, self.plane_floor = groups, statics, plane_floor
        self.t_end, self.comments, self.container = t_end, comments, container
        pos, quat = zip(*(g.expand() for g in groups))
        self.pos, self.quat = np.vstack(pos), np.vstack(quat)
        self.n = len(self.pos)

    def deck(self, t_end=None, interval=None, check_overlaps=False, extra_comments=()):
        t_end = t_end or self.t_end
        min_separation = self.min_separation
        lines = ['! %s' % c for c in list(self.comments) + list(extra_comments)]
        lines += ["&run title = '%s', t_end = %r, dt_max = %r, gravity = 0.0, 0.0, %r /" % (
                      self.title, t_end, DECK_DT_MAX, -G),
                  '&contact friction = %r, restitution = 0.0%s /' % (
                      MU, '' if min_separation is None else ', min_separation = %r' % min_separation),
                  "&output dir = '../../output/%s', interval = %r%s /" % (
                      self.name, interval or t_end / 100, ', check_overlaps = .true.' if check_overlaps else '')]
        if self.plane_floor:
            # The engines' floor is the plane z = 0; a deck takes a fixed box whose top face
            # is that plane, far wider than anything that can reach it.
            lines.append(Group('floor', position=(0, 0, -WALL_T / 2), fixed_box=(2.0, 2.0, WALL_T)).deck_line())
        lines += [g.deck_line() for g in self.statics + self.groups]
        return '\n'.join(lines) + '\n'


def stack_scene():
    """10 cubes on the z axis, the first REST_GAP above the floor, REST_GAP between cubes
    (ricochet refuses touching bodies at the start, so each contact opens by REST_GAP; they
    close in the first ~5 ms)."""
    sh = cube_shape()
    g = Group('cube', sh, position=(0, 0, REST_GAP + CUBE_A / 2), copies=(1, 1, STACK_N),
              spacing=(0, 0, CUBE_A + REST_GAP))
    return Scene('stack_10_cubes', 'stack of 10 cubes', sh, [g], [], True, STACK_T, [
        'Stack of 10 cubes (edge 0.1 m, 1 kg) on a static floor, friction 0.5, e = 0: resting contact.',
        'Generated by tools/bench_resting.py --write-decks (scene "stack"; PyBullet and MuJoCo run the',
        'same bodies there). Faces start %g m apart (ricochet refuses touching bodies).' % REST_GAP,
        'Measure: top-cube drift after 10 s (docs/bench/engines.md).'])


def pyramid_scene():
    """Rows of 5, 4, 3, 2, 1 cubes in the x-z plane, PYR_GAP between the cubes of a row,
    every cube of a row centred over the gap between two cubes of the row below, each
    row REST_GAP above the one below (and the first row REST_GAP above the floor)."""
    sh = cube_shape()
    pitch = CUBE_A + PYR_GAP
    groups = [Group('row%d' % (r + 1), sh,
                    position=(-(n - 1) * pitch / 2, 0, REST_GAP + CUBE_A / 2 + r * (CUBE_A + REST_GAP)),
                    copies=(n, 1, 1), spacing=(pitch, 0, 0))
              for r, n in enumerate(PYR_ROWS)]
    return Scene('pyramid_15', 'pyramid of 15 cubes', sh, groups, [], True, PYR_T, [
        'Pyramid of 15 cubes (edge 0.1 m) in rows 5, 4, 3, 2, 1 in the x-z plane, %g m gaps within a' % PYR_GAP,
        'row, friction 0.5, e = 0. Generated by tools/bench_resting.py --write-decks (scene "pyramid").',
        'Rows start %g m apart (ricochet refuses touching bodies). Measure: largest drift after 10 s.' % REST_GAP])


def lattice_extent(shape, angle):
    """Per axis, an interval [lower, upper] about the centre of mass that holds the body at
    any orientation within `angle` [rad] of its own frame (a rotation by at most `angle`
    moves every point by at most 2 r sin(angle/2), r its distance from the centre of mass,
    so the own-frame box grows by that much; the bounding sphere bounds it too)."""
    d = 2.0 * shape.radius * math.sin(min(angle, math.pi) / 2.0)
    return np.maximum(shape.lo - d, -shape.radius), np.minimum(shape.hi + d, shape.radius)


PILE_SPECS = {
    # shape: (N full, N quick, jitter angle [rad], volume fraction expected in the pile).
    # The fractions size the container and were measured in the runs (docs/bench/engines.md).
    'cubes': ('cube', 1000, 100, math.pi, 0.42),
    'tetrahedra': ('tetrahedron', 1000, 150, 0.2, 0.40),
    'l_shapes': ('l_prism', 200, 40, math.pi, 0.34),
}


def pile_scene(kind, quick=False, n=None, min_separation=PILE_MIN_SEPARATION):
    """N bodies in a jittered lattice above an open-top box. Container: inner square of side
    L = sqrt(N v / (phi h_b PILE_DEPTH)) rounded up to 5 cm, so that a pile of volume
    fraction phi fills it PILE_DEPTH body heights deep; floor top at z = 0; walls
    2 PILE_DEPTH h_b high (a pile of that depth fills half of it, so that little splashes
    out); floor and walls WALL_T thick. Lattice: spacing per axis
    s = (extent width) + 2 JITTER_POS + CLEARANCE (lattice_extent), so that two bodies at
    any jitter are at least CLEARANCE apart along the axis their lattice points differ in;
    nx = ny = as many columns as fit inside the walls with CLEARANCE to spare, centred; the
    lowest body at least CLEARANCE above the wall tops. N = nx ny nz plus a partial top
    layer: up to three &body groups (seeds PILE_SEED, +1, +2)."""
    shape_name, n_full, n_quick, angle, phi = PILE_SPECS[kind]
    sh = SHAPES[shape_name]()
    n = n or (n_quick if quick else n_full)
    side = math.ceil(math.sqrt(n * sh.volume / (phi * sh.h * PILE_DEPTH)) / 0.05 - 1e-9) * 0.05
    side = round(side, 10)
    h_wall = round(math.ceil(2.0 * PILE_DEPTH * sh.h / 0.05 - 1e-9) * 0.05, 10)
    lower, upper = lattice_extent(sh, angle)
    s = (upper - lower) + 2 * JITTER_POS + CLEARANCE
    free = side - (upper[0] - lower[0]) - 2 * JITTER_POS - 2 * CLEARANCE
    nx = int(math.floor(free / s[0] + 1e-9)) + 1
    if free < 0:
        raise ValueError('container too small for one lattice column')
    per_layer = nx * nx
    nz_full, rest = divmod(n, per_layer)
    x0 = -(nx - 1) * s[0] / 2.0 - (lower[0] + upper[0]) / 2.0
    y0 = -(nx - 1) * s[1] / 2.0 - (lower[1] + upper[1]) / 2.0
    z0 = h_wall - lower[2] + JITTER_POS + CLEARANCE
    groups, seed = [], PILE_SEED
    name = {'cube': 'cube', 'tetrahedron': 'tet', 'l_prism': 'ell'}[shape_name]
    jit = dict(jitter_position=JITTER_POS, jitter_angle=angle)
    if nz_full:
        groups.append(Group(name, sh, (x0, y0, z0), (nx, nx, nz_full), s, seed, **jit))
        seed += 1
    if rest >= nx:
        groups.append(Group(name + '_top', sh, (x0, y0, z0 + nz_full * s[2]), (nx, rest // nx, 1), s, seed, **jit))
        seed += 1
    if rest % nx:
        groups.append(Group(name + '_last', sh, (x0, y0 + (rest // nx) * s[1], z0 + nz_full * s[2]),
                            (rest % nx, 1, 1), s, seed, **jit))
    T = WALL_T
    statics = [Group('floor', position=(0, 0, -T / 2), fixed_box=(side + 2 * T, side + 2 * T, T)),
               Group('wall_y-', position=(0, -(side + T) / 2, h_wall / 2), fixed_box=(side + 2 * T, T, h_wall)),
               Group('wall_y+', position=(0, (side + T) / 2, h_wall / 2), fixed_box=(side + 2 * T, T, h_wall)),
               Group('wall_x-', position=(-(side + T) / 2, 0, h_wall / 2), fixed_box=(T, side, h_wall)),
               Group('wall_x+', position=((side + T) / 2, 0, h_wall / 2), fixed_box=(T, side, h_wall))]
    label = {'cube': 'cubes (edge %g m)' % CUBE_A, 'tetrahedron': 'regular tetrahedra (edge %g m)' % TET_A,
             'l_prism': 'L-prisms (%g x %g x %g m, arms %g m)' % (*L_SIZE, L_T)}[shape_name]
    comments = [
        '%d %s poured from a jittered lattice into an open-top box: inner %g x %g m,' % (n, label, side, side),
        'walls %g m high and %g m thick, floor top at z = 0. Friction 0.5, e = 0, density 1000.' % (h_wall, T),
        'Generated by tools/bench_resting.py --write-decks (scene "piles", %s): PyBullet and MuJoCo' % kind,
        'run the same bodies (same lattice, jitter reproduced from the seed). Lattice spacing keeps',
        'every initial gap >= %g m; jitter %g m per axis, up to %.4g rad of rotation.' % (CLEARANCE, JITTER_POS, angle),
        'The Python runs go on until the kinetic energy is below 1e-6 of the potential energy released.']
    if shape_name == 'l_prism':
        comments.append("position is the L's centre of mass (l_shape_mesh's profile from its corner at -x, -y).")
    sc = Scene('pile_' + kind, 'pile of %d %s' % (n, {'l_shapes': 'L-prisms'}.get(kind, kind)), sh, groups, statics, False,
               DECK_T_PILE, comments, container=dict(side=side, h_wall=h_wall, nx=nx, spacing=s.tolist(),
                                                    lattice_top=float(z0 + (nz_full + (rest > 0)) * s[2])),
               min_separation=min_separation)
    assert sc.n == n
    return sc


def all_decks():
    """(file name, text) of every deck this script owns."""
    out = [('stack_10_cubes.nml', stack_scene().deck(interval=0.1)),
           ('pyramid_15.nml', pyramid_scene().deck(interval=0.1))]
    for kind in PILE_SPECS:
        out.append(('pile_%s.nml' % kind, pile_scene(kind).deck(
            t_end=DECK_T_PILE, interval=0.05, check_overlaps=True,
            extra_comments=[
                'min_separation 1e-3 m (1% of the bodies): with the auto 1.7e-5 m the landing takes steps of',
                'milliseconds (docs/benchmarks.md). check_resting.py pile: no overlap at any frame, none',
                'beyond the walls, kinetic energy at the end below 1e-6 of the potential energy released.'])))
    # The pile the test suite runs (tests/regression/check_resting.py, case pile_small).
    out.append(('pile_8_cubes.nml', pile_scene('cubes', n=8, min_separation=None).deck(
        t_end=5.0, interval=0.05, check_overlaps=True, extra_comments=[
            'check_resting.py pile_small: no overlap at any frame (check_overlaps), no body leaves the',
            'box, kinetic energy at the end below 1e-6 of the potential energy released.'])))
    return out


# ----------------------------------------------------------------------------- engines

def kinetic_energy(shape, v, w_body):
    """Translational plus rotational kinetic energy [J]; w_body in the own frame."""
    rot = 0.5 * np.einsum('ni,ij,nj->', w_body, shape.inertia, w_body)
    return 0.5 * shape.mass * float(np.sum(v * v)) + float(rot)


def in_play(x, c):
    """Bodies whose centre is above the floor's underside and over the container's outer
    footprint (walls included). Bodies that left it fall for ever (nothing catches them)
    and would keep the kinetic energy up: the rest criterion leaves them out."""
    reach = c['side'] / 2 + WALL_T
    return (np.abs(x[:, 0]) <= reach) & (np.abs(x[:, 1]) <= reach) & (x[:, 2] > -WALL_T)


class RestingBullet(be.Bullet):
    """PyBullet. Each body's frame is its principal frame at the centre of mass (PyBullet
    takes a diagonal inertia only, and computes compounds' and hulls' inertia from their
    bounding box: the exact mass and principal moments are set with changeDynamics)."""

    def build(self, sc):
        p, cid = self.p, self.cid
        dt = self.reset(None, G)
        mu = math.sqrt(MU)  # product combination: every pair gets MU
        if sc.plane_floor:
            self._dyn(p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid),
                                        physicsClientId=cid), 0.0, mu)
        for g in sc.statics:
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=(0.5 * np.asarray(g.fixed_box)).tolist(),
                                         physicsClientId=cid)
            self._dyn(p.createMultiBody(0, col, basePosition=g.position.tolist(), physicsClientId=cid), 0.0, mu)
        sh = sc.shape
        rp = quat_to_matrix(sh.q_principal)           # principal -> own
        qp_inv = [-sh.q_principal[1], -sh.q_principal[2], -sh.q_principal[3], sh.q_principal[0]]  # x,y,z,w
        if sh.verts is not None:
            col = p.createCollisionShape(p.GEOM_MESH, vertices=(sh.verts @ rp).tolist(), physicsClientId=cid)
        elif len(sh.boxes) == 1 and np.allclose(sh.q_principal, [1, 0, 0, 0]):
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(sh.boxes[0][0]), physicsClientId=cid)
        else:
            col = p.createCollisionShapeArray([p.GEOM_BOX] * len(sh.boxes),
                                              halfExtents=[list(b[0]) for b in sh.boxes],
                                              collisionFramePositions=[(rp.T @ np.array(b[1])).tolist()
                                                                       for b in sh.boxes],
                                              collisionFrameOrientations=[qp_inv] * len(sh.boxes),
                                              physicsClientId=cid)
        self.ids = []
        for i0 in range(0, sc.n, 1000):
            r = p.createMultiBody(sh.mass, col, batchPositions=sc.pos[i0:i0 + 1000].tolist(),
                                  useMaximalCoordinates=True, physicsClientId=cid)
            self.ids.extend(r if isinstance(r, (list, tuple)) else [r])
        for i, b in enumerate(self.ids):
            q = _quat_mul(sc.quat[i], sh.q_principal)
            p.resetBasePositionAndOrientation(b, sc.pos[i].tolist(), [q[1], q[2], q[3], q[0]], physicsClientId=cid)
            self._dyn(b, 0.0, mu)
            p.changeDynamics(b, -1, mass=sh.mass, localInertiaDiagonal=sh.principal.tolist(), physicsClientId=cid)
        self.shape = sh
        return dt, lambda: p.stepSimulation(physicsClientId=cid)

    def positions(self):
        return np.array([self.p.getBasePositionAndOrientation(b, physicsClientId=self.cid)[0] for b in self.ids])

    def state(self):
        """Centres of mass [m], velocities [m/s] and angular velocities in the own frame
        [rad/s] of the moving bodies."""
        p, cid, sh = self.p, self.cid, self.shape
        n = len(self.ids)
        x, v, w = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        rp = quat_to_matrix(sh.q_principal)
        for i, b in enumerate(self.ids):
            x[i], q = p.getBasePositionAndOrientation(b, physicsClientId=cid)
            v[i], ang = p.getBaseVelocity(b, physicsClientId=cid)
            r = quat_to_matrix([q[3], q[0], q[1], q[2]])     # principal -> world
            w[i] = rp @ (r.T @ np.array(ang))
        return x, v, w


class RestingMujoco(be.Mujoco):
    """MuJoCo: MJCF with each body's frame at its centre of mass in its own axes; MuJoCo
    computes mass and inertia from the geoms (exact for boxes and convex meshes)."""

    def build(self, sc):
        sh = sc.shape
        statics = ''.join('<geom type="box" size="%.12g %.12g %.12g" pos="%.12g %.12g %.12g"/>'
                          % (*(0.5 * np.asarray(g.fixed_box)), *g.position) for g in sc.statics)
        if sc.plane_floor:
            statics = '<geom type="plane" size="5 5 0.1"/>' + statics
        asset = ''
        if sh.verts is not None:
            asset = '<asset><mesh name="body" vertex="%s"/></asset>' % ' '.join('%.17g' % x for x in sh.verts.ravel())
            geoms = '<geom type="mesh" mesh="body"/>'
        else:
            geoms = ''.join('<geom type="box" size="%.17g %.17g %.17g" pos="%.17g %.17g %.17g"/>' % (*e, *c)
                            for e, c in sh.boxes)
        bodies = ''.join('<body pos="%.17g %.17g %.17g" quat="%.17g %.17g %.17g %.17g"><freejoint/>%s</body>'
                         % (*sc.pos[i], *sc.quat[i], geoms) for i in range(sc.n))
        ngeom = sc.n * (1 if sh.verts is not None else len(sh.boxes)) + len(sc.statics) + 1
        # Arena as in bench_engines (broad phase ~4 bytes per geom pair) plus room for the
        # constraints of a dense pile (~4 contacts per body, pyramidal cones).
        mem_mb = 256 + int(6.0 * ngeom ** 2 / 2 ** 20)
        xml = ('<mujoco><option gravity="0 0 %r"/><size memory="%dM"/>%s'
               '<default><geom density="%g" friction="%g 0.005 0.0001"/></default>'
               '<worldbody>%s%s</worldbody></mujoco>' % (-G, mem_mb, asset, RHO, MU, statics, bodies))
        dt = self._load(xml)
        self.n, self.shape = sc.n, sh
        mass = self.m.body_mass[1:]
        if not np.allclose(mass, sh.mass, rtol=1e-6):   # MuJoCo keeps mesh vertices in float32
            raise RuntimeError('MuJoCo body mass %r, expected %r' % (mass[0], sh.mass))
        m, d = self.m, self.d
        return dt, lambda: self.mj.mj_step(m, d)

    def positions(self):
        return self.d.qpos.reshape(self.n, 7)[:, :3].copy()

    def state(self):
        qv = self.d.qvel.reshape(self.n, 6)   # free joint: world linear velocity, body-frame angular
        return self.positions(), qv[:, :3].copy(), qv[:, 3:].copy()


def run_fixed(e, sc, t_end):
    """Stack and pyramid: step to t_end; drift of every body from its start."""
    dt, step = e.build(sc)
    x0 = e.positions()
    nsteps = int(round(t_end / dt))
    tstep, dmin = 0.0, math.inf
    for _ in range(nsteps):
        t0 = time.perf_counter()
        step()
        tstep += time.perf_counter() - t0
        dmin = min(dmin, e.min_dist())
    d = e.positions() - x0
    dxy = np.hypot(d[:, 0], d[:, 1])
    return dict(dt=dt, steps=nsteps, t_sim=nsteps * dt, wall_step=tstep, wall_per_sim_s=tstep / (nsteps * dt),
                sim_s_per_wall_s=(nsteps * dt) / tstep, max_pen=max(0.0, -dmin),
                drift_xy=dxy.tolist(), drift_z=d[:, 2].tolist(), drift_3d=np.linalg.norm(d, axis=1).tolist())


def run_fixed_ricochet(e, sc, t_end):
    """Stack and pyramid through the binary: the scene's deck (the same as
    input/validation/), drift of every body from the first frame to the last; the wall time
    is the run's own stepping time (history.csv, from t = 0 after set-up to t_end)."""
    import glob
    import h5py
    import shutil
    import subprocess
    import tempfile
    work = tempfile.mkdtemp(prefix='ricochet_fixed_')
    try:
        deck = os.path.join(work, 'scene.nml')
        with open(deck, 'w') as f:
            f.write(sc.deck(t_end=t_end, interval=t_end / 10))
        out = os.path.join(work, 'out')
        proc = subprocess.run([e.exe, deck, '--output-dir', out], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError('ricochet failed: %s' % (proc.stdout + proc.stderr).strip().splitlines()[0])
        hist = np.genfromtxt(os.path.join(out, 'history.csv'), delimiter=',', names=True)
        wall = float(hist['wall_time_s'][-1] - hist['wall_time_s'][0])
        frames = sorted(glob.glob(os.path.join(out, 'frames', '*.h5')))
        def positions(path):
            with h5py.File(path, 'r') as h5:
                order = np.argsort(h5['bodies/gid'][...])
                return h5['bodies/position'][...].reshape(-1, 3)[order][len(sc.statics) + sc.plane_floor:]
        d = positions(frames[-1]) - positions(frames[0])
        dxy = np.hypot(d[:, 0], d[:, 1])
        t_sim = float(hist['time_s'][-1])
        return dict(dt=DECK_DT_MAX, steps=int(hist['steps_1'][-1]), t_sim=t_sim, wall_step=wall,
                    wall_per_sim_s=wall / t_sim, sim_s_per_wall_s=t_sim / wall, max_pen=0.0,
                    smallest_gap=float(np.min(hist['min_separation_m'])),
                    drift_xy=dxy.tolist(), drift_z=d[:, 2].tolist(), drift_3d=np.linalg.norm(d, axis=1).tolist())
    finally:
        shutil.rmtree(work, ignore_errors=True)


def run_pile(e, sc, t_cap, budget, hold=PILE_HOLD):
    """Pour: step until the kinetic energy of the bodies in play is below REST_RATIO of the
    potential energy they released (checked every PILE_CHECK_DT), t_cap, or `budget`
    seconds of stepping. After the first time at rest, go on for `hold` simulated seconds
    (within the caps) and keep the largest energy ratio and body speed seen: whether the
    pile stays at rest or only passed through a quiet moment."""
    dt, step = e.build(sc)
    sh, c = sc.shape, sc.container
    z0 = e.positions()[:, 2]
    every = max(1, int(round(PILE_CHECK_DT / dt)))
    pen_every = 1 if sc.n <= 200 else 5
    nmax = int(round(t_cap / dt))
    tstep, dmin, k, t_rest, stop = 0.0, math.inf, 0, None, None
    k_end, hold_ratio, hold_speed = nmax, 0.0, 0.0
    ke_hist = []
    while k < k_end:
        t0 = time.perf_counter()
        step()
        tstep += time.perf_counter() - t0
        k += 1
        if k % pen_every == 0:
            dmin = min(dmin, e.min_dist())
        if k % every == 0:
            x, v, w = e.state()
            ok = in_play(x, c)
            ke = kinetic_energy(sh, v[ok], w[ok])
            released = sh.mass * G * float(np.sum(z0[ok] - x[ok, 2]))
            ratio = ke / released if released > 0 else math.inf
            ke_hist.append((k * dt, ke, released, int((~ok).sum())))
            if t_rest is not None:
                hold_ratio = max(hold_ratio, ratio)
                hold_speed = max(hold_speed, float(np.max(np.linalg.norm(v[ok], axis=1), initial=0.0)))
            elif ratio < REST_RATIO:
                t_rest = k * dt
                k_end = min(nmax, k + int(round(hold / dt)))
            if tstep > budget:
                stop = 'wall budget'
                break
    x = e.positions()
    half = c['side'] / 2
    out = (np.abs(x[:, 0]) > half) | (np.abs(x[:, 1]) > half) | (x[:, 2] < 0.0)
    inside = x[~out]
    # Pile height: the 95th percentile of the centres inside, plus half a body height.
    height = float(np.percentile(inside[:, 2], 95)) + sh.h / 2 if len(inside) else 0.0
    t_sim = k * dt
    ke, released = ke_hist[-1][1:3] if ke_hist else (math.nan, math.nan)
    return dict(dt=dt, steps=k, t_sim=t_sim, wall_step=tstep, wall_per_sim_s=tstep / t_sim,
                sim_s_per_wall_s=t_sim / tstep, max_pen=max(0.0, -dmin), pen_every=pen_every, t_rest=t_rest,
                hold=(t_sim - t_rest) if t_rest is not None else 0.0, hold_max_ratio=hold_ratio,
                hold_max_speed=hold_speed, stopped=stop,
                ke_over_released=ke / released if released > 0 else math.nan,
                left=int(out.sum()), n=sc.n, height=height, depth=height / sh.h,
                phi=len(inside) * sh.volume / (c['side'] ** 2 * height) if height > 0 else 0.0,
                container=c, ke_history=ke_hist[::10])


class RicochetPiles:
    """ricochet on the same pile: the scene's deck (output every PILE_CHECK_DT, overlap check
    on) run by the binary (RICOCHET_EXE, default build/app/ricochet) until t_cap or the wall
    budget. Rest and the hold after it from history.csv (kinetic energy against the potential
    energy released by all moving bodies); bodies that left and pile depth from the last
    frame; penetration: none by construction (the smallest gap the run ever computed is kept
    as smallest_gap). Wall time: the whole process (set-up and output included)."""
    name = 'ricochet'

    def __init__(self):
        self.exe = os.environ.get('RICOCHET_EXE', os.path.join(ROOT, 'build', 'app', 'ricochet'))
        if not os.path.exists(self.exe):
            raise ImportError('no ricochet binary at %s (build it, or set RICOCHET_EXE)' % self.exe)
        self.version = 'build/app/ricochet (Release)'

    def settings(self):
        return dict(exe=self.exe, dt_max=DECK_DT_MAX, output_interval=PILE_CHECK_DT)


def run_pile_ricochet(e, sc, t_cap, budget, hold=PILE_HOLD):
    import glob
    import h5py
    import shutil
    import subprocess
    import tempfile
    c, sh = sc.container, sc.shape
    work = tempfile.mkdtemp(prefix='ricochet_pile_')
    try:
        deck = os.path.join(work, 'pile.nml')
        with open(deck, 'w') as f:
            f.write(sc.deck(t_end=t_cap, interval=PILE_CHECK_DT, check_overlaps=True))
        out = os.path.join(work, 'out')
        stop, t0 = None, time.perf_counter()
        try:
            proc = subprocess.run([e.exe, deck, '--output-dir', out], capture_output=True, text=True,
                                  timeout=budget)
            if proc.returncode != 0:
                raise RuntimeError('ricochet failed: %s' % (proc.stdout + proc.stderr).strip().splitlines()[0])
        except subprocess.TimeoutExpired:
            stop = 'wall budget'
        wall = time.perf_counter() - t0
        hist = np.genfromtxt(os.path.join(out, 'history.csv'), delimiter=',', names=True)
        t = hist['time_s']
        ke = hist['kinetic_translational_J'] + hist['kinetic_rotational_J']
        released = hist['potential_J'][0] - hist['potential_J']
        ratio = np.where(released > 0, ke / np.maximum(released, 1e-300), np.inf)
        rest = np.nonzero((ratio < REST_RATIO) & (t > 0))[0]
        t_rest = float(t[rest[0]]) if len(rest) else None
        hold_ratio = float(np.max(ratio[(t >= t_rest) & (t <= t_rest + hold)])) if t_rest is not None else 0.0
        def frame_state(path):
            with h5py.File(path, 'r') as h5:
                names = []
                h5.visit(names.append)
                get = lambda end: h5[[k for k in names if k.endswith(end)][0]][...].reshape(-1, 3)[len(sc.statics):]
                return get('position'), get('/velocity')
        # frame k is at k PILE_CHECK_DT (outputs land on multiples of the interval)
        frames_list = sorted(glob.glob(os.path.join(out, 'frames', '*.h5')))
        hold_speed = 0.0
        if t_rest is not None:
            for k, path in enumerate(frames_list):
                if t_rest - 1e-9 <= k * PILE_CHECK_DT <= t_rest + hold + 1e-9:
                    hold_speed = max(hold_speed, float(np.max(np.linalg.norm(frame_state(path)[1], axis=1))))
        x, v = frame_state(frames_list[-1])
        half = c['side'] / 2
        gone = (np.abs(x[:, 0]) > half) | (np.abs(x[:, 1]) > half) | (x[:, 2] < 0.0)
        inside = x[~gone]
        height = float(np.percentile(inside[:, 2], 95)) + sh.h / 2 if len(inside) else 0.0
        t_sim = float(t[-1])
        return dict(dt=DECK_DT_MAX, steps=int(hist['steps_1'][-1]), t_sim=t_sim, wall_step=wall,
                    wall_per_sim_s=wall / t_sim, sim_s_per_wall_s=t_sim / wall, max_pen=0.0,
                    smallest_gap=float(np.min(hist['min_separation_m'])), pen_every=1, t_rest=t_rest,
                    hold=min(hold, t_sim - t_rest) if t_rest is not None else 0.0, hold_max_ratio=hold_ratio,
                    hold_max_speed=hold_speed,
                    stopped=stop, ke_over_released=float(ratio[-1]), left=int(gone.sum()), n=sc.n,
                    height=height, depth=height / sh.h,
                    phi=len(inside) * sh.volume / (c['side'] ** 2 * height) if height > 0 else 0.0,
                    container=c, events=int(hist['events_1'][-1]),
                    ke_history=[(float(a), float(b), float(r), 0) for a, b, r in zip(t, ke, released)][::10])
    finally:
        shutil.rmtree(work, ignore_errors=True)


def pile_row(r):
    label = {'l_shapes': 'L-prisms'}.get(r['pile'], r['pile'])
    if r['t_rest'] is None:
        why = ('%.0f s stepping budget' % r.get('budget', PILE_BUDGET)) if r['stopped'] else 'time cap'
        rest = 'not at rest at %.2f s (%s; KE/released %.1e)' % (r['t_sim'], why, r['ke_over_released'])
        hold = '-'
    else:
        rest = '%.2f s' % r['t_rest']
        hold = '%.1e, %.2g m/s (%.2g s)' % (r['hold_max_ratio'], r['hold_max_speed'], r['hold'])
    depth = '%.1f h_b, phi %.2f' % (r['depth'], r['phi']) if r['t_rest'] is not None else '-'
    return '| pile %d %s (box %.2f m) | %s | %.3g | %.3g | %s | %s | %s | %s | %d | %s |' % (
        r['n'], label, r['container']['side'], r['engine'], r['dt'], r['sim_s_per_wall_s'],
        be.fmt(r['wall_per_sim_s']), be.fmt(r['max_pen']), rest, hold, r['left'], depth)


PILE_HDR = ('| scene | engine | dt [s] | simulated s per wall s | wall s per simulated s | largest penetration [m] '
            '| time to rest | after rest: largest KE/released, speed (for) | bodies that left | pile depth |\n'
            '|---|---|---|---|---|---|---|---|---|---|\n')


# ----------------------------------------------------------------------------- driver

HDR = ('| scene | engine | dt [s] | simulated s per wall s | wall s per simulated s | largest penetration [m] '
       '| %s |\n|---|---|---|---|---|---|---|\n')


def main():
    global REST_GAP
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--quick', action='store_true',
                    help='piles of 100 cubes, 150 tetrahedra, 40 L-prisms (about 2 minutes in all)')
    ap.add_argument('--scenes', nargs='+', default=['stack', 'pyramid', 'piles'])
    ap.add_argument('--piles', nargs='+', default=list(PILE_SPECS), help='cubes, tetrahedra, l_shapes')
    ap.add_argument('--pile-n', type=int, help='bodies per pile (overrides the sizes above)')
    ap.add_argument('--engines', nargs='*', default=['pybullet', 'mujoco'],
                    help='pybullet, mujoco, ricochet (piles only: the binary runs the same deck); '
                         'none: only rewrite the pile tables from the JSON of earlier runs')
    ap.add_argument('--t-cap', type=float, default=PILE_T_CAP, help='simulated time cap of a pile [s]')
    ap.add_argument('--budget', type=float, default=PILE_BUDGET, help='stepping wall time cap of one pile run [s]')
    ap.add_argument('--hold', type=float, default=PILE_HOLD, help='simulated time watched after rest [s]')
    ap.add_argument('--rest-gap', type=float, default=REST_GAP,
                    help='start gap of resting faces in stack and pyramid [m]; 0: touching, as the engines '
                         'allow (not the decks: ricochet refuses touching bodies)')
    ap.add_argument('--out', default=os.path.join(ROOT, 'docs', 'bench'))
    ap.add_argument('--write-decks', action='store_true', help='write the decks to input/validation and exit')
    ap.add_argument('--check-decks', action='store_true',
                    help='exit 1 unless the decks in input/validation are what --write-decks writes')
    a = ap.parse_args()
    if a.rest_gap != REST_GAP and (a.write_decks or a.check_decks):
        ap.error('--rest-gap does not apply to the decks')
    REST_GAP = a.rest_gap
    gap_sfx = '' if REST_GAP == 1.0e-4 else '_gap%g' % REST_GAP

    if a.write_decks or a.check_decks:
        bad = 0
        for fn, text in all_decks():
            path = os.path.join(DECK_DIR, fn)
            if a.write_decks:
                be.write_md(path, text)
                print('wrote', path)
            else:
                ok = os.path.exists(path) and open(path).read() == text
                print('%s %s' % ('ok  ' if ok else 'DIFFERS', path))
                bad += not ok
        if a.check_decks:
            print('%d passed, %d failed' % (len(all_decks()) - bad, bad))
        sys.exit(1 if bad else 0)

    engines = []
    for name in a.engines:
        try:
            engines.append({'pybullet': RestingBullet, 'mujoco': RestingMujoco, 'ricochet': RicochetPiles}[name]())
        except ImportError as err:
            print('skipping %s: %s (pip install %s)' % (name, err, name), file=sys.stderr)
    sfx = '_quick' if a.quick else ''
    jpath = os.path.join(a.out, 'engines_resting%s.json' % sfx)
    results = dict(machine=platform.platform(), python=platform.python_version(),
                   engines={e.name: e.version for e in engines}, quick=a.quick, runs={})
    if os.path.exists(jpath):   # keep the scenes and engines not run this time
        with open(jpath) as f:
            old = json.load(f)
        results['runs'] = old.get('runs', {})
        results['engines'] = dict(old.get('engines', {}), **results['engines'])

    for scene, make, t_end, what in (('stack', stack_scene, STACK_T, 'top cube drift'),
                                     ('pyramid', pyramid_scene, PYR_T, 'largest drift of any cube')):
        if scene not in a.scenes or not engines:
            continue
        rows, runs = [], []
        for e in engines:
            sc = make()
            r = (run_fixed_ricochet if e.name == 'ricochet' else run_fixed)(e, sc, t_end)
            r['settings'] = e.settings()
            runs.append(dict(engine=e.name, **r))
            if scene == 'stack':
                col = '%.2e m horizontal, %+.2e m vertical' % (r['drift_xy'][-1], r['drift_z'][-1])
            else:
                col = '%.2e m horizontal (cube %d), %.2e m vertical' % (
                    max(r['drift_xy']), int(np.argmax(r['drift_xy'])) + 1, max(abs(z) for z in r['drift_z']))
            line = '| %s | %s | %.3g | %.0f | %s | %s | %s |' % (
                scene + (' (touching)' if REST_GAP == 0 else ''), e.name, r['dt'], r['sim_s_per_wall_s'], be.fmt(r['wall_per_sim_s']), be.fmt(r['max_pen']), col)
            print(line, flush=True)
            rows.append(line)
        results['runs'][scene + gap_sfx] = runs
        intro = {'stack': 'Stack of %d cubes' % STACK_N, 'pyramid': 'Pyramid of 15 cubes (rows 5, 4, 3, 2, 1)'}[scene]
        gap = ('faces touching at the start' if REST_GAP == 0 else
               'resting faces %g m apart at the start (the drift includes closing them)' % REST_GAP)
        md = ('%s, %g s simulated, engine default time step, friction %g, %s; drift of each centre from the '
              'start. tools/bench_resting.py, docs/bench/engines.md.\n\n' % (intro, t_end, MU, gap)
              + HDR % what + '\n'.join(rows) + '\n')
        be.write_md(os.path.join(a.out, 'engines_%s%s%s.md' % (scene, gap_sfx, sfx)), md)
        be.write_md(jpath, json.dumps(results, indent=1))

    if 'piles' in a.scenes:
        # Runs of other engines or piles from earlier invocations stay in the table.
        runs = results['runs'].get('piles', [])
        for kind in a.piles:
            sc = pile_scene(kind, a.quick, a.pile_n)
            for e in engines:
                t0 = time.perf_counter()
                runner = run_pile_ricochet if e.name == 'ricochet' else run_pile
                r = dict(engine=e.name, pile=kind, budget=a.budget, **runner(e, sc, a.t_cap, a.budget, a.hold))
                r['wall_total'] = time.perf_counter() - t0
                r['settings'] = e.settings()
                runs = [q for q in runs if (q['engine'], q['pile'], q['n']) != (e.name, kind, sc.n)] + [r]
                print(pile_row(r), flush=True)
                results['runs']['piles'] = runs
                be.write_md(jpath, json.dumps(results, indent=1))   # after every run: nothing lost
        order = {k: i for i, k in enumerate(PILE_SPECS)}
        runs.sort(key=lambda q: (order.get(q['pile'], 9), q['n'], q['engine'] != 'pybullet', q['engine']))
        md = ('Piles poured into an open-top box until the kinetic energy of the bodies in play is below %g of the '
              'potential energy they released (checked every %g s), or %g s simulated, or a budget of stepping '
              'wall time (per row; default %g s); then '
              'watched for %g s more: the largest KE/released and body speed in that time say whether the pile '
              'stays at rest. Engine default time step, friction %g. Bodies that left: centre outside the '
              'container at the end. Pile depth: height (95th percentile of the centres inside + h_b/2) in body '
              'heights h_b, and the volume fraction phi below it. Penetration checked after every step (every 5th '
              'step above 200 bodies). tools/bench_resting.py, docs/bench/engines.md.\n\n'
              % (REST_RATIO, PILE_CHECK_DT, a.t_cap, PILE_BUDGET, a.hold, MU) + PILE_HDR +
              '\n'.join(pile_row(q) for q in runs) + '\n')
        be.write_md(os.path.join(a.out, 'engines_piles%s.md' % sfx), md)
        be.write_md(jpath, json.dumps(results, indent=1))

if __name__ == '__main__':
    main()
