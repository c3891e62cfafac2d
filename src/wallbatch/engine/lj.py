"""The per-pair arithmetic of `pair_style lj/cut` (physics and units: pair.py), as plain functions
of scalars or arrays: the NumPy path (pair.py) calls them on arrays of pairs, the compiled kernels
(pair_compiled.py) compile them inlined into their loops. One place, so each pair's values are the
same bits on both paths. A leaf: imports only NumPy.
"""

from __future__ import annotations

import numpy as np


def min_image(d: np.ndarray | float, inv_length: float, length: float) -> np.ndarray | float:
    """d [length] moved to its nearest periodic image: d - rint(d / L) L, with inv_length = 1/L
    (0 in a fixed dimension, where d stays as it is). Plain arithmetic: the NumPy path calls it on
    arrays, the compiled kernels (pair_compiled.py) compile it into their loops."""
    return d - np.rint(d * inv_length) * length


def lj_terms(r2: np.ndarray | float, e24, e4, sig2, rc2, off) -> tuple[np.ndarray | float, np.ndarray | float]:
    """fpair = F/r [force/length] and the shifted energy E(r) - off [energy] of pairs at r^2
    [length^2], both 0 at r^2 >= rc2 (inside = r^2 < rc2: computed for every pair, then zeroed,
    no branch). e24 = 24 eps, e4 = 4 eps [energy], sig2 = sigma^2 [length^2], off = E(rc) or 0.

    With t = sig2 / r^2 and s6 = t^3: fpair = (2 s6 - 1) s6 (24 eps) / r^2, E = (s6 - 1) s6 (4 eps).
    The one place of this arithmetic: the NumPy path calls it on arrays of pairs, the compiled
    force pass (pair_compiled.py) compiles it (inlined) into its loop, so each pair's values are
    the same bits on both paths. Scalars or arrays; bool `inside` multiplies as 0/1.
    """
    inside = r2 < rc2
    t = sig2 / r2
    s6 = t * t * t
    return (s6 * 2.0 - 1.0) * s6 * e24 / r2 * inside, ((s6 - 1.0) * s6 * e4 - off) * inside
