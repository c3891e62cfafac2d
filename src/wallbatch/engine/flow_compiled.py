"""fix wall/flow's velocity redraw compiled with numba (behind wallbatch.engine.flow._velocities).

The NumPy functions of wallbatch.engine.flow (`log_tail`, `positive_fraction`,
`solve_flux_speed`) are the reference; this module runs the same arithmetic per redraw, one
element at a time (the NumPy solver already freezes each element on its own, so its result does
not depend on the others). The special functions are SciPy's own (erfc, erfcx, expit from
scipy.special.cython_special, linked by symbol), so the only differences are exp and log (NumPy's
SIMD versions vs the C library's): results agree to a few ulp (tests/engine/test_flow_compiled.py).
The random numbers are drawn in NumPy exactly as before (flow._draw); only the solve is compiled.
`WALLBATCH_NUMBA=0` (or numba missing) keeps the NumPy solver.
"""

from __future__ import annotations

import math

import numpy as np

from wallbatch.engine import backend
from wallbatch.engine import scalar as _scalar

try:  # numba is a dependency, but the NumPy path must keep working without it
    import llvmlite.binding as _llvm
    from numba import njit, types
    from numba.extending import get_cython_function_address
except Exception:  # noqa: BLE001 - any import failure means "no compiled path"
    njit = None

_SQRT_PI = float(np.sqrt(np.pi))
_EPS = float(np.finfo(float).eps)
_SQRT2 = float(np.sqrt(2.0))


def enabled() -> bool:
    """True if the compiled solver may be used: numba imports and backend.use_numba()."""
    return njit is not None and backend.use_numba()


def _link(name: str, fused: str) -> "types.ExternalFunction":
    """SciPy's double-precision `name` (a cpdef function: double f(double, int skip_dispatch)) as
    an external symbol for numba; by name, so the on-disk cache of the kernels stays valid."""
    symbol = f"wallbatch_scipy_{name}"
    _llvm.add_symbol(symbol, get_cython_function_address("scipy.special.cython_special", fused + name))
    return types.ExternalFunction(symbol, types.float64(types.float64, types.intc))


if njit is not None:
    _erfc = _link("erfc", "__pyx_fuse_1")
    _erfcx = _link("erfcx", "__pyx_fuse_1")
    _expit = _link("expit", "__pyx_fuse_0")
    jit = njit(cache=True, nogil=True, error_model="numpy")

    @jit
    def _one_minus_r(y: float) -> float:
        """flow._one_minus_r for one y >= 0."""
        if y < 2.0:
            return 1.0 - _SQRT_PI * y * _erfcx(y, 0)
        depth = 60 if y < 3.0 else (40 if y < 5.0 else 20)
        t = 0.0
        for k in range(depth, 0, -1):
            t = (0.5 * k) / (y + t)
        return t / (y + t)

    @jit
    def log_tail(nu: float, delta: float) -> float:
        """flow.log_tail for one (ν, δ): ln ∫_ν^∞ t exp(-(t - δ)²) dt."""
        y = nu - delta
        if y < 0.0:
            return math.log(0.5 * math.exp(-y * y) + delta * (0.5 * _SQRT_PI) * _erfc(y, 0))
        if delta >= 0.0:
            return -y * y + math.log(0.5 + delta * (0.5 * _SQRT_PI) * _erfcx(y, 0))
        q = _one_minus_r(y)
        return -y * y + math.log(0.5 * (q + (nu / y) * (1.0 - q)))

    _nmin = jit(_scalar.nmin)  # np.minimum / np.maximum of two floats (engine/scalar.py)
    _nmax = jit(_scalar.nmax)

    @jit
    def solve_flux_speed(delta: float, u: float, max_iter: int) -> float:
        """flow.solve_flux_speed for one (δ, u), u in (0, 1]: the same bracket, start, Halley or
        Newton steps and stopping tests, element by element."""
        target = log_tail(0.0, delta) + math.log(u)
        dpos = _nmax(delta, 0.0)
        k = math.log1p(_SQRT_PI * dpos) - math.log(math.exp(-dpos * dpos) + _SQRT_PI * dpos)
        a = 0.0
        b = dpos + math.sqrt(k - math.log(u)) + 1.0
        for _ in range(200):
            if not log_tail(b, delta) > target:
                break
            a = b
            b = 2.0 * b + 1.0
        s = math.sqrt(delta * delta + 2.0)
        mode = 0.5 * (delta + s) if delta >= 0.0 else 1.0 / (s - delta)
        x = _nmin(_nmax(mode, a), b)
        if not u < 1.0:
            return 0.0
        for _ in range(max_iter):
            lt = log_tail(x, delta)
            f = lt - target
            if f >= 0.0:
                a = x
            if f <= 0.0:
                b = x
            e = x - delta
            w = math.exp(-(e * e) - lt)
            d1 = -x * w
            d2 = -w * (1.0 - 2.0 * x * (x - delta) + x * x * w)
            newton = f / d1
            corr = 1.0 - 0.5 * newton * d2 / d1
            step = newton / corr if (corr > 0.5) & (corr < 2.0) else newton
            noise = 4 * _EPS * _nmax(x, (abs(lt) + abs(target) + 1.0) / abs(d1))
            xn = x - step
            inside = (d1 < 0.0) & (xn >= a) & (xn <= b)
            if not inside:
                xn = 0.5 * (a + b)
            done = (f == 0.0) | (inside & (abs(xn - x) <= noise)) | (b - a <= 4 * _EPS * b)
            if f != 0.0:
                x = xn
            if done:
                break
        return x

    inline = njit(cache=True, nogil=True, error_model="numpy", inline="always")

    @inline
    def redraw(u1: float, u2: float, g0: float, g1: float, gamma: float, vflow: float) -> tuple:
        """One atom's new velocity (flow._velocities): side from u1 (backward if u1 > P+), speed ν
        from T(ν)/T(0) = 1 - u2; returns (v along the axis = side ν / γ, the two other components
        g / (γ √2)). γ = 1 / sqrt(2 kT / m) [1 / velocity]."""
        delta = gamma * vflow
        pplus = _expit(log_tail(0.0, delta) - log_tail(0.0, -delta), 0)
        side = -1.0 if u1 > pplus else 1.0
        v_axis = side * solve_flux_speed(side * delta, 1.0 - u2, 100) / gamma
        scale = gamma * _SQRT2
        return v_axis, g0 / scale, g1 / scale

    @inline
    def crossing(xi: float, va: float, prev: float, lo: float, length: float, walls: np.ndarray, phys: int,
                 pend: int, member: bool) -> tuple:
        """FlowKernel.end_of_step's test for one atom: its segment between the walls (of its
        wrapped axis coordinate xi; walls ascending), and whether it crossed a wall this step.
        Returns (segment, direction of the crossing: +-1.0, or 0.0 if none, pend after the test: 0
        if it returned through the wall it was pending at). A member atom crossed if its segment
        changed (not just returning), or it turned back (va against pend) without leaving."""
        t = xi - lo
        if not (t >= 0.0 and t < length):  # t % length is t itself there (positions are wrapped)
            t = t % length
        xw = lo + t
        sg = 0
        for k in range(walls.shape[0]):
            sg += xw >= walls[k]
        direction = 0.0
        if member:
            moved = sg != phys
            pe = float(pend)
            if moved or pe != 0.0:
                dx = xi - prev
                dx -= length * np.rint(dx / length)
                d = np.sign(dx)
                if d == 0.0:
                    d = np.sign(va)
                if d == 0.0:
                    d = 1.0
                returned = (pe != 0.0) & moved & (d == pe)
                turned = (pe != 0.0) & (not moved) & (va * pe <= 0.0)
                if returned:
                    pend = 0
                if (moved & (not returned)) | turned:
                    direction = -pe if turned else d
        return sg, direction, pend

    @jit
    def velocities(u1: np.ndarray, u2: np.ndarray, g: np.ndarray, gamma: np.ndarray, vflow: np.ndarray,
                   v_axis: np.ndarray, v_par: np.ndarray) -> None:
        """flow._velocities into v_axis (n,) and v_par (n, 2) (`redraw` per atom)."""
        for i in range(u1.shape[0]):
            v_axis[i], v_par[i, 0], v_par[i, 1] = redraw(u1[i], u2[i], g[i, 0], g[i, 1], gamma[i], vflow[i])

    @jit
    def detect(x, v, group, axis, lo, length, walls, phys, pend, prev, seg, xa, ci, ai, direction) -> int:
        """FlowKernel.end_of_step up to the draws, for every case (`crossing` per atom): the axis
        coordinate xa (C, N) and its segment seg (C, N); returned atoms get pend 0; the crossings go
        to ci, ai, direction (case-major, ascending atom: the order of the draws). Returns their number."""
        C, N = x.shape[0], x.shape[1]
        n = 0
        for c in range(C):
            ax = axis[c]
            for i in range(N):
                xi = x[c, i, ax]
                xa[c, i] = xi
                s, d, pe = crossing(xi, v[c, i, ax], prev[c, i], lo[c], length[c], walls[c], phys[c, i], pend[c, i],
                                    group[c, i] != 0)
                seg[c, i] = s
                pend[c, i] = pe
                if d != 0.0:
                    ci[n] = c
                    ai[n] = i
                    direction[n] = d
                    n += 1
        return n

    @jit
    def apply(ci, ai, direction, u1, u2, g, kT, mass, vflow, axis, exact, v, pend) -> None:
        """The redraws of the crossings ci, ai from the drawn u1, u2, g (`redraw` per atom), and pend
        after them (rule exact: -direction if the new velocity points back, else 0)."""
        for k in range(ci.shape[0]):
            c, a = ci[k], ai[k]
            ax = axis[c]
            gamma = 1.0 / math.sqrt(2.0 * kT[c] / mass[c, a])
            v_axis, v[c, a, (ax + 1) % 3], v[c, a, (ax + 2) % 3] = redraw(u1[k], u2[k], g[k, 0], g[k, 1], gamma, vflow[c])
            v[c, a, ax] = v_axis
            pend[c, a] = -direction[k] if exact[c] and v_axis * direction[k] < 0.0 else 0.0
