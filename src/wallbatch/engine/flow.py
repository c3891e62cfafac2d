"""fix wall/flow over a batch (physics.md §8 and the decisions table).

Flow walls are planes perpendicular to the flow axis. Positions are never changed; when an atom
of the group crosses a wall its velocity is redrawn: the component along the axis from the
flux-weighted shifted Maxwellian f(v) ∝ |v| exp(-γ² (v - vflow)²) on the whole line, the two
others from a Gaussian of variance kT/m (γ = 1/sqrt(2 kT/m), kT = boltz T / mvv2e in
mass·velocity² units).

Segments: with the internal wall list W = [boxlo, w1..wK, boxhi], segment k holds
W[k] <= x < W[k+1]; the periodic boundary acts as wall K+1 (= wall 0). The kernel takes the
segment of the *wrapped* axis coordinate, so the engine's wrap every step (decisions table)
and an unwrapped coordinate give the same answer: one redraw per crossing (§8.5).

Rules (per case):

* ``lammps``: every change of segment redraws (LAMMPS with positions wrapped every step).
* ``exact`` (default, §8.3b): when a redraw sends the atom back over the wall it has just
  crossed, the atom belongs to the segment it is heading into (the one it came from). Its
  return over that wall is not a crossing; if it turns round before getting back (forces) it
  re-enters the segment it sits in, which is a crossing. An ideal gas then has exactly the
  shifted Maxwellian M(v - vflow) in every segment (tests/engine/test_flow.py; LAMMPS's rule gives
  a density ∝ Z± M(v - vflow) on each side of 0, <v_x> 0.728 instead of 0.4 for vflow 0.4, T 1.5).

A crossing is a redraw; `take_crossings` returns their number per case since the last call.

Random numbers: each case has its own generator. Per step, for each case in batch order, the
atoms to redraw are taken in ascending atom index and drawn as by one call of
`sample_flux_maxwellian`: first n uniforms (side), then n uniforms (speed), then n x 2
standard normals (row-major: atom, then component (axis+1)%3, (axis+2)%3). Nothing else
consumes random numbers, so a run is bit-reproducible from the generators' states.
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine import backend
from wallbatch.scene.case import FlowSpec
from wallbatch.units import UnitSystem

_SQRT_PI = float(np.sqrt(np.pi))
_EPS = float(np.finfo(float).eps)


# ----------------------------------------------------------------------------- sampler


def _one_minus_r(y: np.ndarray) -> np.ndarray:
    """q(y) = 1 - sqrt(pi) y erfcx(y) for y >= 0, without the cancellation at large y.

    Below y = 2 directly (loses < 1 digit). From y = 2 on from Laplace's continued fraction
    sqrt(pi) erfcx(y) = 1/(y + t), t = (1/2)/(y + 1/(y + (3/2)/(y + ...))): q = t/(y + t);
    60 levels (40 from y = 3, 20 from y = 5) give full double precision (checked against mpmath
    in the tests).
    """
    from scipy.special import erfcx  # lazy: scipy.special costs ~0.35 s of import, only flow walls use it
    y = np.asarray(y, float)
    out = np.empty_like(y)
    small = y < 2.0
    ys = y[small]
    out[small] = 1.0 - _SQRT_PI * ys * erfcx(ys)
    for lo, hi, depth in ((2.0, 3.0, 60), (3.0, 5.0, 40), (5.0, np.inf, 20)):
        band = (y >= lo) & (y < hi)  # depth per element, so no element depends on the others
        if band.any():
            yl = y[band]
            t = np.zeros_like(yl)
            for k in range(depth, 0, -1):
                t = (0.5 * k) / (yl + t)
            out[band] = t / (yl + t)
    return out


def log_tail(nu: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """ln T(ν; δ), T(ν; δ) = ∫_ν^∞ t exp(-(t - δ)²) dt = exp(-y²)/2 + δ (√π/2) erfc(y), y = ν - δ,
    for ν >= 0 and any δ (arrays broadcast). Dimensionless (ν = γ|v|, δ = γ vflow on the side drawn).

    Three forms, each free of overflow and cancellation:
    y < 0 (then δ > 0): the sum itself (erfc(y) in (1, 2]);
    y >= 0, δ >= 0:     -y² + ln(1/2 + δ (√π/2) erfcx(y));
    δ < 0 (y >= |δ|):   -y² + ln(q(y) + (ν/y)(1 - q(y))) - ln 2, with q = 1 - √π y erfcx(y),
                        since 1 - |δ| √π erfcx(y) = q + (ν/y)(1 - q) with both terms >= 0.
    """
    from scipy.special import erfc, erfcx  # lazy (see _one_minus_r)
    nu, delta = np.broadcast_arrays(np.asarray(nu, float), np.asarray(delta, float))
    y = nu - delta
    out = np.empty_like(y)
    a = y < 0.0
    b = ~a & (delta >= 0.0)
    c = ~a & ~b
    ya, da = y[a], delta[a]
    out[a] = np.log(0.5 * np.exp(-ya * ya) + da * (0.5 * _SQRT_PI) * erfc(ya))
    yb, db = y[b], delta[b]
    out[b] = -yb * yb + np.log(0.5 + db * (0.5 * _SQRT_PI) * erfcx(yb))
    yc, nc = y[c], nu[c]
    q = _one_minus_r(yc)
    out[c] = -yc * yc + np.log(0.5 * (q + (nc / yc) * (1.0 - q)))
    return out


def positive_fraction(delta: np.ndarray) -> np.ndarray:
    """P+ = probability that the drawn perpendicular velocity is positive, for δ = γ vflow >= 0:
    T(0; δ) / (T(0; δ) + T(0; -δ)) (= (1 + δ/E)/2 of §8.3, E = exp(-δ²)/√π + δ erf δ), computed
    as a logistic of the log ratio so that it is exactly 1, not NaN, for large δ."""
    from scipy.special import expit  # lazy (see _one_minus_r)
    delta = np.asarray(delta, float)
    return expit(log_tail(0.0, delta) - log_tail(0.0, -delta))


def solve_flux_speed(delta: np.ndarray, u: np.ndarray, max_iter: int = 100) -> np.ndarray:
    """ν >= 0 with T(ν; δ)/T(0; δ) = u, u in (0, 1]: inverse-CDF sample of the density
    ∝ ν exp(-(ν - δ)²) on ν > 0 (δ may be negative: the backward side of §8.3).

    Method (instead of LAMMPS's 10 plain Newton steps with exp(x²), quirk #11): solve
    φ(ν) = ln T(ν) - ln T(0) - ln u = 0 in log space, where nothing overflows. φ decreases,
    φ(0) = -ln u >= 0; with w = exp(-(ν-δ)²)/T(ν): φ' = -ν w, φ'' = -w (1 - 2ν(ν-δ) + ν² w).
    Halley's method (Newton's when Halley's correction is unsafe) kept inside a bracket
    [a, b] with φ(a) >= 0 >= φ(b): a step leaving the bracket is replaced by bisection.
    Bracket: a = 0, b = δ⁺ + sqrt(-ln u + ln((1 + √π δ⁺)/(exp(-δ⁺²) + √π δ⁺))) + 1 (δ⁺ =
    max(δ, 0); an upper bound for δ >= 0: T(ν) <= exp(-(ν-δ)²)(1 + √π δ)/2 for ν >= δ and
    T(0) >= (exp(-δ²) + √π δ)/2), b doubled while φ(b) > 0. Start: the mode (δ + sqrt(δ²+2))/2.
    Each element stops on its own when its step is at rounding level (4 eps max(ν,
    (|ln T| + 1)/|φ'|): φ is a difference of O(|ln T|) numbers) or its bracket is 4 eps wide,
    and is then frozen, so the result of an element does not depend on the others in the
    array. Typically 3-5 iterations. u = 1 gives ν = 0; u = 2^-53 gives ν - δ < 7.
    """
    delta, u = np.broadcast_arrays(np.asarray(delta, float), np.asarray(u, float))
    delta, u = delta.ravel().copy(), u.ravel().copy()
    if np.any(~(u > 0.0) | (u > 1.0)):
        raise ValueError("solve_flux_speed: u must be in (0, 1]")
    target = log_tail(0.0, delta) + np.log(u)
    dpos = np.maximum(delta, 0.0)
    k = np.log1p(_SQRT_PI * dpos) - np.log(np.exp(-dpos * dpos) + _SQRT_PI * dpos)  # 0 for δ <= 0
    a = np.zeros_like(delta)
    b = dpos + np.sqrt(k - np.log(u)) + 1.0
    for _ in range(200):
        up = log_tail(b, delta) > target
        if not up.any():
            break
        a = np.where(up, b, a)
        b = np.where(up, 2.0 * b + 1.0, b)
    s = np.sqrt(delta * delta + 2.0)
    mode = np.where(delta >= 0.0, 0.5 * (delta + s), 1.0 / (s - delta))
    x = np.clip(mode, a, b)
    active = u < 1.0
    x[~active] = 0.0
    for _ in range(max_iter):
        i = np.nonzero(active)[0]
        if i.size == 0:
            break
        xi, di, ai, bi = x[i], delta[i], a[i], b[i]
        lt = log_tail(xi, di)
        f = lt - target[i]
        ai = np.where(f >= 0.0, xi, ai)
        bi = np.where(f <= 0.0, xi, bi)
        w = np.exp(-(xi - di) ** 2 - lt)
        d1 = -xi * w
        d2 = -w * (1.0 - 2.0 * xi * (xi - di) + xi * xi * w)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            newton = f / d1
            corr = 1.0 - 0.5 * newton * d2 / d1
            step = np.where((corr > 0.5) & (corr < 2.0), newton / corr, newton)
            noise = 4 * _EPS * np.maximum(xi, (np.abs(lt) + np.abs(target[i]) + 1.0) / np.abs(d1))
        xn = xi - step
        inside = (d1 < 0.0) & (xn >= ai) & (xn <= bi)
        xn = np.where(inside, xn, 0.5 * (ai + bi))
        done = (f == 0.0) | (inside & (np.abs(xn - xi) <= noise)) | (bi - ai <= 4 * _EPS * bi)
        x[i] = np.where(f == 0.0, xi, xn)
        a[i], b[i] = ai, bi
        active[i[done]] = False
    return x


def _draw(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The random numbers of n redraws, in the documented order: u1 (n,), u2 (n,), g (n, 2)."""
    u1 = rng.random(n)
    u2 = rng.random(n)
    g = rng.standard_normal((n, 2))
    return u1, u2, g


def _compiled_flow() -> bool:
    """The compiled flow solver is wanted and imports (numba + scipy.special: imported only then)."""
    if not backend.numba_allowed():
        return False
    from wallbatch.engine import flow_compiled

    return flow_compiled.enabled()


def _velocities(u1: np.ndarray, u2: np.ndarray, g: np.ndarray, gamma: np.ndarray,
                vflow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """§8.3 from given random numbers: side from u1 (backward if u1 > P+), speed from
    T(ν)/T(0) = 1 - u2 (in (0, 1]), parallel components g/(γ√2) = N(0,1) sqrt(kT/m).
    Compiled (flow_compiled.velocities) unless WALLBATCH_NUMBA=0; this NumPy code is the reference."""
    gamma = np.broadcast_to(np.asarray(gamma, float), u1.shape)
    if _compiled_flow():  # the same arithmetic per redraw, compiled (flow_compiled.py)
        from wallbatch.engine import flow_compiled

        v_axis, v_par = np.empty(u1.shape), np.empty((u1.size, 2))
        flow_compiled.velocities(np.ascontiguousarray(u1, float), np.ascontiguousarray(u2, float),
                                 np.ascontiguousarray(g, float), np.ascontiguousarray(gamma),
                                 np.ascontiguousarray(np.broadcast_to(np.asarray(vflow, float), u1.shape)),
                                 v_axis, v_par)
        return v_axis, v_par
    delta = gamma * np.broadcast_to(np.asarray(vflow, float), u1.shape)
    side = np.where(u1 > positive_fraction(delta), -1.0, 1.0)
    nu = solve_flux_speed(side * delta, 1.0 - u2)
    v_axis = side * nu / gamma
    v_par = g / (gamma[:, None] * np.sqrt(2.0))
    return v_axis, v_par


def sample_flux_maxwellian(rng: np.random.Generator, n: int, gamma: float | np.ndarray,
                           vflow: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """n redraws of §8.3: v_axis (n,) from f(v) ∝ |v| exp(-γ²(v - vflow)²) on the whole line,
    v_par (n, 2) Gaussian with variance 1/(2γ²) = kT/m, zero mean.

    gamma = 1/sqrt(2 kT/m) [1/velocity], a number or per atom (n,) (masses differ); vflow
    [velocity] a number or (n,). Draws: rng.random(n) (side), rng.random(n) (speed),
    rng.standard_normal((n, 2)) (parallel), in that order.
    """
    u1, u2, g = _draw(rng, n)
    return _velocities(u1, u2, g, gamma, vflow)


# ----------------------------------------------------------------------------- checks


def _wall_errors(axis: int, lo: float, hi: float, coords: np.ndarray) -> list[str]:
    name = "xyz"[axis]
    w = np.asarray(coords, float).ravel()
    if w.size == 0:
        return [(f"wall/flow needs at least one wall coordinate along {name} (LAMMPS: Illegal fix wall/flow "
                 f"command: missing argument(s))")]
    errors = []
    if not np.all(np.isfinite(w)):
        errors.append(f"flow wall coordinates must be finite numbers, got {w.tolist()}")
        return errors
    if np.any(np.diff(w) <= 0.0):
        errors.append(f"flow wall coordinates along {name} must be strictly increasing (no repeats), got "
                      f"{w.tolist()}: list them in ascending order, each once (LAMMPS: Wrong fix wall/flow "
                      f"wall ordering or some walls are outside simulation domain)")
    out = w[(w <= lo) | (w >= hi)]
    if out.size:
        errors.append(f"flow walls {out.tolist()} lie on or outside the box ({lo:g} .. {hi:g} along {name}): "
                      f"every wall must be strictly inside the box, the box bounds already act as a wall "
                      f"(LAMMPS: Wrong fix wall/flow wall ordering or some walls are outside simulation domain)")
    return errors


def check_flow(axis: int | str, periodic: np.ndarray, box_lo: np.ndarray, box_hi: np.ndarray,
               coords: np.ndarray, *, temperature: float | None = None,
               vflow: float | None = None) -> list[str]:
    """The physics.md §8.6 errors (and the T <= 0 decision) that apply to a scene; [] if none.

    axis: 0..2 or 'x'/'y'/'z'; periodic (3,) bool; box_lo, box_hi (3,) and coords (K,) in box
    units (absolute positions along the axis). temperature and vflow are checked when given.
    """
    ax = {"x": 0, "y": 1, "z": 2, 0: 0, 1: 1, 2: 2}.get(axis if isinstance(axis, str) else int(axis))
    if ax is None:
        return [f"wall/flow axis must be x, y or z (0, 1, 2), got {axis!r}"]
    name = "xyz"[ax]
    errors = []
    if not bool(np.asarray(periodic)[ax]):
        errors.append(f"wall/flow cannot be used with a non-periodic boundary along the flow axis {name}: make "
                      f"the box periodic along {name} (LAMMPS: Fix wall/flow cannot be used with a non-periodic "
                      f"boundary along the flow axis)")
    errors += _wall_errors(ax, float(np.asarray(box_lo, float)[ax]), float(np.asarray(box_hi, float)[ax]), coords)
    if temperature is not None and not temperature > 0.0:
        errors.append(f"wall/flow temperature must be > 0, got {temperature:g}: a temperature <= 0 has no "
                      f"Maxwellian to draw from (LAMMPS accepts it and gives NaN velocities)")
    if vflow is not None and not vflow > 0.0:
        errors.append(f"wall/flow vflow must be > 0, got {vflow:g} (LAMMPS: velocity cannot be 0; a negative "
                      f"direction is not supported: flip the axis orientation of the scene instead)")
    return errors


# ----------------------------------------------------------------------------- kernel


class FlowKernel:
    """fix wall/flow for a batch of C cases (one spec and one generator per case).

    State per atom: `phys` (C, N), the segment the atom sat in at the previous check, and
    `pend` (C, N) in {-1, 0, +1}: nonzero while the atom, redrawn back over the wall it just
    crossed (rule exact), travels back to it; the sign is the direction of that return.
    Its stored segment (`segments`) is then the one beyond that wall.
    """

    def __init__(self, specs: list[FlowSpec], rngs: list[np.random.Generator], box_lo: np.ndarray,
                 box_hi: np.ndarray, units: UnitSystem):
        if len(specs) != len(rngs) or not specs:
            raise ValueError(f"FlowKernel: {len(specs)} specs need as many generators, got {len(rngs)}")
        C = len(specs)
        self.fix_id = specs[0].fix_id
        self.rngs = list(rngs)
        self.group = np.stack([np.asarray(s.group, bool) for s in specs])
        self.axis = np.array([s.axis for s in specs], dtype=np.intp)
        self.vflow = np.array([s.vflow for s in specs], float)
        temperature = np.array([s.temperature for s in specs], float)
        self.exact = np.array([s.rule == "exact" for s in specs])
        lo = np.broadcast_to(np.asarray(box_lo, float), (C, 3))
        hi = np.broadcast_to(np.asarray(box_hi, float), (C, 3))
        rows = np.arange(C)
        self.lo, self.length = lo[rows, self.axis].copy(), (hi - lo)[rows, self.axis].copy()
        errors = []
        for c, s in enumerate(specs):
            where = f"walls.{s.fix_id} (case {c})"
            if s.rule not in ("exact", "lammps"):
                errors.append(f"{where}: rule must be 'exact' or 'lammps', got {s.rule!r}")
            if s.axis not in (0, 1, 2):
                errors.append(f"{where}: axis must be 0, 1 or 2, got {s.axis!r}")
                continue
            errors += [f"{where}: {e}" for e in check_flow(s.axis, (True, True, True), lo[c], hi[c], s.walls,
                                                           temperature=s.temperature, vflow=s.vflow)]
        if errors:
            raise ValueError("\n".join(errors))
        self.kT = units.boltz * temperature / units.mvv2e  # (C,) mass*velocity^2
        kmax = max(len(s.walls) for s in specs)
        self.walls = np.full((C, kmax), np.inf)  # padded with +inf: never <= x
        for c, s in enumerate(specs):
            self.walls[c, :len(s.walls)] = s.walls
        self.nseg = np.array([len(s.walls) + 1 for s in specs])
        self.crossings = np.zeros(C)
        self.phys: np.ndarray | None = None
        self.pend: np.ndarray | None = None
        self.prev: np.ndarray | None = None

    @property
    def ncases(self) -> int:
        return len(self.rngs)

    def _axis_coord(self, a: np.ndarray) -> np.ndarray:
        """a[c, :, axis[c]] as (C, N) (a copy)."""
        if np.all(self.axis == self.axis[0]):
            return a[:, :, self.axis[0]].copy()
        return a[np.arange(self.ncases)[:, None], np.arange(a.shape[1])[None, :], self.axis[:, None]]

    def _segment(self, xa: np.ndarray) -> np.ndarray:
        """Segment index 0..K of each wrapped axis coordinate (C, N): number of walls <= x."""
        xw = self.lo[:, None] + np.mod(xa - self.lo[:, None], self.length[:, None])
        seg = np.zeros(xa.shape, dtype=np.intp)
        for k in range(self.walls.shape[1]):
            seg += xw >= self.walls[:, k, None]
        return seg

    @property
    def segments(self) -> np.ndarray:
        """Stored segment per atom (C, N): where it sits, or for a pending atom (rule exact) the
        segment beyond the wall it is heading back over."""
        return np.mod(self.phys + self.pend, self.nseg[:, None])

    def take(self, keep: np.ndarray) -> None:
        """Keep some cases (boolean mask or indices over the batch)."""
        idx = np.arange(self.ncases)[keep]
        self.rngs = [self.rngs[i] for i in idx]
        for name in ("group", "axis", "vflow", "exact", "lo", "length", "kT", "walls", "nseg", "crossings",
                     "phys", "pend", "prev"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, value[idx])

    def setup(self, x: np.ndarray) -> None:
        """At the start of a run: every atom's segment from its position (§8.2), nothing pending."""
        xa = self._axis_coord(x)
        self.phys = self._segment(xa)
        self.pend = np.zeros(xa.shape, dtype=np.int8)
        self.prev = xa.copy()

    def end_of_step(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray) -> None:
        """Redraw (in place in v) the velocity of group atoms that crossed a flow wall this step.

        Crossing direction d = sign of the minimum-image displacement along the axis since the
        previous call. For a group atom:
        * not pending, segment changed: crossing in direction d;
        * pending, segment changed in the return direction: back over the wall, no crossing;
        * pending, segment changed the other way (two walls at once; not seen in practice):
          crossing in direction d;
        * pending, same segment, velocity no longer heading back (v_axis * pend <= 0): it has
          turned round in front of the wall, i.e. re-entered its segment: crossing in -pend.
        After a redraw under rule exact, pend = -d if the new v_axis points back (v_axis * d < 0).
        """
        if self.phys is None:
            raise RuntimeError(f"walls.{self.fix_id}: FlowKernel.setup(x) must run before end_of_step")
        if _compiled_flow():
            self._end_of_step_compiled(x, v, mass)
            return
        C = self.ncases
        xa = self._axis_coord(x)
        p = self._segment(xa)
        # candidates: group atoms whose segment changed, or that are pending
        ci, ai = np.nonzero(self.group & ((p != self.phys) | (self.pend != 0)))
        if ci.size:
            moved = p[ci, ai] != self.phys[ci, ai]
            pend = self.pend[ci, ai].astype(float)
            va = v[ci, ai, self.axis[ci]]
            dx = xa[ci, ai] - self.prev[ci, ai]
            dx -= self.length[ci] * np.round(dx / self.length[ci])  # minimum image
            d = np.sign(dx)
            d = np.where(d == 0.0, np.sign(va), d)
            d = np.where(d == 0.0, 1.0, d)
            returned = (pend != 0.0) & moved & (d == pend)
            turned = (pend != 0.0) & ~moved & (va * pend <= 0.0)
            cross = (moved & ~returned) | turned
            self.pend[ci[returned], ai[returned]] = 0
            direction = np.where(turned, -pend, d)[cross]
            ci, ai = ci[cross], ai[cross]
        if ci.size:
            counts = np.bincount(ci, minlength=C)
            parts = [_draw(self.rngs[c], int(counts[c])) for c in np.nonzero(counts)[0]]
            u1, u2, g = (np.concatenate(z) for z in zip(*parts))
            gamma = 1.0 / np.sqrt(2.0 * self.kT[ci] / mass[ci, ai])
            v_axis, v_par = _velocities(u1, u2, g, gamma, self.vflow[ci])
            ax = self.axis[ci]
            v[ci, ai, ax] = v_axis
            v[ci, ai, (ax + 1) % 3] = v_par[:, 0]
            v[ci, ai, (ax + 2) % 3] = v_par[:, 1]
            back = self.exact[ci] & (v_axis * direction < 0.0)
            self.pend[ci, ai] = np.where(back, -direction, 0.0).astype(np.int8)
            self.crossings += counts
        self.phys = p
        self.prev = xa

    def _end_of_step_compiled(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray) -> None:
        """end_of_step with the detection and the redraws compiled (flow_compiled.detect, apply);
        the random numbers drawn here as in the NumPy code (per case, `_draw`, same order)."""
        from wallbatch.engine import flow_compiled  # lazy (see _velocities)
        C, N = x.shape[0], x.shape[1]
        seg = np.empty((C, N), np.intp)
        xa = np.empty((C, N))
        ci = np.empty(C * N, np.intp)
        ai = np.empty(C * N, np.intp)
        direction = np.empty(C * N)
        n = flow_compiled.detect(x, v, self.group, self.axis, self.lo, self.length, self.walls, self.phys,
                                 self.pend, self.prev, seg, xa, ci, ai, direction)
        if n:
            ci, ai, direction = ci[:n], ai[:n], direction[:n]
            counts = np.bincount(ci, minlength=C)
            parts = [_draw(self.rngs[c], int(counts[c])) for c in np.nonzero(counts)[0]]
            u1, u2, g = (np.concatenate(z) for z in zip(*parts))
            flow_compiled.apply(ci, ai, direction, u1, u2, g, self.kT, mass, self.vflow, self.axis, self.exact, v,
                                self.pend)
            self.crossings += counts
        self.phys = seg
        self.prev = xa

    def take_crossings(self) -> np.ndarray:
        """Redraws (crossings) per case (C,) since the previous call; resets the counter."""
        out = self.crossings.copy()
        self.crossings[:] = 0.0
        return out
