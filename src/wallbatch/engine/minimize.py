"""Batched energy minimisation: LAMMPS ``minimize etol ftol maxiter maxeval`` (issue 8).

Two styles, as LAMMPS 22Jul2025 runs them (re-derived from its documentation and behaviour,
checked against the binary in ``tests/engine/test_minimize.py``):

* ``cg`` (LAMMPS's default ``min_style``): Polak-Ribiere conjugate gradients with the
  ``quadratic`` line search (LAMMPS's default ``min_modify line``);
* ``fire``: FIRE 2.0 (Guenole et al., Comput. Mater. Sci. 175, 109584 (2020)) with LAMMPS's
  default ``min_modify`` parameters (semi-implicit Euler, half step back, initial delay).

Everything is batched over C cases: ``x`` is ``(C, N, 3)`` [length]. Every case has its own
state machine, iteration and evaluation counters and stops on its own; the objective is called
once per round with the positions of all cases that need an evaluation in that round (masks
keep finished cases frozen). Per-case arithmetic never mixes cases (row-wise reductions only),
so a case gives the same numbers alone or in any batch, provided the objective does too.

Stopping criteria (reported with LAMMPS's words, :data:`STOP_REASONS`):

* ``energy tolerance``: ``|E_k - E_{k-1}| < etol * 0.5 * (|E_k| + |E_{k-1}| + 1e-8)`` between
  iterations (for fire only once more than ``delaystep`` iterations have passed since the last
  velocity reset; ``etol = 0`` disables it);
* ``force tolerance``: ``|F|_2^2 < ftol^2``, the 2-norm of the global 3N force vector (LAMMPS's
  default ``min_modify norm two``; ``ftol = 0`` disables it);
* ``max iterations`` (``maxiter``, counted like LAMMPS: an iteration whose line search fails
  counts), ``max force evaluations`` (``maxeval``, checked after each complete iteration, so
  the last line search may overshoot it, as in LAMMPS; cg only: LAMMPS's fire never checks it);
* cg line-search failures: ``search direction is not downhill``, ``linesearch alpha is zero``,
  ``quadratic factors are zero`` (positions reset to the start of the failed line search),
  ``forces are zero``;
* fire: ``max iterations with v.f negative`` (2000 consecutive iterations with v.f <= 0);
* ``NaN``: the objective returned a NaN energy or a non-finite force; the case keeps the last
  accepted state (start of the line search for cg, the previous step for fire).

Iteration and evaluation counts are LAMMPS's ("Iterations, force evaluations"): the initial
evaluation is not counted, and the line-search resets to the starting point are counted
(they are taken from memory here, without calling the objective again).

Deliberate deviation from LAMMPS: an all-zero search direction (all forces exactly zero) stops
with ``forces are zero``; LAMMPS tests the downhill condition first and so reports
``search direction is not downhill`` (its ``forces are zero`` is unreachable for atoms).

Walls that move with LAMMPS's step (variables of ``step``, ``time``, ``ramp``, ...): LAMMPS's
minimizer counts each iteration as a timestep, and ``minimize(..., clock=...)`` hands the caller
that count per case (and fire's adaptive timestep) before every objective call; see
:func:`minimize`.

Energies inside the algorithm are divided by N when ``MinSettings.norm`` is true, as LAMMPS
does with ``thermo_modify norm yes`` (its default in lj units); this changes only the absolute
thresholds (1e-8 in the energy tolerance, ``EMACH``, ``EPS_QUAD``). Reported energies are
always the objective's (extensive) values.

Forces that are not the gradient of the energy (walls without ``fix_modify energy yes``, whose
force acts but whose energy is not in E): the minimiser still terminates, because every loop is
bounded (``maxiter``; the backtracking halves alpha until the ideal decrease 0.4 alpha f.h is
below ``EMACH``). cg takes its search direction from the forces but accepts a line-search step
only if E falls (or a secant step raises it by less than ``EMACH``): when E does not fall along
the forces (e.g. E constant) it gives up with ``linesearch alpha is zero``, positions back at
the start of that line search, and a force that does not change along the line gives
``quadratic factors are zero``. fire moves with the forces only and uses E only for the energy
tolerance: it relaxes to where the total force (walls included) vanishes and stops there on
``force tolerance``; with etol > 0 and E constant it stops on ``energy tolerance`` after
``delaystep + 2`` iterations (the first one resets v). Both match LAMMPS, which behaves the
same way; use fire, or count the wall energy, when such walls matter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wallbatch.scene.case import MinSettings

__all__ = ["STOP_REASONS", "MinResult", "MinSettings", "minimize"]

Objective = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
IterationHook = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
Clock = Callable[[np.ndarray, "np.ndarray | None"], None]

STOP_REASONS = (
    "max iterations",
    "max force evaluations",
    "energy tolerance",
    "force tolerance",
    "search direction is not downhill",
    "linesearch alpha is zero",
    "forces are zero",
    "quadratic factors are zero",
    "max iterations with v.f negative",
    "NaN",
    "inactive",
)

EPS_ENERGY = 1.0e-8  # minimum normalisation in the energy tolerance
# quadratic line search (LAMMPS min_linesearch)
ALPHA_MAX = 1.0  # largest step factor along h
ALPHA_REDUCE = 0.5  # backtracking factor
BACKTRACK_SLOPE = 0.4  # sufficient-decrease factor
QUADRATIC_TOL = 0.1  # accuracy of the quadratic model that allows a secant step
EMACH = 1.0e-8  # energy changes below this are noise
EPS_QUAD = 1.0e-28  # f.h or its change below this: quadratic factors are zero
# fire defaults (LAMMPS min_modify)
FIRE_DELAYSTEP = 20
FIRE_DTGROW = 1.1
FIRE_DTSHRINK = 0.5
FIRE_ALPHA0 = 0.25
FIRE_ALPHASHRINK = 0.99
FIRE_TMAX = 10.0  # dtmax = tmax * timestep
FIRE_TMIN = 0.02  # dtmin = tmin * timestep
FIRE_VDFMAX = 2000  # consecutive iterations with v.f <= 0 before giving up

# per-case phase: which evaluation the case is waiting for (_FINAL: the last one, at the step of
# a stop that comes after the step counter advanced, with a clock only)
_DONE, _SETUP, _TRIAL, _QUAD, _V0, _STEP, _FINAL = -1, 0, 1, 2, 3, 4, 5


@dataclass
class MinResult:
    """Per-case outcome. Energies [energy] are the objective's, fnorm2 [force] is |F|_2 at x."""

    x: np.ndarray  # (C, N, 3)
    energy_before: np.ndarray  # (C,)
    energy_after: np.ndarray  # (C,)
    iterations: np.ndarray  # (C,) int
    evaluations: np.ndarray  # (C,) int, LAMMPS's count (the initial evaluation not included)
    stop_reason: list[str]
    fnorm2: np.ndarray  # (C,)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (R, M) arrays (one contiguous reduction per row)."""
    return np.sum(a * b, axis=1)


class _Minimizer:
    """State shared by both styles; arrays are (C, M) with M = 3N, or (C,)."""

    def __init__(self, x0: np.ndarray, settings: MinSettings, hook: IterationHook | None,
                 reevaluate: bool = False):
        c, n = x0.shape[:2]
        m = 3 * n
        self.s = settings
        self.hook = hook
        self.reevaluate = reevaluate  # a clock: stops after the step advanced evaluate once more
        self.pending = [""] * c  # the stop reason of a case in _FINAL
        self.n = n
        self.nrm = float(n) if settings.norm and n > 0 else 1.0
        self.x = x0.reshape(c, m).copy()
        self.f = np.zeros((c, m))
        self.e = np.full(c, np.nan)  # raw (extensive) energy of the state in x, f
        self.e_init = np.full(c, np.nan)
        self.phase = np.full(c, _DONE)
        self.niter = np.zeros(c, dtype=np.int64)
        self.neval = np.zeros(c, dtype=np.int64)
        self.reason = ["inactive"] * c

    def stop(self, rows: np.ndarray, reason: str) -> None:
        self.phase[rows] = _DONE
        for r in rows.tolist():
            self.reason[r] = reason

    def stop_at_step(self, rows: np.ndarray, reason: str) -> None:
        """Stop in an iteration whose step had no evaluation at the positions kept. LAMMPS
        evaluates them once more at that step (not counted); without a clock nothing moves with the
        step and the energy and forces in memory are those numbers, so the stop is immediate."""
        if not self.reevaluate:
            self.stop(rows, reason)
            return
        self.phase[rows] = _FINAL
        for r in rows.tolist():
            self.pending[r] = reason

    def receive_final(self, rows: np.ndarray) -> None:
        """The last evaluation of cases in _FINAL arrived (in e, f): stop with their reason."""
        final = rows[self.phase[rows] == _FINAL]
        for r in final.tolist():
            self.stop(np.array([r]), self.pending[r])

    def finish_iteration(self, rows: np.ndarray) -> None:
        if self.hook is not None and rows.size:
            self.hook(rows.copy(), self.niter[rows].copy(), self.e[rows].copy())

    def etol_met(self, rows: np.ndarray, eprev: np.ndarray) -> np.ndarray:
        e, ep = self.e[rows] / self.nrm, eprev / self.nrm
        return np.abs(e - ep) < self.s.etol * 0.5 * (np.abs(e) + np.abs(ep) + EPS_ENERGY)

    def ftol_met(self, rows: np.ndarray) -> np.ndarray:
        if self.s.ftol <= 0.0:
            return np.zeros(rows.size, dtype=bool)
        return _dot(self.f[rows], self.f[rows]) < self.s.ftol * self.s.ftol


class _CG(_Minimizer):
    """Polak-Ribiere CG with LAMMPS's quadratic line search (min_modify line quadratic).

    One iteration: line search along h from x0 (trial x0 + alpha h, alpha starting at
    min(1, dmax / max|h|)), then the stopping tests, then h = f + beta h with
    beta = max(0, (f.f - f.g) / g.g), restarted (beta = 0) every 3N iterations and whenever
    h is not downhill. Line search per trial: secant step to f.h = 0 when the quadratic model
    of E is accurate (relerr <= 0.1) and accepted if it does not raise E by EMACH or more;
    otherwise accept if E fell by 0.4 alpha f.h, else halve alpha.
    """

    def __init__(self, x0, settings, hook, reevaluate=False):
        super().__init__(x0, settings, hook, reevaluate)
        c, m = self.x.shape
        self.nlimit = max(m, 1)
        self.x0 = self.x.copy()
        self.f0 = np.zeros((c, m))
        self.e0 = np.zeros(c)
        self.g = np.zeros((c, m))
        self.h = np.zeros((c, m))
        self.gg = np.zeros(c)
        self.fdoth = np.zeros(c)
        self.alphamax = np.zeros(c)
        self.alpha = np.zeros(c)
        self.alphaprev = np.zeros(c)
        self.fhprev = np.zeros(c)
        self.engprev = np.zeros(c)
        self.fh = np.zeros(c)

    # --- results of one round of evaluations
    def receive(self, rows: np.ndarray) -> None:
        self.receive_final(rows)
        phase = self.phase[rows]
        setup = rows[phase == _SETUP]
        trial = rows[phase == _TRIAL]
        quad = rows[phase == _QUAD]
        self.neval[trial] += 1
        self.neval[quad] += 1
        if setup.size:
            self.g[setup] = self.f[setup]
            self.h[setup] = self.f[setup]
            self.gg[setup] = _dot(self.f[setup], self.f[setup])
        done = [self._after_trial(trial), self._after_quad(quad)]
        done = np.concatenate(done)
        self.finish_iteration(done)
        cont = self._end_iteration(done)
        self._start_iteration(np.concatenate([setup, cont]))

    def fail_nan(self, rows: np.ndarray) -> None:
        searching = rows[(self.phase[rows] != _SETUP) & (self.phase[rows] != _FINAL)]
        self.neval[searching] += 1
        self._reset(searching)
        self.stop(rows, "NaN")

    # --- line search
    def _after_trial(self, rows: np.ndarray) -> np.ndarray:
        """Trial at x0 + alpha h evaluated; returns the rows whose line search succeeded."""
        if rows.size == 0:
            return rows
        fh = _dot(self.f[rows], self.h[rows]) / self.nrm
        delfh = fh - self.fhprev[rows]
        zero = (np.abs(fh) < EPS_QUAD) | (np.abs(delfh) < EPS_QUAD)
        self.neval[rows[zero]] += 1  # LAMMPS re-evaluates the starting point
        self._reset(rows[zero])
        self.stop_at_step(rows[zero], "quadratic factors are zero")
        keep = ~zero
        rows, fh, delfh = rows[keep], fh[keep], delfh[keep]
        self.fh[rows] = fh
        alpha, alphaprev = self.alpha[rows], self.alphaprev[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            ecur = self.e[rows] / self.nrm
            relerr = np.abs(1.0 - (0.5 * (alpha - alphaprev) * (fh + self.fhprev[rows]) + ecur)
                            / self.engprev[rows])
            alpha0 = alpha - (alpha - alphaprev) * fh / delfh
        secant = (relerr <= QUADRATIC_TOL) & (alpha0 > 0.0) & (alpha0 < self.alphamax[rows])
        q = rows[secant]
        self.x[q] = self.x0[q] + alpha0[secant][:, None] * self.h[q]
        self.phase[q] = _QUAD
        return self._backtrack(rows[~secant])

    def _after_quad(self, rows: np.ndarray) -> np.ndarray:
        """Secant step evaluated: accept unless E rose by EMACH or more, else backtrack."""
        if rows.size == 0:
            return rows
        ok = (self.e[rows] / self.nrm - self.e0[rows] / self.nrm) < EMACH
        return np.concatenate([rows[ok], self._backtrack(rows[~ok])])

    def _backtrack(self, rows: np.ndarray) -> np.ndarray:
        """Sufficient-decrease test on the last evaluated E; halve alpha or give up."""
        if rows.size == 0:
            return rows
        alpha = self.alpha[rows]
        ecur = self.e[rows] / self.nrm
        de_ideal = -BACKTRACK_SLOPE * alpha * self.fdoth[rows]
        de = ecur - self.e0[rows] / self.nrm
        ok = de <= de_ideal
        more = rows[~ok]
        self.fhprev[more] = self.fh[more]
        self.engprev[more] = ecur[~ok]
        self.alphaprev[more] = alpha[~ok]
        alpha = alpha[~ok] * ALPHA_REDUCE
        self.alpha[more] = alpha
        zero = (alpha <= 0.0) | (de_ideal[~ok] >= -EMACH)
        self.neval[more[zero]] += 1  # LAMMPS re-evaluates the starting point
        self._reset(more[zero])
        self.stop_at_step(more[zero], "linesearch alpha is zero")
        go = more[~zero]
        self.x[go] = self.x0[go] + alpha[~zero][:, None] * self.h[go]
        self.phase[go] = _TRIAL
        return rows[ok]

    def _reset(self, rows: np.ndarray) -> None:
        """Back to the start of the line search (its energy and forces are known)."""
        self.x[rows] = self.x0[rows]
        self.f[rows] = self.f0[rows]
        self.e[rows] = self.e0[rows]

    # --- outer iteration
    def _end_iteration(self, rows: np.ndarray) -> np.ndarray:
        """Stopping tests after a successful line search, then the new search direction."""
        if rows.size == 0:
            return rows
        maxeval = self.neval[rows] >= self.s.maxeval
        self.stop(rows[maxeval], "max force evaluations")
        rows = rows[~maxeval]
        etol = self.etol_met(rows, self.e0[rows])
        self.stop(rows[etol], "energy tolerance")
        rows = rows[~etol]
        ftol = self.ftol_met(rows)
        self.stop(rows[ftol], "force tolerance")
        rows = rows[~ftol]
        f, g, h = self.f[rows], self.g[rows], self.h[rows]
        ff = _dot(f, f)
        with np.errstate(divide="ignore", invalid="ignore"):
            beta = np.maximum(0.0, (ff - _dot(f, g)) / self.gg[rows])
        beta[(self.niter[rows] + 1) % self.nlimit == 0] = 0.0
        self.gg[rows] = ff
        h = f + beta[:, None] * h
        uphill = _dot(f, h) <= 0.0
        h[uphill] = f[uphill]
        self.g[rows] = f
        self.h[rows] = h
        return rows

    def _start_iteration(self, rows: np.ndarray) -> None:
        """Count the iteration and start its line search (first trial at alphamax)."""
        if rows.size == 0:
            return
        last = self.niter[rows] >= self.s.maxiter
        self.stop(rows[last], "max iterations")
        rows = rows[~last]
        self.niter[rows] += 1
        h = self.h[rows]
        hmax = np.abs(h).max(axis=1) if h.shape[1] else np.zeros(rows.size)
        zero = hmax == 0.0
        self.stop_at_step(rows[zero], "forces are zero")
        fdoth = _dot(self.f[rows], h) / self.nrm
        downhill = fdoth > 0.0
        self.stop_at_step(rows[~zero & ~downhill], "search direction is not downhill")
        ok = ~zero & downhill
        rows, hmax = rows[ok], hmax[ok]
        self.fdoth[rows] = fdoth[ok]
        self.x0[rows] = self.x[rows]
        self.f0[rows] = self.f[rows]
        self.e0[rows] = self.e[rows]
        alpha = np.minimum(ALPHA_MAX, self.s.dmax / hmax)
        self.alphamax[rows] = alpha
        self.alpha[rows] = alpha
        self.alphaprev[rows] = 0.0
        self.fhprev[rows] = self.fdoth[rows]
        self.engprev[rows] = self.e[rows] / self.nrm
        self.x[rows] = self.x0[rows] + alpha[:, None] * self.h[rows]
        self.phase[rows] = _TRIAL


class _Fire(_Minimizer):
    """FIRE 2.0 with semi-implicit Euler steps, LAMMPS's defaults (min_modify).

    Per iteration: if v.f > 0, mix v -> (1 - a) v + a |v| f/|f| after the kick and, once
    more than delaystep iterations have passed since v.f was last <= 0, dt -> min(1.1 dt,
    10 dt0) and a -> 0.99 a; if v.f <= 0 (after the first delaystep iterations), a -> 0.25 and
    dt -> dt/2 (not below 0.02 dt0), move back by dt v / 2 (with the new dt, as LAMMPS
    22Jul2025 does) and set v = 0. The step is
    v += dtv (ftm2v/m) f, x += dtv v with dtv <= dt limited so that no coordinate moves more
    than dmax (judged from v = dt (ftm2v/m) f after a reset, which costs one evaluation).
    """

    def __init__(self, x0, settings, hook, mass, ftm2v, reevaluate=False):
        super().__init__(x0, settings, hook, reevaluate)
        c, m = self.x.shape
        self.mass = np.repeat(np.broadcast_to(mass, (c, self.n)), 3, axis=1).astype(float)
        self.ftm2v = float(ftm2v)
        dt0 = float(settings.timestep)
        self.dtmax, self.dtmin = FIRE_TMAX * dt0, FIRE_TMIN * dt0
        self.v = np.zeros((c, m))
        self.dt = np.full(c, dt0)
        self.a = np.full(c, FIRE_ALPHA0)
        self.last_negative = np.zeros(c, dtype=np.int64)
        self.negatives = np.zeros(c, dtype=np.int64)
        self.flagv0 = np.ones(c, dtype=bool)
        self.mix = np.zeros(c, dtype=bool)
        self.scale1 = np.zeros(c)
        self.scale2 = np.zeros(c)
        self.x_prev = self.x.copy()
        self.f_prev = np.zeros((c, m))
        self.e_prev = np.zeros(c)

    def receive(self, rows: np.ndarray) -> None:
        self.receive_final(rows)
        phase = self.phase[rows]
        setup = rows[phase == _SETUP]
        v0 = rows[phase == _V0]
        step = rows[phase == _STEP]
        self.neval[v0] += 1
        self.neval[step] += 1
        # the reset evaluation gives forces only; E stays that of the last step
        self.e[v0] = self.e_prev[v0]
        self._step(v0)
        self.flagv0[step] = False
        self.finish_iteration(step)
        self._start_iteration(np.concatenate([setup, self._tests(step)]))

    def fail_nan(self, rows: np.ndarray) -> None:
        moved = rows[(self.phase[rows] != _SETUP) & (self.phase[rows] != _FINAL)]
        self.neval[moved] += 1
        self.x[moved] = self.x_prev[moved]
        self.f[moved] = self.f_prev[moved]
        self.e[moved] = self.e_prev[moved]
        self.stop(rows, "NaN")

    def _tests(self, rows: np.ndarray) -> np.ndarray:
        etol = np.zeros(rows.size, dtype=bool)
        if self.s.etol > 0.0:
            settled = self.niter[rows] - self.last_negative[rows] > FIRE_DELAYSTEP
            etol = settled & self.etol_met(rows, self.e_prev[rows])
        self.stop(rows[etol], "energy tolerance")
        rows = rows[~etol]
        ftol = self.ftol_met(rows)
        self.stop(rows[ftol], "force tolerance")
        return rows[~ftol]

    def _start_iteration(self, rows: np.ndarray) -> None:
        """Count the iteration, adapt dt and alpha from v.f, then step (after a reset: first
        ask for the forces at the reset position)."""
        if rows.size == 0:
            return
        last = self.niter[rows] >= self.s.maxiter
        self.stop(rows[last], "max iterations")
        rows = rows[~last]
        self.niter[rows] += 1
        it = self.niter[rows]
        self.x_prev[rows] = self.x[rows]  # last step: eprevious, and the state kept on NaN
        self.f_prev[rows] = self.f[rows]
        self.e_prev[rows] = self.e[rows]
        v, f = self.v[rows], self.f[rows]
        vdotf = _dot(v, f)
        pos = vdotf > 0.0
        self.mix[rows] = pos
        # v.f > 0: mixing factors, accelerate after the delay
        p = rows[pos]
        if p.size:
            vv = _dot(v[pos], v[pos])
            ff = _dot(f[pos], f[pos])
            a = self.a[p]
            self.scale1[p] = 1.0 - a
            with np.errstate(divide="ignore", invalid="ignore"):
                self.scale2[p] = np.where(ff <= 1e-20, 0.0, a * np.sqrt(vv / ff))
            self.negatives[p] = 0
            grow = p[it[pos] - self.last_negative[p] > FIRE_DELAYSTEP]
            self.dt[grow] = np.minimum(self.dt[grow] * FIRE_DTGROW, self.dtmax)
            self.a[grow] *= FIRE_ALPHASHRINK
        # v.f <= 0: slow down (after the initial delay), half step back, v = 0
        q = rows[~pos]
        if q.size:
            self.last_negative[q] = it[~pos]
            slow = q[~(it[~pos] < FIRE_DELAYSTEP)]
            self.a[slow] = FIRE_ALPHA0
            shrink = slow[self.dt[slow] * FIRE_DTSHRINK >= self.dtmin]
            self.dt[shrink] *= FIRE_DTSHRINK
            self.negatives[q] += 1
            stuck = self.negatives[q] > FIRE_VDFMAX
            self.stop_at_step(q[stuck], "max iterations with v.f negative")
            q = q[~stuck]
            self.x[q] -= 0.5 * self.dt[q][:, None] * self.v[q]
            self.v[q] = 0.0
            self.flagv0[q] = True
        rows = rows[(self.phase[rows] != _DONE) & (self.phase[rows] != _FINAL)]
        reset = self.flagv0[rows]
        self.phase[rows[reset]] = _V0  # forces at the reset position first
        self._step(rows[~reset])

    def _step(self, rows: np.ndarray) -> None:
        """Limit dtv, kick (and mix), drift; ask for the new energy and forces."""
        if rows.size == 0:
            return
        f = self.f[rows]
        mass = self.mass[rows]
        reset = self.flagv0[rows]
        v_reset = ((self.dt[rows] * self.ftm2v)[:, None] / mass) * f  # v after a reset
        v = np.where(reset[:, None], v_reset, self.v[rows])
        vmax = np.abs(v).max(axis=1) if v.shape[1] else np.zeros(rows.size)
        dt = self.dt[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            dtv = np.where(dt * vmax > self.s.dmax, self.s.dmax / vmax, dt)
        v[reset] = 0.0
        v = v + ((dtv * self.ftm2v)[:, None] / mass) * f
        mix = self.mix[rows]
        v[mix] = self.scale1[rows][mix][:, None] * v[mix] + self.scale2[rows][mix][:, None] * f[mix]
        self.v[rows] = v
        self.x[rows] = self.x[rows] + dtv[:, None] * v
        self.phase[rows] = _STEP


def minimize(
    x0: np.ndarray,
    objective: Objective,
    settings: MinSettings,
    active: np.ndarray | None = None,
    *,
    mass: np.ndarray | float = 1.0,
    ftm2v: float = 1.0,
    callback: IterationHook | None = None,
    clock: Clock | None = None,
    moving: bool = True,
) -> MinResult:
    """Minimise every active case from ``x0`` (C, N, 3) [length].

    ``objective(x_sub, rows) -> (E (R,), F (R, N, 3))`` [energy], [force] is called with the
    positions of the cases ``rows`` (indices into the batch) that need an evaluation; F should
    be -dE/dx (see the module docstring for forces without energy). ``mass`` [mass] (C, N),
    (N,) or scalar and ``ftm2v`` (force*time/mass to velocity) enter fire only.
    ``callback(rows, iterations, energies)`` is called after every completed iteration (the
    successful line search of cg, the step of fire) with the cases' new energies.
    Inactive cases are not touched: x unchanged, NaN energies, stop reason ``inactive``.
    Positions are passed to the objective as they are: periodic wrapping is the caller's.

    ``clock(steps, dt)``, for an objective that changes with LAMMPS's step (a wall moved by a
    variable of ``step``, ``time``, ``ramp``, ...), is called before every objective call with
    each case's step (C,) as LAMMPS's minimizer counts it (0 at the initial evaluation, k during
    iteration k: its line search, or its reset and fire step) and, for fire, each case's current
    fire timestep (C,) (LAMMPS's ``dt`` and ``time`` follow it), None for cg. With a clock, a stop
    that keeps positions last evaluated at an earlier step (a failed line search reset to its start,
    ``search direction is not downhill``, ``forces are zero``, ``max iterations with v.f negative``)
    evaluates them once more at the current step, as LAMMPS does, without counting it; the final
    energy and forces are then those of the moved objective. Without a clock nothing changes with
    the step and those stops keep the numbers in memory (the same numbers, no extra call).
    ``moving=False``: the clock only follows the count (e.g. for messages), the objective does not
    change with it, and those stops keep the numbers in memory as without a clock.
    """
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.ndim != 3 or x0.shape[2] != 3:
        raise ValueError(f"x0 must have shape (C, N, 3), not {x0.shape}")
    c, n = x0.shape[:2]
    active = np.ones(c, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    if active.shape != (c,):
        raise ValueError(f"active must have shape ({c},), not {active.shape}")
    reevaluate = clock is not None and moving
    if settings.style == "cg":
        mz: _CG | _Fire = _CG(x0, settings, callback, reevaluate)
    else:
        mz = _Fire(x0, settings, callback, mass, ftm2v, reevaluate)
    mz.phase[active] = _SETUP
    rows = np.flatnonzero(active)
    while rows.size:
        if clock is not None:
            clock(mz.niter.copy(), mz.dt.copy() if isinstance(mz, _Fire) else None)
        energy, force = objective(mz.x[rows].reshape(rows.size, n, 3), rows)
        energy = np.asarray(energy, dtype=np.float64).reshape(rows.size)
        force = np.asarray(force, dtype=np.float64)
        if force.shape != (rows.size, n, 3):
            raise ValueError(f"objective returned forces of shape {force.shape}, "
                             f"expected {(rows.size, n, 3)}")
        force = force.reshape(rows.size, 3 * n)
        bad = np.isnan(energy) | ~np.isfinite(force).all(axis=1)
        good = rows[~bad]
        first = mz.phase[rows] == _SETUP
        mz.e_init[rows[first]] = energy[first]
        mz.e[rows[first]] = energy[first]
        mz.e[good] = energy[~bad]
        mz.f[good] = force[~bad]
        if bad.any():
            mz.fail_nan(rows[bad])
        mz.receive(good)
        rows = np.flatnonzero(mz.phase != _DONE)
    f = mz.f
    fnorm2 = np.sqrt(_dot(f, f))
    fnorm2[~active] = np.nan
    e_after = mz.e.copy()
    return MinResult(
        x=mz.x.reshape(c, n, 3),
        energy_before=mz.e_init,
        energy_after=e_after,
        iterations=mz.niter,
        evaluations=mz.neval,
        stop_reason=mz.reason,
        fnorm2=fnorm2,
    )
