"""High-precision reference for the exact free-rotation propagator near the separatrix.

Principal moments (1, 1.5, 3) kg m^2, q0 = identity, body w0 = (3, 2, 1 + 10^-e) rad/s
(e = 6, 9: 1 - k^2 = 1.3e-6, 1.3e-9; e -> infinity is exactly on the separatrix). The
doubles 3, 2, 1 + 10^-e are taken exactly; Euler's equations for m = I w and
q' = q (0, w)/2 are integrated by mpmath's Taylor-series ODE solver at 40 digits.
Writes tests/data/free_rotation_near_separatrix.csv: e, t, qw, qx, qy, qz, mx, my, mz.
Run with a Python that has mpmath (python3 -m pip show mpmath); takes ~1 minute.
"""
import mpmath
from mpmath import mp, mpf, odefun

mp.dps = 40
INERTIA = [mpf(1), mpf('1.5'), mpf(3)]


def rhs(t, y):
    qw, qx, qy, qz, m1, m2, m3 = y
    w = [m1 / INERTIA[0], m2 / INERTIA[1], m3 / INERTIA[2]]
    dq = [0.5 * (-qx * w[0] - qy * w[1] - qz * w[2]),
          0.5 * (qw * w[0] + qy * w[2] - qz * w[1]),
          0.5 * (qw * w[1] - qx * w[2] + qz * w[0]),
          0.5 * (qw * w[2] + qx * w[1] - qy * w[0])]
    dm = [m2 * w[2] - m3 * w[1], m3 * w[0] - m1 * w[2], m1 * w[1] - m2 * w[0]]
    return dq + dm


def main():
    lines = ['# torque-free rigid body, I = (1, 1.5, 3) kg m^2, q0 = 1, body w0 = (3, 2, 1 + 10^-e) rad/s (doubles, exact)',
             '# mpmath ' + mpmath.__version__ + ' odefun (Taylor) at mp.dps = 40; tools/reference/free_rotation_near_separatrix.py',
             '# e,t,qw,qx,qy,qz,mx,my,mz (m = body angular momentum, kg m^2/s)']
    for e in (6, 9):
        w0 = [mpf(3.0), mpf(2.0), mpf(1.0 + 10.0 ** (-e))]
        y0 = [mpf(1), mpf(0), mpf(0), mpf(0)] + [INERTIA[i] * w0[i] for i in range(3)]
        sol = odefun(rhs, 0, y0)
        for t in (3, 6, 9, 12):
            y = sol(mpf(t))
            lines.append(','.join([str(e), str(t)] + [mp.nstr(v, 22) for v in y]))
    with open('tests/data/free_rotation_near_separatrix.csv', 'w') as f:
        f.write('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
