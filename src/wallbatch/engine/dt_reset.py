"""fix dt/reset's per-atom largest timestep: one formula for the NumPy engine and the compiled path.

`dt_candidate` is plain arithmetic on floats or arrays; its only branch is `select` (np.where),
which wallbatch.engine.compiled overloads for scalars, so the numba path compiles this very
function and both paths agree bit for bit.
"""

from __future__ import annotations

import numpy as np

BIG = 1.0e20  # dt/reset's "no limit"


def select(cond, a, b):
    """np.where(cond, a, b); the compiled path gives scalars `a if cond else b`."""
    return np.where(cond, a, b)


def dt_candidate(v0, v1, v2, f0, f1, f2, m, ftm2v, mvv2e, xmax, emax):
    """The largest dt [time] for one atom under fix dt/reset (physics.md §9), elementwise.

    v [velocity], f [force] components, m [mass], xmax [length] the largest move, emax [energy]
    the largest energy change (<= 0: none); ftm2v, mvv2e the unit conversions. dt = min(xmax/|v|,
    sqrt(2 xmax / (ftm2v |f|/m)), emax/(|f||v| sqrt(ftm2v mvv2e))), then shortened so that the
    step's displacement dt v + (ftm2v/2) dt^2 f/m stays within xmax.
    """
    vsq = v0 * v0 + v1 * v1 + v2 * v2
    fsq = f0 * f0 + f1 * f1 + f2 * f2
    dtv = select(vsq > 0, xmax / np.sqrt(vsq), BIG)
    dtf = select(fsq > 0, np.sqrt(2.0 * xmax / (ftm2v * np.sqrt(fsq) / m)), BIG)
    dt = np.minimum(dtv, dtf)
    dte = emax / np.sqrt(fsq * vsq) / np.sqrt(ftm2v * mvv2e)
    dt = select((emax > 0) & (vsq * fsq > 0), np.minimum(dt, dte), dt)
    k = (0.5 * ftm2v) * (dt * dt / m)
    d0 = dt * v0 + k * f0
    d1 = dt * v1 + k * f1
    d2 = dt * v2 + k * f2
    dr = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return select(dr > xmax, dt * xmax / dr, dt)
